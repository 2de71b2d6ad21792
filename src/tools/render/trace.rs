//! Ray casting against the zero level set of a sparse grid (Houston et al. 2006, Sec. 6.3).
//!
//! All of it runs in *voxel space*: the voxel `c` sits at the point `c` (world position
//! `origin + h c`), so cells are unit cubes and distances are in voxels. The level set is
//! the zero set of the trilinear interpolant of the grid's values; like the paper, every
//! query is a random access that reads the stored value inside the band and ±γ outside.
//!
//! * **Empty space** is skipped with an [`Occupancy`] pyramid built from the band voxels
//!   (8³-voxel blocks, then 8× coarser levels): a ray is clipped to its box and walked
//!   block by block (a 3D DDA per level), descending only into occupied blocks, and only
//!   runs of occupied finest blocks are marched. Outside them every cell has eight
//!   non-band corners of one sign (the band separates inside from outside), so the
//!   interpolant has no zero there. This is the tile list's sparsity at a coarser grain;
//!   the paper's H-RLE grid plays the same part (its "acceleration structure").
//! * **Inside occupied blocks** the ray is sphere traced (the paper's "adaptive stepping
//!   based on the magnitude of the level set values"): a step of `SAFETY · |φ|`. The
//!   interpolant of a distance field changes by at most one voxel per voxel along each
//!   axis, so its gradient is at most √3 and a step below `|φ| / √3` cannot cross a zero;
//!   `SAFETY = 0.5` keeps that guarantee for fields whose neighbour differences reach
//!   1.15 voxels (an evolved band that is not exactly a distance).
//! * **Root refinement**: once two samples differ in sign, the Illinois variant of regula
//!   falsi on the interpolant brackets the crossing to 10⁻⁷ voxel (the paper solves the
//!   cubic of the interpolant along the ray instead; both find a zero of the same
//!   function).

use crate::storage::interpolate::Trilinear as Sampler;
use crate::storage::levelset::{Accessor, LevelSet};

/// Sphere-tracing step as a fraction of |φ| (see the module docs for why 0.5).
const SAFETY: f64 = 0.5;
/// Smallest step in voxels: a part thinner than this can be stepped over.
const MIN_STEP: f64 = 0.02;
/// Interpolant samples one ray may take before it is declared a miss (a ray grazing the
/// surface for thousands of voxels).
const MAX_SAMPLES: u32 = 1 << 17;
/// Width in voxels at which root refinement stops.
const ROOT_TOL: f64 = 1e-7;

/// What one pass over the band voxels finds out about the level set.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BandSummary {
    /// Inclusive voxel bounding box of the band voxels.
    pub lo: [i64; 3],
    pub hi: [i64; 3],
    /// Inclusive voxel bounding box of the band voxels with φ ≤ 0 (`None` if there are
    /// none).
    pub inside: Option<([i64; 3], [i64; 3])>,
    /// Whether some band voxel has φ > 0.
    pub any_outside: bool,
    /// The lowest point of the surface in voxel units along z: min over band voxels
    /// with φ ≤ 0 of `z + φ/h`. The ball of radius |φ| around an inside voxel lies
    /// inside the shape, so this never undercuts the surface, and the voxel just above
    /// the lowest point attains it to the accuracy of the stored distance.
    pub bottom_z: f64,
}

/// Summarises the band; `None` when the grid stores no band voxel.
pub(crate) fn summarise<G: LevelSet + ?Sized>(grid: &G) -> Option<BandSummary> {
    let h = grid.spec().voxel_size as f64;
    let mut s: Option<BandSummary> = None;
    grid.for_each_band_voxel(&mut |c, v| {
        let p = [c.x as i64, c.y as i64, c.z as i64];
        let b = s.get_or_insert(BandSummary {
            lo: p,
            hi: p,
            inside: None,
            any_outside: false,
            bottom_z: f64::INFINITY,
        });
        grow(&mut b.lo, &mut b.hi, p);
        // φ = 0 counts as outside, as on the grids, in fast marching and the evolution.
        if v >= 0.0 {
            b.any_outside = true;
        } else {
            b.bottom_z = b.bottom_z.min(p[2] as f64 + v as f64 / h);
            let (lo, hi) = b.inside.get_or_insert((p, p));
            grow(lo, hi, p);
        }
    });
    s
}

/// Grows the box `lo..=hi` to hold `p`.
fn grow(lo: &mut [i64; 3], hi: &mut [i64; 3], p: [i64; 3]) {
    for ((l, h), v) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
        *l = (*l).min(v);
        *h = (*h).max(v);
    }
}

/// Largest number of blocks a level stores as a dense bitmap (2 MiB of bits); a level with
/// more (a band spread over a huge box) stores its occupied blocks in a hash set.
const MAX_DENSE: i64 = 1 << 24;
/// log2 of the finest block edge (8 voxels) and of the factor between levels (8).
const FINE_SHIFT: u32 = 3;
const LEVEL_SHIFT: u32 = 3;
/// The coarsest level has at most this many blocks along every axis.
const TOP_BLOCKS: i64 = 8;

/// Which blocks of one level are occupied.
enum Blocks {
    Dense(Vec<u64>),
    Sparse(std::collections::HashSet<[i64; 3]>),
}

/// One level of the [`Occupancy`] pyramid: blocks of `2^shift` voxels, `n` per axis.
struct Level {
    shift: u32,
    n: [i64; 3],
    blocks: Blocks,
}

impl Level {
    fn new(shift: u32, n: [i64; 3]) -> Level {
        let total = n.iter().map(|&v| v as f64).product::<f64>();
        let blocks = if total <= MAX_DENSE as f64 {
            Blocks::Dense(vec![0; (total as usize).div_ceil(64)])
        } else {
            Blocks::Sparse(Default::default())
        };
        Level { shift, n, blocks }
    }

    #[inline]
    fn index(&self, b: [i64; 3]) -> usize {
        (b[0] + self.n[0] * (b[1] + self.n[1] * b[2])) as usize
    }

    fn set(&mut self, b: [i64; 3]) {
        // Only a dense level's index is computed: a hashed level's could overflow.
        let i = matches!(self.blocks, Blocks::Dense(_)).then(|| self.index(b)).unwrap_or(0);
        match &mut self.blocks {
            Blocks::Dense(bits) => bits[i >> 6] |= 1 << (i & 63),
            Blocks::Sparse(set) => {
                set.insert(b);
            }
        }
    }

    #[inline]
    fn get(&self, b: [i64; 3]) -> bool {
        match &self.blocks {
            Blocks::Dense(bits) => {
                let i = self.index(b);
                bits[i >> 6] & (1 << (i & 63)) != 0
            }
            Blocks::Sparse(set) => set.contains(&b),
        }
    }

    /// The occupied blocks, in no particular order.
    fn occupied(&self) -> Vec<[i64; 3]> {
        match &self.blocks {
            Blocks::Dense(bits) => {
                let mut out = Vec::new();
                for (w, &word) in bits.iter().enumerate() {
                    let mut m = word;
                    while m != 0 {
                        let i = (w * 64 + m.trailing_zeros() as usize) as i64;
                        m &= m - 1;
                        let x = i % self.n[0];
                        let y = (i / self.n[0]) % self.n[1];
                        out.push([x, y, i / (self.n[0] * self.n[1])]);
                    }
                }
                out
            }
            Blocks::Sparse(set) => set.iter().copied().collect(),
        }
    }
}

/// Occupancy of space as a pyramid of blocks: a block of the finest level (8³ cells) is
/// set when one of its cells has a band voxel among its eight corners; a block of the next
/// level (8× the edge) when one of its 8³ children is set, up to a level of at most 8
/// blocks per axis. The cell with base voxel `v` spans `[v, v + 1]³` in voxel space;
/// block `b` of edge `S` holds the cells with base voxels `lo + S b ..= lo + S b + S − 1`,
/// i.e. the region `[lo + S b, lo + S (b + 1)]`. Rays descend only into set blocks, so a
/// band spread over a huge box (two small shapes 2³⁰ voxels apart) costs a few steps per
/// level, not a walk over the empty space between.
pub(crate) struct Occupancy {
    lo: [i64; 3],
    /// Finest first.
    levels: Vec<Level>,
}

impl Occupancy {
    /// The pyramid of a grid's band; `summary` is that of [`summarise`].
    pub(crate) fn build<G: LevelSet + ?Sized>(grid: &G, summary: &BandSummary) -> Occupancy {
        // Cells with a band corner have base voxels in lo − 1 ..= hi.
        let lo = [summary.lo[0] - 1, summary.lo[1] - 1, summary.lo[2] - 1];
        let extent: [i64; 3] = std::array::from_fn(|a| summary.hi[a] - lo[a] + 1);
        let blocks = |shift: u32| -> [i64; 3] {
            std::array::from_fn(|a| (extent[a] + (1 << shift) - 1) >> shift)
        };
        let mut fine = Level::new(FINE_SHIFT, blocks(FINE_SHIFT));
        grid.for_each_band_voxel(&mut |c, _| {
            let b = |v: i32, a: usize| {
                ((v as i64 - 1 - lo[a]) >> FINE_SHIFT, (v as i64 - lo[a]) >> FINE_SHIFT)
            };
            let (x0, x1) = b(c.x, 0);
            let (y0, y1) = b(c.y, 1);
            let (z0, z1) = b(c.z, 2);
            for z in [z0, z1] {
                for y in [y0, y1] {
                    for x in [x0, x1] {
                        fine.set([x, y, z]);
                    }
                }
            }
        });
        let mut levels = vec![fine];
        loop {
            let last = levels.last().expect("one level");
            if last.n.iter().all(|&n| n <= TOP_BLOCKS) {
                break;
            }
            let shift = last.shift + LEVEL_SHIFT;
            let mut up = Level::new(shift, blocks(shift));
            for b in last.occupied() {
                up.set(b.map(|v| v >> LEVEL_SHIFT));
            }
            levels.push(up);
        }
        Occupancy { lo, levels }
    }
}

pub(crate) fn normalize(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (n > 0.0 && n.is_finite()).then(|| [v[0] / n, v[1] / n, v[2] / n])
}

#[inline]
fn at(o: [f64; 3], d: [f64; 3], t: f64) -> [f64; 3] {
    [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]
}

/// Finds the first zero of the interpolant along `o + t d` (voxel space, `d` a unit
/// vector) for `t` in `[t0, t1]`, marching only through occupied finest blocks.
pub(crate) fn trace<A: Accessor>(
    occ: &Occupancy,
    s: &mut Sampler<A>,
    o: [f64; 3],
    d: [f64; 3],
    t0: f64,
    t1: f64,
) -> Option<f64> {
    let top = occ.levels.len() - 1;
    let size = (1i64 << FINE_SHIFT) as f64;
    // Clip to the box of the finest level (slab test); the coarser levels cover it.
    let (mut ta, mut tb) = (t0, t1);
    for a in 0..3 {
        let lo = occ.lo[a] as f64;
        let hi = lo + size * occ.levels[0].n[a] as f64;
        if d[a] == 0.0 {
            if o[a] < lo || o[a] > hi {
                return None;
            }
            continue;
        }
        let (u, v) = ((lo - o[a]) / d[a], (hi - o[a]) / d[a]);
        ta = ta.max(u.min(v));
        tb = tb.min(u.max(v));
    }
    if ta.is_nan() || tb.is_nan() || ta >= tb {
        return None;
    }
    s.samples = 0;
    let n = occ.levels[top].n;
    let mut run = None;
    let bmax = [n[0] - 1, n[1] - 1, n[2] - 1];
    walk(occ, top, [0; 3], bmax, s, o, d, ta, tb, &mut run)
        .or_else(|| run.and_then(|start| march(s, o, d, start, tb)))
}

/// 3D DDA (Amanatides and Woo) over the blocks `bmin..=bmax` of level `k` along the ray
/// for `t` in `[ta, tb]`: descends into occupied blocks. Consecutive occupied finest
/// blocks form one run (`run` holds its start, across levels), marched when the ray
/// enters an empty block: one sphere trace per run instead of a restart per block.
#[allow(clippy::too_many_arguments)]
fn walk<A: Accessor>(
    occ: &Occupancy,
    k: usize,
    bmin: [i64; 3],
    bmax: [i64; 3],
    s: &mut Sampler<A>,
    o: [f64; 3],
    d: [f64; 3],
    ta: f64,
    tb: f64,
    run: &mut Option<f64>,
) -> Option<f64> {
    let level = &occ.levels[k];
    let size = (1i64 << level.shift) as f64;
    let p = at(o, d, ta);
    let mut b = [0i64; 3];
    let mut next = [f64::INFINITY; 3];
    let mut stride = [0i64; 3];
    // Where the ray leaves block `b` through its face on axis `a`. Computed afresh for
    // every block (not accumulated), so a face shared by two levels gives the same bits
    // at both and consecutive marched intervals meet exactly.
    let face = |a: usize, b: i64| {
        (occ.lo[a] as f64 + size * (b + (d[a] > 0.0) as i64) as f64 - o[a]) / d[a]
    };
    for a in 0..3 {
        let rel = ((p[a] - occ.lo[a] as f64) / size).floor();
        b[a] = (rel as i64).clamp(bmin[a], bmax[a]);
        if d[a] != 0.0 {
            stride[a] = if d[a] > 0.0 { 1 } else { -1 };
            next[a] = face(a, b[a]);
        }
    }
    let mut t = ta;
    loop {
        let a = if next[0] <= next[1] && next[0] <= next[2] {
            0
        } else if next[1] <= next[2] {
            1
        } else {
            2
        };
        let exit = next[a].min(tb);
        if exit > t {
            if !level.get(b) {
                if let Some(start) = run.take() {
                    let hit = march(s, o, d, start, t);
                    if hit.is_some() || s.samples > MAX_SAMPLES {
                        return hit;
                    }
                }
            } else if k == 0 {
                run.get_or_insert(t);
            } else {
                let cmin = b.map(|v| v << LEVEL_SHIFT);
                let lower = &occ.levels[k - 1].n;
                let cmax: [i64; 3] = std::array::from_fn(|i| {
                    ((b[i] << LEVEL_SHIFT) + (1 << LEVEL_SHIFT) - 1).min(lower[i] - 1)
                });
                let hit = walk(occ, k - 1, cmin, cmax, s, o, d, t, exit, run);
                if hit.is_some() || s.samples > MAX_SAMPLES {
                    return hit;
                }
            }
        }
        if exit >= tb {
            return None;
        }
        b[a] += stride[a];
        if b[a] < bmin[a] || b[a] > bmax[a] {
            return None;
        }
        t = exit;
        next[a] = face(a, b[a]);
    }
}

/// Sphere tracing over `[ta, tb]`, then root refinement at the first sign change.
fn march<A: Accessor>(
    s: &mut Sampler<A>,
    o: [f64; 3],
    d: [f64; 3],
    ta: f64,
    tb: f64,
) -> Option<f64> {
    let mut t = ta;
    let mut f = s.phi(at(o, d, t));
    if f == 0.0 {
        return Some(t);
    }
    while t < tb {
        if s.samples > MAX_SAMPLES {
            return None;
        }
        let tn = (t + (SAFETY * f.abs()).max(MIN_STEP)).min(tb);
        let fn_ = s.phi(at(o, d, tn));
        if (fn_ < 0.0) != (f < 0.0) || fn_ == 0.0 {
            return Some(refine(s, o, d, (t, f), (tn, fn_)));
        }
        t = tn;
        f = fn_;
    }
    None
}

/// The Illinois algorithm on a bracket whose ends differ in sign (or whose right end is
/// zero): secant steps, halving the weight of an end that is kept twice.
fn refine<A: Accessor>(
    s: &mut Sampler<A>,
    o: [f64; 3],
    d: [f64; 3],
    (mut a, mut fa): (f64, f64),
    (mut b, mut fb): (f64, f64),
) -> f64 {
    if fb == 0.0 {
        return b;
    }
    let mut side = 0i8;
    for _ in 0..100 {
        if b - a <= ROOT_TOL {
            break;
        }
        let mut m = (a * fb - b * fa) / (fb - fa);
        if !(m > a && m < b) {
            m = 0.5 * (a + b);
        }
        let fm = s.phi(at(o, d, m));
        if fm == 0.0 {
            return m;
        }
        if (fm < 0.0) == (fb < 0.0) {
            b = m;
            fb = fm;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        } else {
            a = m;
            fa = fm;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        }
    }
    // The secant estimate of the final bracket.
    let m = (a * fb - b * fa) / (fb - fa);
    if m >= a && m <= b {
        m
    } else {
        0.5 * (a + b)
    }
}
