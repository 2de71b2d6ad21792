//! DT-Grid against a dense reference and brute-force oracles.

use super::*;
use crate::storage::shapes::Shape;
use fastrand::Rng;

// ---------------------------------------------------------------------------
// Dense ground truth
// ---------------------------------------------------------------------------

/// A clamped signed distance field sampled on a box of voxels.
struct Dense {
    spec: GridSpec,
    min: Coord,
    dims: [i32; 3],
    phi: Vec<f32>,
}

impl Dense {
    fn idx(&self, c: Coord) -> Option<usize> {
        let (x, y, z) = (c.x - self.min.x, c.y - self.min.y, c.z - self.min.z);
        if x < 0 || y < 0 || z < 0 || x >= self.dims[0] || y >= self.dims[1] || z >= self.dims[2] {
            return None;
        }
        Some((x + self.dims[0] * (y + self.dims[1] * z)) as usize)
    }

    fn get(&self, c: Coord) -> f32 {
        self.phi[self.idx(c).unwrap_or_else(|| panic!("{c} outside the dense box"))]
    }

    fn coords(&self) -> impl Iterator<Item = Coord> + '_ {
        let m = self.min;
        let d = self.dims;
        (0..d[2]).flat_map(move |z| {
            (0..d[1])
                .flat_map(move |y| (0..d[0]).map(move |x| Coord::new(m.x + x, m.y + y, m.z + z)))
        })
    }

    /// Band voxels in order.
    fn band(&self) -> Vec<(Coord, f32)> {
        let g = self.spec.gamma();
        self.coords().map(|c| (c, self.get(c))).filter(|(_, v)| v.abs() < g).collect()
    }
}

/// A random union of 1–4 spheres and boxes, at negative and positive coordinates, on a
/// box with a margin of ≥ 6 voxels around the band (room for dilation by 3 and the
/// random-access box 2 voxels beyond the band).
fn random_scene(rng: &mut Rng, spec: GridSpec) -> Dense {
    let vs = spec.voxel_size as f64;
    let n = rng.usize(1..=4);
    let mut shapes = Vec::new();
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for _ in 0..n {
        // Centres and sizes in voxels, converted to world units.
        let c = [0; 3].map(|_: i32| (rng.f64() * 44.0 - 22.0) * vs);
        let s = if rng.bool() {
            let r = (2.5 + rng.f64() * 9.0) * vs;
            Shape::Sphere { center: c, radius: r }
        } else {
            let b = [0; 3].map(|_: i32| (1.5 + rng.f64() * 8.0) * vs);
            Shape::Box { center: c, half_extents: b }
        };
        let ext = match &s {
            Shape::Sphere { radius, .. } => [*radius; 3],
            Shape::Box { half_extents, .. } => *half_extents,
            _ => unreachable!("spheres and boxes only"),
        };
        for i in 0..3 {
            lo[i] = lo[i].min(c[i] - ext[i]);
            hi[i] = hi[i].max(c[i] + ext[i]);
        }
        shapes.push(s);
    }
    let margin = spec.half_width as f64 + 7.0;
    let min = Coord::new(
        (lo[0] / vs - margin).floor() as i32,
        (lo[1] / vs - margin).floor() as i32,
        (lo[2] / vs - margin).floor() as i32,
    );
    let max = [0, 1, 2].map(|i| (hi[i] / vs + margin).ceil() as i32);
    let dims = [max[0] - min.x + 1, max[1] - min.y + 1, max[2] - min.z + 1];
    let mut d = Dense { spec, min, dims, phi: vec![0.0; (dims[0] * dims[1] * dims[2]) as usize] };
    let g = spec.gamma();
    let cs: Vec<Coord> = d.coords().collect();
    for (i, c) in cs.into_iter().enumerate() {
        let p = spec.world(c);
        let v = shapes.iter().map(|s| s.sdf(p)).fold(f64::MAX, f64::min) as f32;
        d.phi[i] = v.clamp(-g, g);
    }
    d
}

fn specs() -> [GridSpec; 3] {
    [
        GridSpec::new(1.0, [0.0; 3], 3.0).unwrap(),
        GridSpec::new(0.5, [0.0; 3], 2.0).unwrap(),
        GridSpec::new(1.0, [0.0; 3], 2.0).unwrap(),
    ]
}

fn build(points: &[(Coord, f32)], spec: GridSpec) -> DtGrid {
    let g = DtGrid::from_sorted(spec, points.iter().copied()).unwrap();
    g.check_invariants().unwrap();
    g
}

fn offset(c: Coord, o: Coord) -> Option<Coord> {
    c.checked_add(o)
}

/// Brute-force Chebyshev dilation of a set of points, as a mask over the dense box.
fn dilate_mask(d: &Dense, keep: impl Fn(Coord) -> bool, h: i32) -> Vec<bool> {
    let mut m: Vec<bool> = d.coords().map(&keep).collect();
    let dims = d.dims;
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let src = m.clone();
        for c in d.coords() {
            let i = d.idx(c).unwrap();
            if !src[i] {
                continue;
            }
            let p = [c.x - d.min.x, c.y - d.min.y, c.z - d.min.z][axis];
            for s in -h..=h {
                let q = p + s;
                assert!(q >= 0 && q < dims[axis], "dense box too small for the dilation");
                m[(i as i32 + s * strides[axis]) as usize] = true;
            }
        }
    }
    m
}

// ---------------------------------------------------------------------------
// The scenes
// ---------------------------------------------------------------------------

fn scenes() -> Vec<Dense> {
    let mut out = Vec::new();
    let mut rng = Rng::with_seed(0x005e_edd7);
    for spec in specs() {
        for _ in 0..2 {
            out.push(random_scene(&mut rng, spec));
        }
    }
    out
}

#[test]
fn random_access_matches_dense_truth() {
    for d in scenes() {
        let band = d.band();
        let g = build(&band, d.spec);
        assert_eq!(g.len(), band.len());
        assert_eq!(g.band_voxels(), band.len());
        let (lo, hi) = g.bounding_box().unwrap();
        let exp_lo =
            band.iter().map(|p| p.0).fold(Coord::new(i32::MAX, i32::MAX, i32::MAX), |a, c| {
                Coord::new(a.x.min(c.x), a.y.min(c.y), a.z.min(c.z))
            });
        let exp_hi =
            band.iter().map(|p| p.0).fold(Coord::new(i32::MIN, i32::MIN, i32::MIN), |a, c| {
                Coord::new(a.x.max(c.x), a.y.max(c.y), a.z.max(c.z))
            });
        assert_eq!((lo, hi), (exp_lo, exp_hi));
        let mut stored = 0;
        for z in lo.z - 2..=hi.z + 2 {
            for y in lo.y - 2..=hi.y + 2 {
                for x in lo.x - 2..=hi.x + 2 {
                    let c = Coord::new(x, y, z);
                    let want = d.get(c);
                    assert_eq!(g.value(c).to_bits(), want.to_bits(), "at {c}");
                    assert_eq!(g.is_inside(c), want < 0.0, "at {c}");
                    match g.find(c) {
                        Ok(i) => {
                            stored += 1;
                            assert_eq!(g.values()[i], want);
                            assert_eq!(g.locate(c).unwrap().index(), i);
                        }
                        Err(inside) => {
                            assert_eq!(inside, want < 0.0);
                            assert!(g.locate(c).is_none());
                        }
                    }
                }
            }
        }
        assert_eq!(stored, band.len());
    }
}

#[test]
fn iter_visits_pushed_points_in_order() {
    for d in scenes() {
        let band = d.band();
        let g = build(&band, d.spec);
        let got: Vec<(Coord, f32)> = g.iter().collect();
        assert_eq!(got, band);
        let mut it = g.iter();
        assert_eq!(it.len(), band.len());
        let mut k = 0;
        while let Some(loc) = it.peek_locator() {
            assert_eq!(loc.coord(), band[k].0);
            assert_eq!(loc.index(), k);
            assert_eq!(g.locate(loc.coord()), Some(loc));
            it.next();
            k += 1;
        }
        assert_eq!(k, band.len());
        // fold (nested loops) agrees with next()
        let mut folded = Vec::new();
        g.iter().for_each(|p| folded.push(p));
        assert_eq!(folded, band);
        // fold after a partial traversal
        let mut it = g.iter();
        for _ in 0..band.len() / 3 {
            it.next();
        }
        let rest: Vec<_> = it.fold(Vec::new(), |mut v, p| {
            v.push(p);
            v
        });
        assert_eq!(rest, band[band.len() / 3..]);
    }
}

fn check_stencil(g: &DtGrid, st: &Stencil, expected_centres: &[(Coord, f32)]) {
    let mut it = StencilIter::new(g, st);
    let mut k = 0;
    while it.advance() {
        let c = it.center();
        assert_eq!(c, expected_centres[k].0);
        assert_eq!(it.center_index(), k);
        assert_eq!(it.locator().unwrap().coord(), c);
        for (j, &o) in st.offsets().iter().enumerate() {
            // Targets beyond i32 are checked in `near_the_i32_limits`.
            if let Some(t) = offset(c, o) {
                assert_eq!(
                    it.values()[j].to_bits(),
                    g.value(t).to_bits(),
                    "centre {c}, offset {o}"
                );
            }
        }
        k += 1;
    }
    assert_eq!(k, expected_centres.len());
    assert!(!it.advance(), "advance after the end stays false");
}

#[test]
fn stencil_iterator_matches_random_access() {
    let mut rng = Rng::with_seed(77);
    for d in scenes() {
        let band = d.band();
        let g = build(&band, d.spec);
        for st in [Stencil::star7(), Stencil::box27(), Stencil::weno5()] {
            check_stencil(&g, &st, &band);
        }
        // An arbitrary stencil: unsorted, repeated and far offsets.
        let mut offs: Vec<Coord> = (0..12)
            .map(|_| Coord::new(rng.i32(-6..=6), rng.i32(-6..=6), rng.i32(-6..=6)))
            .collect();
        offs.push(offs[3]);
        offs.push(Coord::new(0, 0, 40));
        offs.push(Coord::new(-40, 0, 0));
        check_stencil(&g, &Stencil::new(offs).unwrap(), &band);
        // for_each agrees with advance()
        let mut n = 0;
        StencilIter::new(&g, &Stencil::weno5()).for_each(|c, i, v| {
            assert_eq!(c, band[i].0);
            assert_eq!(v[0], band[i].1);
            assert_eq!(v[6], g.value(Coord::new(c.x + 3, c.y, c.z)));
            n += 1;
        });
        assert_eq!(n, band.len());
    }
}

#[test]
fn stencil_layouts() {
    let s = Stencil::star7();
    assert_eq!(s.len(), 7);
    assert_eq!(s.index_of(Coord::new(0, -1, 0)), Some(3));
    assert_eq!(s.index_of(Coord::new(0, 0, 1)), Some(6));
    let b = Stencil::box27();
    assert_eq!(b.len(), 27);
    assert_eq!(b.index_of(Coord::new(0, 0, 0)), Some(crate::coord::MID));
    let w = Stencil::weno5();
    assert_eq!(w.len(), 19);
    for a in 0..3 {
        for s in [-3i32, -2, -1, 1, 2, 3] {
            let mut o = [0; 3];
            o[a] = s;
            let want = if s < 0 { 1 + 6 * a + (s + 3) as usize } else { 6 * a + (s + 3) as usize };
            assert_eq!(w.index_of(Coord::new(o[0], o[1], o[2])), Some(want));
        }
    }
    assert!(Stencil::new(vec![]).is_err());
}

#[test]
fn locator_neighbours_match_random_access() {
    for d in scenes() {
        let band = d.band();
        let g = build(&band, d.spec);
        for &(c, v) in &band {
            let loc = g.locate(c).unwrap();
            assert_eq!(g.value_at(&loc), v);
            for axis in Axis::ALL {
                let u = axis.unit();
                for delta in [-9, -4, -3, -2, -1, 0, 1, 2, 3, 4, 9] {
                    let t = Coord::new(c.x + delta * u.x, c.y + delta * u.y, c.z + delta * u.z);
                    let want = g.value(t);
                    assert_eq!(
                        g.neighbour(&loc, axis, delta).to_bits(),
                        want.to_bits(),
                        "{c} {axis:?} {delta}"
                    );
                    match g.neighbour_locator(&loc, axis, delta) {
                        Ok(l) => assert_eq!(Some(l), g.locate(t)),
                        Err(inside) => {
                            assert!(g.locate(t).is_none());
                            assert_eq!(inside, want < 0.0);
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn dilation_matches_brute_force() {
    let mut reuse = DtGrid::default();
    for d in scenes() {
        let band = d.band();
        let g = build(&band, d.spec);
        let gamma = d.spec.gamma();
        for h in 0..=3 {
            let dil = g.dilate(h).unwrap();
            dil.check_invariants().unwrap();
            let mask = dilate_mask(&d, |c| d.get(c).abs() < gamma, h as i32);
            assert_eq!(dil.len(), mask.iter().filter(|&&b| b).count(), "h = {h}");
            for (c, v) in dil.iter() {
                assert!(mask[d.idx(c).unwrap()], "{c} is not within {h} of the band");
                // Old points keep their values; new ones lie outside the band, where the
                // clamped truth is exactly ±γ with the right sign.
                assert_eq!(v.to_bits(), d.get(c).to_bits(), "h = {h} at {c}");
            }
            g.dilate_into(h, &mut reuse).unwrap();
            assert!(reuse == dil);
        }
    }
}

#[test]
fn rebuild_matches_brute_force() {
    for d in scenes() {
        let band = d.band();
        let g = build(&band, d.spec);
        let (gamma, vs) = (d.spec.gamma(), d.spec.voxel_size);
        for (keep_below, h) in [(1.25 * vs, 1), (0.75 * gamma, 2), (1.1 * vs, 3)] {
            let r = g.rebuild(keep_below, h).unwrap();
            r.check_invariants().unwrap();
            let mask = dilate_mask(&d, |c| d.get(c).abs() < keep_below, h as i32);
            assert_eq!(r.len(), mask.iter().filter(|&&b| b).count());
            for (c, v) in r.iter() {
                assert!(mask[d.idx(c).unwrap()]);
                let t = d.get(c);
                let want = if t.abs() < keep_below { t } else { d.spec.background(t < 0.0) };
                assert_eq!(v.to_bits(), want.to_bits(), "kb {keep_below}, h {h} at {c}");
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Random sparse sets: the sign rule itself, against a brute-force oracle
// ---------------------------------------------------------------------------

/// The sign rule on a sorted point list: outside for an absent column; else the sign of
/// the nearest stored value to the left in the column, or of the column's first value.
fn oracle(points: &[(Coord, f32)], c: Coord, gamma: f32) -> f32 {
    if let Ok(i) = points.binary_search_by(|p| p.0.cmp(&c)) {
        return points[i].1;
    }
    let col: Vec<&(Coord, f32)> = points.iter().filter(|p| p.0.z == c.z && p.0.y == c.y).collect();
    let Some(first) = col.first() else { return gamma };
    let v = col.iter().rev().find(|p| p.0.x < c.x).map_or(first.1, |p| p.1);
    if v < 0.0 {
        -gamma
    } else {
        gamma
    }
}

fn random_sparse(rng: &mut Rng, base: Coord) -> Vec<(Coord, f32)> {
    let (nx, ny, nz) = (rng.i32(1..24), rng.i32(1..6), rng.i32(1..6));
    let density = rng.f32() * 0.9 + 0.05;
    let mut pts = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                if rng.f32() < density {
                    let v = match rng.u8(0..10) {
                        0 => 0.0,
                        1 => -0.0,
                        2 => 3.0,
                        3 => -3.0,
                        _ => rng.f32() * 6.0 - 3.0,
                    };
                    pts.push((Coord::new(base.x + x, base.y + y, base.z + z * 3), v));
                }
            }
        }
    }
    pts
}

#[test]
fn sparse_sets_follow_the_sign_rule() {
    let mut rng = Rng::with_seed(4242);
    let spec = GridSpec::default();
    let gamma = spec.gamma();
    for round in 0..150 {
        let base = Coord::new(rng.i32(-40..40), rng.i32(-40..40), rng.i32(-40..40));
        let pts = random_sparse(&mut rng, base);
        let g = build(&pts, spec);
        assert_eq!(g.iter().collect::<Vec<_>>(), pts);
        let lo = base.wrapping_sub(Coord::new(8, 4, 8));
        let mut all = Vec::new();
        for z in 0..32 {
            for y in 0..14 {
                for x in 0..44 {
                    let c = lo.wrapping_add(Coord::new(x, y, z));
                    let want = oracle(&pts, c, gamma);
                    assert_eq!(g.value(c).to_bits(), want.to_bits(), "round {round} at {c}");
                    all.push(c);
                }
            }
        }
        let st = Stencil::new(
            (0..10)
                .map(|_| Coord::new(rng.i32(-7..=7), rng.i32(-3..=3), rng.i32(-4..=4)))
                .collect(),
        )
        .unwrap();
        check_stencil(&g, &st, &pts);
        for h in [1, 2] {
            let dil = g.dilate(h).unwrap();
            dil.check_invariants().unwrap();
            let expect: Vec<(Coord, f32)> = all
                .iter()
                .copied()
                .filter(|c| pts.iter().any(|p| p.0.chebyshev(*c) <= h as i64))
                .map(|c| (c, oracle(&pts, c, gamma)))
                .collect();
            assert_eq!(dil.iter().collect::<Vec<_>>(), expect, "round {round}, h {h}");
        }
    }
}

// ---------------------------------------------------------------------------
// Edge cases
// ---------------------------------------------------------------------------

#[test]
fn empty_grid() {
    let g = DtGrid::default();
    g.check_invariants().unwrap();
    assert!(g.is_empty());
    assert_eq!(g.len(), 0);
    assert_eq!(g.value(Coord::new(1, 2, 3)), 3.0);
    assert_eq!(g.find(Coord::new(0, 0, 0)), Err(false));
    assert!(g.locate(Coord::new(0, 0, 0)).is_none());
    assert_eq!(g.iter().next(), None);
    assert_eq!(g.bounding_box(), None);
    assert_eq!(g.last(), None);
    let mut it = StencilIter::new(&g, &Stencil::box27());
    assert!(!it.advance());
    assert!(!it.advance());
    let d = g.dilate(2).unwrap();
    assert!(d.is_empty());
    d.check_invariants().unwrap();
    assert!(g.rebuild(1.0, 1).unwrap().is_empty());
    assert_eq!(g.memory().values, 0);
}

#[test]
fn single_point() {
    let spec = GridSpec::default();
    let mut g = DtGrid::new(spec);
    let c = Coord::new(-5, 7, -9);
    g.push(c, -1.5).unwrap();
    g.check_invariants().unwrap();
    assert_eq!(g.len(), 1);
    assert_eq!(g.value(c), -1.5);
    // Same column: sign of the only value on both sides; other columns outside.
    assert_eq!(g.value(Coord::new(-6, 7, -9)), -3.0);
    assert_eq!(g.value(Coord::new(100, 7, -9)), -3.0);
    assert_eq!(g.value(Coord::new(-5, 8, -9)), 3.0);
    assert_eq!(g.value(Coord::new(-5, 7, -8)), 3.0);
    assert_eq!(g.bounding_box(), Some((c, c)));
    let mut it = StencilIter::new(&g, &Stencil::box27());
    assert!(it.advance());
    assert_eq!(it.center(), c);
    for (j, o) in Stencil::box27().offsets().iter().enumerate() {
        assert_eq!(it.values()[j], g.value(c.checked_add(*o).unwrap()));
    }
    assert!(!it.advance());
    let d = g.dilate(1).unwrap();
    assert_eq!(d.len(), 27);
    for (p, v) in d.iter() {
        assert_eq!(
            v,
            if p == c {
                -1.5
            } else if p.y == c.y && p.z == c.z {
                -3.0
            } else {
                3.0
            }
        );
    }
    let loc = g.locate(c).unwrap();
    assert_eq!(g.neighbour(&loc, Axis::X, 1), -3.0);
    assert_eq!(g.neighbour(&loc, Axis::X, -1), -3.0);
    assert_eq!(g.neighbour(&loc, Axis::Y, 1), 3.0);
    assert_eq!(g.neighbour(&loc, Axis::Z, -1), 3.0);
}

#[test]
fn errors() {
    let mut g = DtGrid::default();
    g.push(Coord::new(0, 0, 0), 1.0).unwrap();
    g.push(Coord::new(1, 0, 0), 1.0).unwrap();
    let before = g.clone();
    assert_eq!(
        g.push(Coord::new(1, 0, 0), 0.0),
        Err(GridError::NotSorted { last: Coord::new(1, 0, 0), coord: Coord::new(1, 0, 0) })
    );
    assert!(matches!(g.push(Coord::new(5, -1, 0), 0.0), Err(GridError::NotSorted { .. })));
    assert!(matches!(g.push(Coord::new(5, 5, -1), 0.0), Err(GridError::NotSorted { .. })));
    assert_eq!(
        g.push(Coord::new(9, 0, 0), f32::NAN),
        Err(GridError::NaN { coord: Coord::new(9, 0, 0) })
    );
    assert!(g == before);
    // Clamping.
    g.push(Coord::new(3, 0, 0), 100.0).unwrap();
    g.push(Coord::new(4, 0, 0), f32::NEG_INFINITY).unwrap();
    assert_eq!(&g.values()[2..], &[3.0, -3.0]);
    g.check_invariants().unwrap();
    assert!(g.rebuild(f32::NAN, 1).is_err());
}

#[test]
fn near_the_i32_limits() {
    let spec = GridSpec::default();
    let (lo, hi) = (i32::MIN, i32::MAX);
    let pts = vec![
        (Coord::new(lo, lo, lo), -1.0),
        (Coord::new(lo + 1, lo, lo), 1.0),
        (Coord::new(hi, lo, lo), 0.5),
        (Coord::new(0, hi - 1, lo), -0.5),
        (Coord::new(hi - 1, hi, lo), 2.0),
        (Coord::new(hi, hi, lo), 2.0),
        (Coord::new(lo, lo, hi - 2), 0.25),
        (Coord::new(hi, hi, hi), -2.0),
    ];
    let g = build(&pts, spec);
    assert_eq!(g.iter().collect::<Vec<_>>(), pts);
    for &(c, v) in &pts {
        assert_eq!(g.value(c), v);
    }
    assert_eq!(g.value(Coord::new(hi - 1, lo, lo)), 3.0); // gap after value 1.0
    assert_eq!(g.value(Coord::new(hi - 5, hi, hi)), -3.0); // before the first value -2.0
    assert_eq!(g.bounding_box(), Some((Coord::new(lo, lo, lo), Coord::new(hi, hi, hi))));
    // Neighbours beyond the range read as not stored.
    let loc = g.locate(Coord::new(hi, hi, hi)).unwrap();
    assert_eq!(g.neighbour(&loc, Axis::X, 1), -3.0);
    assert_eq!(g.neighbour(&loc, Axis::Y, 1), 3.0);
    assert_eq!(g.neighbour(&loc, Axis::Z, i32::MAX), 3.0);
    let loc = g.locate(Coord::new(lo, lo, lo)).unwrap();
    assert_eq!(g.neighbour(&loc, Axis::X, -1), -3.0);
    assert_eq!(g.neighbour(&loc, Axis::X, i32::MIN), -3.0);
    assert_eq!(g.neighbour(&loc, Axis::Z, -1), 3.0);
    // Stencils that reach past the range: unrepresentable targets read as not stored.
    let st = Stencil::new(vec![
        Coord::new(3, 0, 0),
        Coord::new(-3, 0, 0),
        Coord::new(0, 2, 0),
        Coord::new(0, 0, -1),
    ])
    .unwrap();
    let mut it = StencilIter::new(&g, &st);
    let mut k = 0;
    while it.advance() {
        let c = it.center();
        for (j, &o) in st.offsets().iter().enumerate() {
            let want = match c.checked_add(o) {
                Some(t) => g.value(t),
                None if o.x > 0 => g.value(Coord::new(hi, c.y, c.z)).signum() * 3.0,
                None if o.x < 0 => {
                    let first = pts.iter().find(|p| p.0.y == c.y && p.0.z == c.z).unwrap().1;
                    first.signum() * 3.0
                }
                None => 3.0,
            };
            assert_eq!(it.values()[j], want, "centre {c} offset {o}");
        }
        k += 1;
    }
    assert_eq!(k, pts.len());
    // Dilation past the limit fails cleanly, naming a stored point.
    let mut out = DtGrid::default();
    assert!(matches!(g.dilate(1), Err(GridError::OutOfRange { .. })));
    assert!(matches!(g.dilate_into(1, &mut out), Err(GridError::OutOfRange { .. })));
    assert!(out.is_empty());
    let inner =
        build(&[(Coord::new(hi - 1, lo + 1, 0), -1.0), (Coord::new(lo + 1, hi - 1, 0), 1.0)], spec);
    let d = inner.dilate(1).unwrap();
    assert_eq!(d.len(), 54);
    assert_eq!(d.bounding_box(), Some((Coord::new(lo, lo, -1), Coord::new(hi, hi, 1))));
    assert_eq!(
        inner.dilate(2),
        Err(GridError::OutOfRange { coord: Coord::new(hi - 1, lo + 1, 0) })
    );
    assert_eq!(
        inner.dilate(u32::MAX).map(|g| g.len()),
        Err(GridError::OutOfRange { coord: Coord::new(hi - 1, lo + 1, 0) })
    );
}

#[test]
fn memory_report_counts_every_array() {
    let d = scenes().remove(0);
    let band = d.band();
    let g = build(&band, d.spec);
    let m = g.memory();
    assert_eq!(m.values, 4 * g.len());
    let [c1, c2, c3] = g.num_components();
    let n1 = g.l1.points();
    let n2 = g.num_columns();
    // ncoord (2 i32 per component) + acc (C + 1 u32) per level + IndexPairs (n + 1) × 8.
    let want = 4 * (2 * (c1 + c2 + c3) + (c1 + 1) + (c2 + 1) + (c3 + 1)) + 8 * (n1 + 1 + n2 + 1);
    assert_eq!(m.indices, want);
    assert_eq!(m.flags, 0);
    let mut shrunk = g.clone();
    shrunk.clear();
    assert!(shrunk.is_empty());
    shrunk.check_invariants().unwrap();
    assert!(shrunk.memory().slack >= m.values);
}
