//! Inside or outside by axis-aligned rays with oriented crossings and a majority vote
//! (Houston et al. 2006, Sec. 6.2.2, after Houston et al. 2003).
//!
//! For each axis `a` the mesh is rasterised onto the lattice of voxel-centre lines along
//! `a`: every triangle records a *crossing* on each line its projection covers, with the
//! line position `t` where the line meets it and an orientation `s` = +1 when the ray
//! (running towards +a) enters through the triangle's front (its normal opposes the ray),
//! −1 when it leaves. Along a line, the winding count from −∞ to a voxel is
//! `w⁻ = Σ s` over the crossings before it and the count from +∞ is `w⁺ = −Σ s` over the
//! crossings after it; for a closed, consistently oriented mesh both equal the voxel's
//! winding number, so "inside" (≠ 0) is the same answer on every half-ray. Each axis line
//! through a voxel therefore gives two votes, one per direction, and the voxel is inside
//! when more than half of the votes say so: a hole on one side of the voxel costs one
//! vote, not the whole axis, and overlapping closed parts (self-intersections) add up
//! their windings to the union.
//!
//! # Exact crossings
//! Whether a line hits a triangle is decided exactly, so that a line through a shared
//! edge or vertex is counted exactly once: the projected vertices are rounded to a fixed
//! lattice of 2⁻²⁴ voxel (the same rounding for every triangle that shares them) and the
//! 2D edge functions are evaluated in `i128` integers; a point exactly on an edge belongs
//! to the triangle whose edge is a "top-left" edge, i.e. the point is moved by a symbolic
//! ε in the direction (1, ε) across the projection plane (watertight rasterisation).
//! A triangle whose projection has zero area is missed by every line (it is missed by the
//! moved point too). The position `t` is the barycentric combination of the vertices'
//! f64 coordinates with those exact weights, so it lies on the triangle.
//!
//! The work is O(triangles + crossings): a triangle is visited row by row over the lines
//! its projection covers.

use super::distance::Tri;
use crate::coord::Coord;
use rayon::prelude::*;

/// Fixed-point bits per voxel of the projected vertices.
const FRAC: u32 = 24;

/// The crossings of one axis, grouped by line and sorted along each line.
pub(super) struct AxisLines {
    /// The axis the lines run along (0 = x, 1 = y, 2 = z).
    axis: usize,
    /// Where each line's crossings are.
    index: LineIndex,
    /// Crossing positions along the axis, voxel units, sorted within each line.
    t: Vec<f64>,
    /// Crossing orientations (+1 enters, −1 leaves).
    s: Vec<i8>,
}

/// The lines' crossings: `t[start[i]..start[i + 1]]` for line `i`.
enum LineIndex {
    /// Every line of the lines' bounding rectangle (lower corner `lo` in the two other
    /// voxel coordinates, `dims` lines a side), line `(j, k)` at `(k − lo₁) dims₀ + j − lo₀`:
    /// a line is found in one step.
    Dense { lo: [i64; 2], dims: [u64; 2], start: Vec<u32> },
    /// The lines with crossings, by sorted [`line_key`] (found by binary search).
    Sparse { keys: Vec<u64>, start: Vec<u32> },
}

impl LineIndex {
    /// The crossings of line `(j, k)`, `None` when it has none. `hint` carries a search
    /// position from one call to the next along a row of lines (`j` increasing).
    #[inline]
    fn line(&self, j: i32, k: i32, hint: &mut Option<usize>) -> Option<(usize, usize)> {
        match self {
            LineIndex::Dense { lo, dims, start } => {
                let (dj, dk) = (j as i64 - lo[0], k as i64 - lo[1]);
                if dj < 0 || dk < 0 || dj as u64 >= dims[0] || dk as u64 >= dims[1] {
                    return None;
                }
                let cell = (dk as u64 * dims[0] + dj as u64) as usize;
                let (s, e) = (start[cell] as usize, start[cell + 1] as usize);
                (s < e).then_some((s, e))
            }
            LineIndex::Sparse { keys, start } => {
                let key = line_key(j, k);
                let i = hint.get_or_insert_with(|| keys.partition_point(|&x| x < key));
                if keys.get(*i) != Some(&key) {
                    return None;
                }
                let r = (start[*i] as usize, start[*i + 1] as usize);
                *i += 1;
                Some(r)
            }
        }
    }
}

/// How the sign is decided ([`super::SignMethod`] without its docs).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Votes {
    /// Two votes per axis, three axes, inside when at least four say so.
    Majority,
    /// The x axis from −∞ only.
    Single,
}

/// Ray crossings of every axis the sign method uses.
pub(super) struct Rays {
    axes: Vec<AxisLines>,
    votes: Votes,
    /// The box of the vertices (voxel units): every voxel beyond it is outside.
    lo: [f64; 3],
    hi: [f64; 3],
}

/// `(j, k)` → a u64 whose order is k first, then j.
#[inline]
fn line_key(j: i32, k: i32) -> u64 {
    ((k as u32 ^ 0x8000_0000) as u64) << 32 | (j as u32 ^ 0x8000_0000) as u64
}

/// The other two axes of `a`, cyclic (so that `det` below is the `a` component of the
/// triangle's normal).
#[inline]
fn others(a: usize) -> (usize, usize) {
    ((a + 1) % 3, (a + 2) % 3)
}

/// One crossing: line key, position, orientation.
type Crossing = (u64, f64, i8);

impl Rays {
    /// Rasterises the triangles (vertices in voxel units) along the axes `votes` needs.
    pub(super) fn new(tris: &[Tri], votes: Votes) -> Rays {
        let axes: &[usize] = match votes {
            Votes::Majority => &[0, 1, 2],
            Votes::Single => &[0],
        };
        let axes = axes.iter().map(|&a| AxisLines::new(tris, a)).collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in tris.iter().flat_map(|t| t.vertices()) {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        Rays { axes, votes, lo, hi }
    }

    /// Bit `l` set when voxel `l` (local index, x fastest) of tile `t` is inside.
    ///
    /// A voxel beyond the box of the vertices is outside. The votes agree (its lines
    /// across the axes it is beyond meet no triangle, so at least four of its six votes
    /// say outside), and the single ray, which alone could carry an open mesh's count
    /// out to infinity, is kept to the box: the inside is bounded either way.
    pub(super) fn tile_inside(&self, t: Coord) -> u64 {
        let base = [4 * t.x, 4 * t.y, 4 * t.z];
        let in_box: [[bool; 4]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|l| {
                (self.lo[a]..=self.hi[a]).contains(&((base[a] + l as i32) as f64))
            })
        });
        // votes[l]: inside votes of voxel l.
        let mut votes = [0u8; 64];
        for lines in &self.axes {
            let a = lines.axis;
            let (b, c) = others(a);
            for lc in 0..4 {
                let k = base[c] + lc;
                let mut hint = None;
                for lb in 0..4 {
                    let j = base[b] + lb;
                    let Some((s, e)) = lines.index.line(j, k, &mut hint) else {
                        continue; // no crossing: zero votes on this line
                    };
                    let (ts, ss) = (&lines.t[s..e], &lines.s[s..e]);
                    // Per voxel of the line, the windings of the crossings before it and
                    // at or before it, in one pass over the line's crossings.
                    let x: [f64; 4] = std::array::from_fn(|la| (base[a] + la as i32) as f64);
                    let (mut below, mut upto, mut total) = ([0i32; 4], [0i32; 4], 0i32);
                    for (&tk, &sk) in ts.iter().zip(ss) {
                        let sk = sk as i32;
                        total += sk;
                        for la in 0..4 {
                            below[la] += if tk < x[la] { sk } else { 0 };
                            upto[la] += if tk <= x[la] { sk } else { 0 };
                        }
                    }
                    for la in 0..4 {
                        let mut l = [0usize; 3];
                        (l[a], l[b], l[c]) = (la, lb as usize, lc as usize);
                        let local = l[0] + 4 * l[1] + 16 * l[2];
                        let w_minus = below[la];
                        let w_plus = -(total - upto[la]);
                        votes[local] += match self.votes {
                            Votes::Majority => (w_minus != 0) as u8 + (w_plus != 0) as u8,
                            Votes::Single => (w_minus != 0) as u8,
                        };
                    }
                }
            }
        }
        let need = match self.votes {
            Votes::Majority => 4,
            Votes::Single => 1,
        };
        let mut mask = 0u64;
        for (l, &v) in votes.iter().enumerate() {
            let boxed = in_box[0][l & 3] && in_box[1][l >> 2 & 3] && in_box[2][l >> 4];
            mask |= ((v >= need && boxed) as u64) << l;
        }
        mask
    }
}

impl AxisLines {
    fn new(tris: &[Tri], a: usize) -> AxisLines {
        let chunks: Vec<Vec<Crossing>> = tris
            .par_chunks(1024)
            .map(|chunk| {
                let mut out = Vec::new();
                for tri in chunk {
                    rasterise(tri, a, &mut out);
                }
                out
            })
            .collect();
        // Equal (key, t) pairs may come in any order: a query counts crossings strictly
        // before or at-or-before a voxel, never splitting crossings at one position.
        let (all, index) = sort_crossings(chunks);
        let t = all.iter().map(|c| c.1).collect();
        let s = all.iter().map(|c| c.2).collect();
        AxisLines { axis: a, index, t, s }
    }
}

/// The crossings of `chunks` sorted by line key, then position along the line: by a
/// counting sort over the lines' bounding rectangle when it has at most four cells per
/// crossing (then each line's few crossings by position), else a comparison sort.
fn sort_crossings(chunks: Vec<Vec<Crossing>>) -> (Vec<Crossing>, LineIndex) {
    let n: usize = chunks.iter().map(Vec::len).sum();
    if n == 0 {
        return (Vec::new(), LineIndex::Sparse { keys: Vec::new(), start: vec![0] });
    }
    let jk = |key: u64| {
        let j = (key as u32 ^ 0x8000_0000) as i32 as i64;
        let k = ((key >> 32) as u32 ^ 0x8000_0000) as i32 as i64;
        (j, k)
    };
    let (mut lo, mut hi) = ([i64::MAX; 2], [i64::MIN; 2]);
    for c in chunks.iter().flatten() {
        let (j, k) = jk(c.0);
        (lo[0], hi[0]) = (lo[0].min(j), hi[0].max(j));
        (lo[1], hi[1]) = (lo[1].min(k), hi[1].max(k));
    }
    let dims = [(hi[0] - lo[0] + 1).max(0) as u64, (hi[1] - lo[1] + 1).max(0) as u64];
    match dims[0].checked_mul(dims[1]) {
        Some(cells) if n > 0 && cells <= 4 * n as u64 && n <= u32::MAX as usize => {
            let cell = |c: &Crossing| {
                let (j, k) = jk(c.0);
                ((k - lo[1]) as u64 * dims[0] + (j - lo[0]) as u64) as usize
            };
            let (mut all, start) = super::counting_sort(&chunks, cells as usize, cell, |c| *c);
            for w in start.windows(2) {
                if w[1] - w[0] > 1 {
                    all[w[0] as usize..w[1] as usize].sort_unstable_by(|p, q| p.1.total_cmp(&q.1));
                }
            }
            (all, LineIndex::Dense { lo, dims, start })
        }
        _ => {
            let mut all: Vec<Crossing> = chunks.into_iter().flatten().collect();
            all.par_sort_unstable_by(|p, q| p.0.cmp(&q.0).then(p.1.total_cmp(&q.1)));
            let mut keys = Vec::new();
            let mut start = Vec::new();
            for (i, c) in all.iter().enumerate() {
                if keys.last() != Some(&c.0) {
                    keys.push(c.0);
                    start.push(i as u32);
                }
            }
            start.push(all.len() as u32);
            (all, LineIndex::Sparse { keys, start })
        }
    }
}

/// Rounds a coordinate in voxel units to the fixed-point lattice.
#[inline]
fn fixed(u: f64) -> i64 {
    (u * (1u64 << FRAC) as f64).round() as i64
}

/// 2D edge function of P, Q relative to the point p (all fixed point): twice the signed
/// area of (p, P, Q). Exact, and `edge(p, Q, P) == -edge(p, P, Q)`.
#[inline]
fn edge(p: [i64; 2], pp: [i64; 2], q: [i64; 2]) -> i128 {
    let (u0, u1) = ((pp[0] - p[0]) as i128, (pp[1] - p[1]) as i128);
    let (v0, v1) = ((q[0] - p[0]) as i128, (q[1] - p[1]) as i128);
    u0 * v1 - u1 * v0
}

/// Whether a point on the edge with direction `d` (of a counter-clockwise triangle)
/// belongs to the triangle: the point moved by (ε, ε²) lies inside.
#[inline]
fn top_left(d: [i64; 2]) -> bool {
    d[1] < 0 || (d[1] == 0 && d[0] > 0)
}

/// Appends the crossings of one triangle with the lines along axis `a`.
fn rasterise(tri: &Tri, a: usize, out: &mut Vec<Crossing>) {
    let (b, c) = others(a);
    let v = tri.vertices();
    let q: [[i64; 2]; 3] = v.map(|p| [fixed(p[b]), fixed(p[c])]);
    let det = edge(q[0], q[1], q[2]);
    if det == 0 {
        return;
    }
    // Orient counter-clockwise: flip the sign of every edge function and direction.
    let sg: i64 = if det > 0 { 1 } else { -1 };
    // A ray along +a leaves through a triangle whose normal has a positive `a` component
    // (det > 0), and enters through one with a negative component.
    let orientation: i8 = if det > 0 { -1 } else { 1 };
    let dir = |i: usize, j: usize| [sg * (q[j][0] - q[i][0]), sg * (q[j][1] - q[i][1])];
    let incl = [top_left(dir(0, 1)), top_left(dir(1, 2)), top_left(dir(2, 0))];
    let one = 1i64 << FRAC;
    let (cmin, cmax) =
        (q.iter().map(|p| p[1]).min().unwrap(), q.iter().map(|p| p[1]).max().unwrap());
    let (bmin, bmax) =
        (q.iter().map(|p| p[0]).min().unwrap(), q.iter().map(|p| p[0]).max().unwrap());
    let (k0, k1) =
        (cmin.div_euclid(one) + (cmin.rem_euclid(one) != 0) as i64, cmax.div_euclid(one));
    let (j0, j1) =
        (bmin.div_euclid(one) + (bmin.rem_euclid(one) != 0) as i64, bmax.div_euclid(one));
    let qf: [[f64; 2]; 3] = q.map(|p| [p[0] as f64, p[1] as f64]);
    let inv_det = 1.0 / (det as f64);
    for k in k0..=k1 {
        // The span of the row (fixed point, in f64), widened by a voxel either side: the
        // exact test below decides.
        let kc = (k * one) as f64;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..3 {
            let (p, r) = (qf[i], qf[(i + 1) % 3]);
            if (p[1] - kc) * (r[1] - kc) <= 0.0 {
                let x = if p[1] == r[1] {
                    p[0]
                } else {
                    p[0] + (kc - p[1]) * (r[0] - p[0]) / (r[1] - p[1])
                };
                let x2 = if p[1] == r[1] { r[0] } else { x };
                lo = lo.min(x.min(x2));
                hi = hi.max(x.max(x2));
            }
        }
        if lo > hi {
            continue;
        }
        let js = ((lo / one as f64).floor() as i64 - 1).max(j0);
        let je = ((hi / one as f64).ceil() as i64 + 1).min(j1);
        for j in js..=je {
            let p = [j * one, k * one];
            let e = [edge(p, q[1], q[2]), edge(p, q[2], q[0]), edge(p, q[0], q[1])];
            // e[0] is the edge B→C (weight of A), e[1] C→A, e[2] A→B.
            let inside = |ev: i128, inc: bool| {
                let ev = ev * sg as i128;
                ev > 0 || (ev == 0 && inc)
            };
            if inside(e[2], incl[0]) && inside(e[0], incl[1]) && inside(e[1], incl[2]) {
                let t = (e[0] as f64 * v[0][a] + e[1] as f64 * v[1][a] + e[2] as f64 * v[2][a])
                    * inv_det;
                out.push((line_key(j as i32, k as i32), t, orientation));
            }
        }
    }
}
