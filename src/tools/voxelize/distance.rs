//! Exact point–triangle distances (Ericson, *Real-Time Collision Detection*, Sec. 5.1.5,
//! "closest point on triangle to point"), in f64 and voxel units.

use crate::storage::tiles::TILE_LEN;

/// A triangle prepared for distance queries: vertices in voxel units (voxel centres at
/// integers) and the dot products every query shares.
#[derive(Clone, Debug)]
pub(super) struct Tri {
    a: [f64; 3],
    ab: [f64; 3],
    ac: [f64; 3],
    bc: [f64; 3],
    /// (b − a) × (c − a).
    n: [f64; 3],
    ab2: f64,
    ac2: f64,
    bc2: f64,
    abac: f64,
    /// 1 / |n|², or 0 for a degenerate triangle (see [`Tri::new`]).
    inv_n2: f64,
}

#[inline(always)]
fn sub(p: [f64; 3], q: [f64; 3]) -> [f64; 3] {
    [p[0] - q[0], p[1] - q[1], p[2] - q[2]]
}

#[inline(always)]
fn dot(p: [f64; 3], q: [f64; 3]) -> f64 {
    p[0] * q[0] + p[1] * q[1] + p[2] * q[2]
}

#[inline(always)]
fn cross(p: [f64; 3], q: [f64; 3]) -> [f64; 3] {
    [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
}

/// |p − (a + t d)|² for the clamped projection parameter t of p on the segment a + t d
/// (`d2 = |d|²`; a zero-length segment is its point).
#[inline]
fn segment2(ap: [f64; 3], d: [f64; 3], d2: f64) -> f64 {
    let t = if d2 > 0.0 { (dot(ap, d) / d2).clamp(0.0, 1.0) } else { 0.0 };
    let r = [ap[0] - t * d[0], ap[1] - t * d[1], ap[2] - t * d[2]];
    dot(r, r)
}

impl Tri {
    /// The triangle `(a, b, c)`. It is *degenerate* when its area is negligible against
    /// its edges (|n|² ≤ 10⁻²⁴ |ab|² |ac|², an angle below 10⁻¹² rad, or a zero edge):
    /// then the distance is the least distance to its three edges, which is what the
    /// area-zero triangle is, and no division by its area is made.
    pub(super) fn new(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Tri {
        let (ab, ac, bc) = (sub(b, a), sub(c, a), sub(c, b));
        let n = cross(ab, ac);
        let (ab2, ac2, bc2) = (dot(ab, ab), dot(ac, ac), dot(bc, bc));
        let n2 = dot(n, n);
        let degenerate =
            n2.is_nan() || n2 <= 1e-24 * ab2 * ac2 || ab2 == 0.0 || ac2 == 0.0 || bc2 == 0.0;
        Tri {
            a,
            ab,
            ac,
            bc,
            n,
            ab2,
            ac2,
            bc2,
            abac: dot(ab, ac),
            inv_n2: if degenerate { 0.0 } else { 1.0 / n2 },
        }
    }

    /// The three vertices.
    pub(super) fn vertices(&self) -> [[f64; 3]; 3] {
        let a = self.a;
        [a, [a[0] + self.ab[0], a[1] + self.ab[1], a[2] + self.ab[2]], {
            [a[0] + self.ac[0], a[1] + self.ac[1], a[2] + self.ac[2]]
        }]
    }

    /// Twice the area (voxel units²).
    pub(super) fn double_area(&self) -> f64 {
        dot(self.n, self.n).sqrt()
    }

    /// Perimeter (voxel units).
    pub(super) fn perimeter(&self) -> f64 {
        self.ab2.sqrt() + self.ac2.sqrt() + self.bc2.sqrt()
    }

    /// The unnormalised normal (b − a) × (c − a).
    pub(super) fn normal(&self) -> [f64; 3] {
        self.n
    }

    /// Squared distance from `p` to the triangle (exact up to f64 rounding).
    #[inline(always)]
    pub(super) fn dist2(&self, p: [f64; 3]) -> f64 {
        let ap = sub(p, self.a);
        if self.inv_n2 == 0.0 {
            let bp = sub(ap, self.ab);
            return segment2(ap, self.ab, self.ab2)
                .min(segment2(ap, self.ac, self.ac2))
                .min(segment2(bp, self.bc, self.bc2));
        }
        // Ericson's Voronoi-region tests, with bp = ap − ab and cp = ap − ac folded into
        // the shared dot products.
        let d1 = dot(self.ab, ap);
        let d2 = dot(self.ac, ap);
        if d1 <= 0.0 && d2 <= 0.0 {
            return dot(ap, ap); // vertex a
        }
        let d3 = d1 - self.ab2;
        let d4 = d2 - self.abac;
        if d3 >= 0.0 && d4 <= d3 {
            let bp = sub(ap, self.ab);
            return dot(bp, bp); // vertex b
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let v = (d1 / self.ab2).clamp(0.0, 1.0); // edge ab
            let r = [ap[0] - v * self.ab[0], ap[1] - v * self.ab[1], ap[2] - v * self.ab[2]];
            return dot(r, r);
        }
        let d5 = d1 - self.abac;
        let d6 = d2 - self.ac2;
        if d6 >= 0.0 && d5 <= d6 {
            let cp = sub(ap, self.ac);
            return dot(cp, cp); // vertex c
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let w = (d2 / self.ac2).clamp(0.0, 1.0); // edge ac
            let r = [ap[0] - w * self.ac[0], ap[1] - w * self.ac[1], ap[2] - w * self.ac[2]];
            return dot(r, r);
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = ((d4 - d3) / self.bc2).clamp(0.0, 1.0); // edge bc
            let bp = sub(ap, self.ab);
            let r = [bp[0] - w * self.bc[0], bp[1] - w * self.bc[1], bp[2] - w * self.bc[2]];
            return dot(r, r);
        }
        let h = dot(self.n, ap); // face
        h * h * self.inv_n2
    }
}

/// A triangle in f32 with its vertices relative to a tile's first voxel: the search pass
/// of [`LocalTri::search_tile`], which only has to find each voxel's nearest triangle (the
/// distance itself is then taken in f64 from that triangle, [`Tri::dist2`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct LocalTri {
    a: [f32; 3],
    ab: [f32; 3],
    ac: [f32; 3],
    bc: [f32; 3],
    n: [f32; 3],
    side: [[f32; 3]; 3],
    inv_e2: [f32; 3],
    inv_n2: f32,
}

impl Tri {
    /// This triangle relative to `base` (a tile's first voxel), in f32: the differences
    /// are taken in f64 and rounded once, the products computed from those.
    #[inline(always)]
    pub(super) fn local(&self, base: [f64; 3]) -> LocalTri {
        self.shape().at(self.local_a(base))
    }

    /// The first vertex relative to `base`, rounded to f32 once: the only part of
    /// [`Tri::local`] that depends on the base.
    #[inline(always)]
    pub(super) fn local_a(&self, base: [f64; 3]) -> [f32; 3] {
        sub(self.a, base).map(|x| x as f32)
    }

    /// [`Tri::local`] without its first vertex (set to 0): the edges, normal and factors in
    /// f32, made once per triangle and moved to each tile by [`Tri::local_a`].
    ///
    /// The edges' inner sides (n × ab, n × bc, n × ca: a point p is on the inner side of
    /// edge ab when (p − a)·(n × ab) ≥ 0, and so on; all zero for a degenerate triangle)
    /// and the edges' 1/|e|² (0 for a zero-length edge) are made here, in f64, and
    /// rounded once: the f64 triangle does not keep them.
    pub(super) fn shape(&self) -> LocalTri {
        let f = |v: [f64; 3]| v.map(|x| x as f32);
        let (n, ab, ac, bc) = (self.n, self.ab, self.ac, self.bc);
        let side = if self.inv_n2 == 0.0 {
            [[0.0; 3]; 3]
        } else {
            [cross(n, ab), cross(n, bc), cross(n, [-ac[0], -ac[1], -ac[2]])]
        };
        let inv = |e2: f64| if e2 > 0.0 { 1.0 / e2 } else { 0.0 };
        let inv_e2 = [inv(self.ab2), inv(self.ac2), inv(self.bc2)];
        // A sliver whose 1/|n|² exceeds f32 is its edges to f32 precision (a degenerate
        // triangle, as in `Tri::new`).
        let inv_n2 = self.inv_n2 as f32;
        let solid = inv_n2.is_finite();
        LocalTri {
            a: [0.0; 3],
            ab: f(self.ab),
            ac: f(self.ac),
            bc: f(self.bc),
            n: f(self.n),
            side: if solid { side.map(f) } else { [[0.0; 3]; 3] },
            inv_e2: inv_e2.map(|x| (x as f32).min(f32::MAX)),
            inv_n2: if solid { inv_n2 } else { 0.0 },
        }
    }
}

impl LocalTri {
    /// This shape with its first vertex at `a` ([`Tri::local_a`]).
    #[inline(always)]
    pub(super) fn at(&self, a: [f32; 3]) -> LocalTri {
        LocalTri { a, ..*self }
    }

    /// Folds this triangle (`id`) into the 64 voxels' nearest triangles: where its
    /// squared distance (f32, without branches: the plane's distance where the
    /// voxel projects inside the triangle, on the inner side of all three edges, else the
    /// least distance to the three edges; a degenerate triangle takes the edges alone) is below
    /// `best`, it replaces `best` and `arg`. Loops over the 16 voxels of a z-layer, so the
    /// compiler runs them as vectors of the widest registers the caller's instruction-set
    /// level has.
    ///
    /// A layer is skipped when the triangle's bounding box lies farther from the layer's
    /// 4 × 4 voxels than the largest `best` of the layer (`layer_max`, kept up to date
    /// here): no voxel of it could take the triangle. The bound keeps a margin of 10⁻³
    /// (relative, and absolute in squared voxels) over the f32 roundings of the distance
    /// (about 10⁻⁶ of the tile's coordinates), so the skipped layers are exactly those
    /// the search would leave as they are: the same `best` and `arg`.
    #[inline(always)]
    pub(super) fn search_tile(
        &self,
        id: u32,
        best: &mut [f32; TILE_LEN],
        arg: &mut [u32; TILE_LEN],
        layer_max: &mut [f32; 4],
    ) {
        let b = [0, 1, 2].map(|k| self.a[k] + self.ab[k]);
        let c = [0, 1, 2].map(|k| self.a[k] + self.ac[k]);
        let lo = [0, 1, 2].map(|k| self.a[k].min(b[k]).min(c[k]));
        let hi = [0, 1, 2].map(|k| self.a[k].max(b[k]).max(c[k]));
        // The gap from the box to the voxels 0..=3 along an axis, 0 where they overlap.
        let gap = |k: usize, from: f32, to: f32| (lo[k] - to).max(from - hi[k]).max(0.0);
        let (gx, gy) = (gap(0, 0.0, 3.0), gap(1, 0.0, 3.0));
        let gxy = gx * gx + gy * gy;
        for z in 0..4 {
            let zf = z as f32;
            let gz = gap(2, zf, zf);
            let bound = gxy + gz * gz;
            if bound > layer_max[z] * (1.0 + 1e-3) + 1e-3 {
                continue;
            }
            for l in 16 * z..16 * z + 16 {
                let d = self.dist2([(l & 3) as f32, (l >> 2 & 3) as f32, zf]);
                let better = d < best[l];
                best[l] = if better { d } else { best[l] };
                arg[l] = if better { id } else { arg[l] };
            }
            // The largest of the layer as the largest of its bits as signed integers (an
            // order-free maximum, so it runs as vectors): the order of the values, which
            // are ≥ +0 (sums of squares and the cap); a NaN would compare as the
            // largest and keep the layer searched.
            let top =
                best[16 * z..16 * z + 16].iter().fold(i32::MIN, |m, v| m.max(v.to_bits() as i32));
            layer_max[z] = f32::from_bits(top as u32);
        }
    }

    /// `p − q` for the point `q` of the triangle nearest to `p` (f32, relative to the
    /// same base, without branches: the plane's normal offset where `p` projects inside,
    /// else the offset from the nearest of the three edges).
    #[inline(always)]
    pub(super) fn offset(&self, p: [f32; 3]) -> [f32; 3] {
        let ap = [p[0] - self.a[0], p[1] - self.a[1], p[2] - self.a[2]];
        let bp = [ap[0] - self.ab[0], ap[1] - self.ab[1], ap[2] - self.ab[2]];
        let cp = [ap[0] - self.ac[0], ap[1] - self.ac[1], ap[2] - self.ac[2]];
        let dot = |r: [f32; 3], d: [f32; 3]| r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
        let seg = |r: [f32; 3], d: [f32; 3], inv: f32| {
            let t = (dot(r, d) * inv).clamp(0.0, 1.0);
            [r[0] - t * d[0], r[1] - t * d[1], r[2] - t * d[2]]
        };
        let inside = (dot(ap, self.side[0]) >= 0.0)
            & (dot(bp, self.side[1]) >= 0.0)
            & (dot(cp, self.side[2]) >= 0.0)
            & (self.inv_n2 != 0.0);
        let k = dot(ap, self.n) * self.inv_n2;
        let plane = [k * self.n[0], k * self.n[1], k * self.n[2]];
        let (e0, e1, e2) = (
            seg(ap, self.ab, self.inv_e2[0]),
            seg(ap, self.ac, self.inv_e2[1]),
            seg(bp, self.bc, self.inv_e2[2]),
        );
        let (d0, d1, d2) = (dot(e0, e0), dot(e1, e1), dot(e2, e2));
        let e01 = if d1 < d0 { e1 } else { e0 };
        let e = if d2 < d0.min(d1) { e2 } else { e01 };
        if inside {
            plane
        } else {
            e
        }
    }

    /// The squared distance (f32) from `p`, relative to the same base, without branches
    /// (see [`LocalTri::search_tile`]); inlined into loops over points, which then run as
    /// vectors.
    #[inline(always)]
    pub(super) fn dist2(&self, p: [f32; 3]) -> f32 {
        let ap = [p[0] - self.a[0], p[1] - self.a[1], p[2] - self.a[2]];
        let bp = [ap[0] - self.ab[0], ap[1] - self.ab[1], ap[2] - self.ab[2]];
        let cp = [ap[0] - self.ac[0], ap[1] - self.ac[1], ap[2] - self.ac[2]];
        let dot = |r: [f32; 3], d: [f32; 3]| r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
        let seg = |r: [f32; 3], d: [f32; 3], inv: f32| {
            let t = (dot(r, d) * inv).clamp(0.0, 1.0);
            let q = [r[0] - t * d[0], r[1] - t * d[1], r[2] - t * d[2]];
            dot(q, q)
        };
        let inside = (dot(ap, self.side[0]) >= 0.0)
            & (dot(bp, self.side[1]) >= 0.0)
            & (dot(cp, self.side[2]) >= 0.0)
            & (self.inv_n2 != 0.0);
        let h = dot(ap, self.n);
        let plane = h * h * self.inv_n2;
        let edges = seg(ap, self.ab, self.inv_e2[0])
            .min(seg(ap, self.ac, self.inv_e2[1]))
            .min(seg(bp, self.bc, self.inv_e2[2]));
        if inside {
            plane
        } else {
            edges
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The distance by a different route: the plane when the projection falls inside
    /// (barycentric signs), else the least distance to the three edges.
    fn reference(t: &Tri, p: [f64; 3]) -> f64 {
        let [a, b, c] = t.vertices();
        let n = t.normal();
        let seg = |p: [f64; 3], a: [f64; 3], b: [f64; 3]| {
            let d = sub(b, a);
            segment2(sub(p, a), d, dot(d, d))
        };
        let edges = seg(p, a, b).min(seg(p, b, c)).min(seg(p, c, a));
        let n2 = dot(n, n);
        if n2 == 0.0 {
            return edges;
        }
        let side = |a: [f64; 3], b: [f64; 3]| dot(cross(sub(b, a), sub(p, a)), n) >= 0.0;
        if side(a, b) && side(b, c) && side(c, a) {
            let h = dot(n, sub(p, a));
            return (h * h / n2).min(edges);
        }
        edges
    }

    #[test]
    fn ericson_agrees_with_plane_and_edges_everywhere() {
        let mut rng = fastrand::Rng::with_seed(7);
        let mut r = |s: f64| (rng.f64() - 0.5) * s;
        let mut worst = 0f64;
        for i in 0..20_000 {
            let a = [r(4.0), r(4.0), r(4.0)];
            let mut b = [r(4.0), r(4.0), r(4.0)];
            let mut c = [r(4.0), r(4.0), r(4.0)];
            match i % 10 {
                // Degenerate: a point, a segment (collinear), a repeated vertex.
                0 => (b, c) = (a, a),
                1 => c = [2.0 * b[0] - a[0], 2.0 * b[1] - a[1], 2.0 * b[2] - a[2]],
                2 => c = b,
                // A sliver.
                3 => c = [b[0] + 1e-9, b[1], b[2] - 1e-9],
                _ => {}
            }
            let t = Tri::new(a, b, c);
            let p = [r(10.0), r(10.0), r(10.0)];
            let (got, want) = (t.dist2(p).sqrt(), reference(&t, p).sqrt());
            assert!(got.is_finite(), "{a:?} {b:?} {c:?} {p:?}");
            // The f32 search relative to a tile: every voxel's distance within f32
            // rounding of the reference.
            let (mut best, mut arg) = ([f32::INFINITY; TILE_LEN], [u32::MAX; TILE_LEN]);
            let local = t.local([-1.0, -2.0, 0.0]);
            local.search_tile(i as u32, &mut best, &mut arg, &mut [f32::INFINITY; 4]);
            for (l, &b) in best.iter().enumerate() {
                let q = [(l & 3) as f64 - 1.0, (l >> 2 & 3) as f64 - 2.0, (l >> 4) as f64];
                let want = reference(&t, q).sqrt();
                let got = (b as f64).sqrt();
                assert!((got - want).abs() <= 1e-5 * (1.0 + want), "{i}/{l}: {got} vs {want}");
                assert_eq!(arg[l], i as u32);
                // The offset to the nearest point has the distance's length.
                let v = local.offset([(l & 3) as f32, (l >> 2 & 3) as f32, (l >> 4) as f32]);
                let len = v.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
                assert!((len - want).abs() <= 1e-5 * (1.0 + want), "{i}/{l}: |v| {len} vs {want}");
            }
            worst = worst.max((got - want).abs());
            assert!((got - want).abs() <= 1e-9 * (1.0 + want), "{i}: {got} vs {want}");
        }
        assert!(worst < 1e-9);
        // Exactly known values: the unit right triangle in z = 0.
        let t = Tri::new([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(t.dist2([0.25, 0.25, 2.0]), 4.0); // face
        assert_eq!(t.dist2([-3.0, -4.0, 0.0]), 25.0); // vertex a
        assert_eq!(t.dist2([0.5, -2.0, 0.0]), 4.0); // edge ab
        assert_eq!(t.dist2([1.0, 1.0, 0.0]), 0.5); // edge bc
    }

    /// The search with its skipped layers leaves every voxel's nearest triangle and
    /// distance as the search over all 64 voxels does, bit for bit: triangles of all
    /// sizes (slivers and degenerate ones among them) around a tile, folded in with the
    /// band's cap as the voxelizer folds them.
    #[test]
    fn skipped_layers_change_nothing() {
        let mut rng = fastrand::Rng::with_seed(11);
        let mut skipped = 0;
        for tile in 0..300 {
            let cap = [9.0f32, 2.25, 30.0][tile % 3] * (1.0 + 1e-4);
            let (mut best, mut arg) = ([cap; TILE_LEN], [u32::MAX; TILE_LEN]);
            let (mut all, mut all_arg) = ([cap; TILE_LEN], [u32::MAX; TILE_LEN]);
            let mut layer_max = [cap; 4];
            let base = [rng.f64() * 40.0 - 20.0, rng.f64() * 40.0 - 20.0, rng.f64() * 40.0 - 20.0];
            for id in 0..60u32 {
                let size = [0.3, 3.0, 12.0][rng.usize(0..3)];
                let centre = [0, 1, 2].map(|k| base[k] + 1.5 + (rng.f64() - 0.5) * 14.0);
                let mut v = || [0, 1, 2].map(|k| centre[k] + (rng.f64() - 0.5) * size);
                let (a, b, mut c) = (v(), v(), v());
                if id % 13 == 0 {
                    c = [b[0] + 1e-9, b[1], b[2] - 1e-9];
                }
                let local = Tri::new(a, b, c).local(base);
                let before = best;
                local.search_tile(id, &mut best, &mut arg, &mut layer_max);
                for l in 0..TILE_LEN {
                    let d = local.dist2([(l & 3) as f32, (l >> 2 & 3) as f32, (l >> 4) as f32]);
                    if d < all[l] {
                        (all[l], all_arg[l]) = (d, id);
                    }
                }
                skipped += usize::from(before == best);
                assert_eq!(
                    best.map(f32::to_bits),
                    all.map(f32::to_bits),
                    "tile {tile}, triangle {id}"
                );
                assert_eq!(arg, all_arg, "tile {tile}, triangle {id}");
            }
        }
        // The case the skip is for: most triangles here change no voxel of the tile.
        assert!(skipped > 9000, "{skipped}");
    }
}
