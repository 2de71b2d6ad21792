//! The distance march of [`super::dense_distance`] on a flat array: no sparse store, no
//! hash map, no per-voxel coordinates — for dense arrays without periodic axes.
//!
//! The march is the one of [`super::march`] (Bærentzen, *On the Implementation of Fast
//! Marching Methods for 3D Lattices*, Technical Report IMM-REP-2001-13 (2001), Sec. 2.1,
//! Fig. 3; the updates of Sec. 3 and Sec. 4), on a copy of the box padded by one layer
//! of wall voxels along every axis longer than one voxel, so the six neighbours of a box
//! voxel and the second neighbours of a frozen one are found by adding strides, without
//! bounds checks; walls and obstacles are never trial, never frozen.
//!
//! **Same values, bit for bit.** The update reads the same frozen neighbours in the same
//! order and solves the same terms ([`super::march::solve_terms`]); the march freezes
//! voxels in the same order — the heap orders by (arrival time, coordinate), a strict
//! total order, and the padded index of a voxel is in coordinate order (z, then y, then
//! x), so any heap that extracts the least entry of that order extracts the same
//! sequence. The heap here is 16-ary (a quarter of the depth of a binary heap, and the
//! sixteen children of a node are adjacent in memory).
//!
//! **Two sides, two threads.** A voxel's update reads the frozen voxels of its own side
//! and the interface only, and an open voxel off the interface has no open neighbour of
//! the other sign, so the inside and the outside are two independent marches: each runs
//! on its own padded box (the bounding box of its side's voxels grown by two), where the
//! other side's voxels off the interface are walls, and freezes its voxels in the order
//! of the one march over both restricted to its side — same values on any thread count.
//!
//! **One array.** A voxel that is not frozen holds a quiet NaN in place of its value, its
//! state in the upper bits (far, trial, wall) and, when trial, its heap slot in the lower
//! ones. The update's comparisons reject NaN, so it reads a neighbour's value without
//! first reading a state.
//!
//! The interface initialisation (each voxel's distance estimate from its own star) and
//! the first trial layer (each voxel's update from the frozen interface, for the far
//! neighbours of the interface voxels only) depend on nothing the march changes, so they
//! run on all threads, one row per task, and give the same values on any thread count.

use super::march::{solve_terms, Lattice, Term};
use super::source::interface_distance;
use super::FmmError;
use crate::progress::{Progress, Ticker};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// The result of a dense march: one value per voxel (x fastest) and whether the march
/// reached it. Voxels not reached (obstacles, cut off by obstacles, beyond `narrow`) hold
/// 0.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseMarch {
    /// The marched value (distance in world units, or travel time) per voxel.
    pub values: Vec<f32>,
    /// Whether the march froze the voxel (false: an obstacle, cut off, beyond `narrow`).
    pub reached: Vec<bool>,
}

/// The states of the voxels that are not frozen, as the upper 32 bits of a quiet NaN held
/// in place of their value (a frozen voxel holds its finite value): far, trial (the lower
/// 32 bits hold its heap handle), and wall (padding, obstacles, the other side).
const FAR: u64 = 0xFFF8_0001;
const TRIAL: u64 = 0xFFF8_0002;
const WALL: u64 = 0xFFF8_0003;

/// The value of a voxel in state `tag` with `low` as its lower bits.
#[inline(always)]
fn boxed(tag: u64, low: u32) -> f64 {
    f64::from_bits(tag << 32 | low as u64)
}

/// The state of a voxel's value (any other number: frozen).
#[inline(always)]
fn tag_of(v: f64) -> u64 {
    v.to_bits() >> 32
}

/// Units of the progress, and how many voxels are frozen between reports (as the sparse
/// march).
const PROGRESS_UNITS: u64 = 1000;
const PROGRESS_EVERY: u64 = 1 << 14;

/// A heap entry: the arrival time's bits in total order (bits 64..128) and the padded
/// index (bits 0..32), so that the least entry is the least (time, coordinate).
#[inline(always)]
fn entry(t: f64, i: usize) -> u128 {
    let b = t.to_bits();
    // The bits of an f64 as an unsigned key in `f64::total_cmp` order.
    let k = if b >> 63 == 1 { !b } else { b | 1 << 63 };
    ((k as u128) << 64) | i as u128
}

/// The padded index of an entry.
#[inline(always)]
fn index_of(e: u128) -> usize {
    e as u32 as usize
}

/// Whether the flat march can index the padded box of `dims` (entries hold 32-bit
/// indices).
pub(super) fn fits(dims: [usize; 3]) -> bool {
    dims.iter()
        .map(|&n| n + 2 * usize::from(n > 1))
        .try_fold(1usize, |a, n| a.checked_mul(n))
        .is_some_and(|t| t <= u32::MAX as usize)
}

#[inline(always)]
fn time_of(e: u128) -> f64 {
    let k = (e >> 64) as u64;
    f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
}

/// The march of one side (inside or outside) over its padded box.
struct Flat {
    /// Per voxel of the padded box: the arrival time in march units of a frozen voxel
    /// (its signed value times [`Flat::sign`]: the interface voxels of the other side
    /// hold negative times), or the state of any other (a NaN, see [`FAR`]). The voxels
    /// of the other side that are not on the interface are walls: the march of one side
    /// never reads them.
    value: Vec<f64>,
    /// −1 inside, 1 outside: a frozen voxel's signed value is `sign · time` (negation
    /// is exact, so the times are those of the one march's `sign · value`, bit for bit;
    /// holding times saves the update a multiplication per neighbour read).
    sign: f64,
    /// The box's first array voxel, the padding per axis (1 along the array's axes longer
    /// than one voxel) and the strides of the padded box.
    lo: [usize; 3],
    pad: [usize; 3],
    strides: [usize; 3],
    /// Per active axis (longer than one voxel), in axis order: the stride and the term
    /// factor `(h₀ / hₐ)²`.
    axes: Vec<(usize, f64)>,
    /// The trial voxels' entries, a 16-ary min-heap (the children of slot `p` are
    /// `16p + 1 ..= 16p + 16`).
    heap: Vec<u128>,
}

impl Flat {
    /// The padded index of array voxel `(x, y, z)` (inside the box).
    #[inline(always)]
    fn index(&self, x: usize, y: usize, z: usize) -> usize {
        let [sx, sy, sz] = self.strides;
        (x - self.lo[0] + self.pad[0]) * sx
            + (y - self.lo[1] + self.pad[1]) * sy
            + (z - self.lo[2] + self.pad[2]) * sz
    }

    /// Places `e` at heap slot `p` or above.
    #[inline(always)]
    fn sift_up(&mut self, mut p: usize, e: u128) {
        while p > 0 {
            let parent = (p - 1) / 16;
            let pe = self.heap[parent];
            if pe <= e {
                break;
            }
            self.place(p, pe);
            p = parent;
        }
        self.place(p, e);
    }

    /// Places `e` at heap slot `p` or below.
    #[inline(always)]
    fn sift_down(&mut self, mut p: usize, e: u128) {
        let n = self.heap.len();
        loop {
            let first = 16 * p + 1;
            if first >= n {
                break;
            }
            let (c, ce) = if first + 16 <= n {
                // Sixteen children: a tournament of independent comparisons, four deep
                // (entries are distinct, so the least is the loop's below; a loop's
                // dependent chain of comparisons was slower with four children). A pop
                // sifts the last entry down nearly to the bottom (pushes and decreases
                // hardly move: at 96³, 0.87 M pops moved entries down 5.9 M levels of a
                // 4-ary heap and 2.6 M pushes and changes moved them up 64 k levels), so
                // fewer levels pay: `dense_distance` of docs/python_bench.py's torus at
                // 96³, order 2, in a Rust timing binary (fastest of 5, three alternating
                // runs, 2-core AMD EPYC, 2026-11-30), 151 / 159 / 162 ms with four
                // children against 151 / 153 / 148 ms with eight; then 143 / 151 / 144 ms
                // with eight against 142 / 141 / 142 ms with sixteen. The 1024² circle
                // (at most 2.9 k trial pixels): 79 / 80 / 80 ms with four, 82 / 82 / 80
                // ms with eight; 81 / 80 / 79 ms with eight, 80 / 77 / 78 ms with sixteen.
                let k = &self.heap[first..first + 16];
                let pick = |x: usize, y: usize| if k[y] < k[x] { (y, k[y]) } else { (x, k[x]) };
                let m = |(x, ex): (usize, u128), (y, ey): (usize, u128)| {
                    if ey < ex {
                        (y, ey)
                    } else {
                        (x, ex)
                    }
                };
                let l = m(m(pick(0, 1), pick(2, 3)), m(pick(4, 5), pick(6, 7)));
                let r = m(m(pick(8, 9), pick(10, 11)), m(pick(12, 13), pick(14, 15)));
                let (a, ea) = m(l, r);
                (first + a, ea)
            } else {
                let (mut c, mut ce) = (first, self.heap[first]);
                for k in first + 1..n {
                    let ke = self.heap[k];
                    if ke < ce {
                        (c, ce) = (k, ke);
                    }
                }
                (c, ce)
            };
            if ce >= e {
                break;
            }
            self.place(p, ce);
            p = c;
        }
        self.place(p, e);
    }

    /// Puts entry `e` at heap slot `p`, its voxel holding the slot.
    #[inline(always)]
    fn place(&mut self, p: usize, e: u128) {
        self.heap[p] = e;
        self.value[index_of(e)] = boxed(TRIAL, p as u32);
    }

    /// Makes voxel `i` trial with time `t`: a new entry.
    #[inline(always)]
    fn push(&mut self, i: usize, t: f64) {
        self.heap.push(0);
        self.sift_up(self.heap.len() - 1, entry(t, i));
    }

    /// Removes the least entry (the heap is not empty).
    #[inline(always)]
    fn pop(&mut self) {
        let last = self.heap.pop().expect("a non-empty heap");
        if !self.heap.is_empty() {
            self.sift_down(0, last);
        }
    }

    /// Sets the time of the trial voxel `i` to `t` (smaller or larger), if it differs.
    #[inline(always)]
    fn change(&mut self, i: usize, t: f64) {
        let p = self.value[i].to_bits() as u32 as usize;
        let old = self.heap[p];
        if time_of(old) != t {
            let e = entry(t, i);
            if e < old {
                self.sift_up(p, e);
            } else {
                self.sift_down(p, e);
            }
        }
    }

    /// The arrival time at the trial voxel `i` from its frozen neighbours:
    /// [`super::march`]'s `update` (a voxel reads the frozen voxels of its own side and the
    /// interface of either side — here every frozen voxel, the other side's others being
    /// walls; per axis the smaller frozen neighbour, with the second-order difference
    /// where the voxel beyond it is frozen and not larger). Voxels not frozen hold NaN,
    /// which no comparison below takes.
    #[inline(always)]
    fn update<const SECOND: bool>(&self, i: usize) -> f64 {
        let value = &self.value[..];
        let mut terms = [Term { a: 0.0, k: 0.0 }; 3];
        let mut n = 0;
        for &(stride, w) in &self.axes {
            let mut v1 = f64::INFINITY;
            let mut v2 = None;
            for j in [i - stride, i + stride] {
                let t1 = value[j];
                if t1 < v1 {
                    v1 = t1;
                    v2 = None;
                    if SECOND {
                        // In range: the frozen voxel `j` is in the box, `j ± stride` at
                        // worst in the padding.
                        let t2 = value[2 * j - i];
                        if t2 <= t1 {
                            v2 = Some(t2);
                        }
                    }
                }
            }
            if v1 < f64::INFINITY {
                terms[n] = match v2 {
                    Some(v2) => Term { a: w * (9.0 / 4.0), k: (4.0 * v1 - v2) / 3.0 },
                    None => Term { a: w, k: v1 },
                };
                n += 1;
            }
        }
        if n == 0 {
            return f64::INFINITY;
        }
        solve_terms(&mut terms[..n], 1.0)
    }

    /// Asks the CPU for the cache lines the updates around voxel `i` read: its own, the
    /// ±1 and ±2 rows along y and z, and the four diagonal neighbours in the y–z plane
    /// (thirteen lines). A hint only. The loop calls it for the next voxel to freeze (the
    /// heap's least entry after a pop), so the lines arrive while the current voxel's
    /// neighbours are updated: the value array of a 96³ box is 7.5 MB, beyond the L2
    /// cache, and the y and z neighbours are rows and slabs apart. Measured in decision
    /// 0052 (same bits; at 160³ 690–741 ms without, 609–625 ms with).
    #[inline(always)]
    fn prefetch_around(&self, i: usize) {
        let (sy, sz) = (self.strides[1], self.strides[2]);
        let at = |k: usize| crate::memory::prefetch_line(self.value.as_ptr().wrapping_add(k));
        at(i);
        for o in [sy, 2 * sy, sz, 2 * sz, sy + sz, sz - sy] {
            at(i + o);
            at(i.wrapping_sub(o));
        }
    }

    /// The loop of Fig. 3 (see [`super::march`]'s `run`): freezes voxels in order of
    /// arrival time while it is `≤ limit`. `popped` counts the voxels frozen by both
    /// sides (for the progress of a march without limit over `expected` voxels).
    fn run<const SECOND: bool>(
        &mut self,
        limit: f64,
        expected: u64,
        ticker: &Ticker<'_>,
        popped: &AtomicU64,
    ) -> Result<(), FmmError> {
        let mut mine = 0u64;
        while let Some(&e) = self.heap.first() {
            let t = time_of(e);
            if t > limit {
                break;
            }
            self.pop();
            if let Some(&next) = self.heap.first() {
                self.prefetch_around(index_of(next));
            }
            let i = index_of(e);
            mine += 1;
            if mine.is_multiple_of(PROGRESS_EVERY) {
                let share = if limit.is_finite() || expected == 0 {
                    t / limit
                } else {
                    let all = popped.fetch_add(PROGRESS_EVERY, Ordering::Relaxed) + PROGRESS_EVERY;
                    all as f64 / expected as f64
                };
                ticker.set(((share * PROGRESS_UNITS as f64) as u64).min(PROGRESS_UNITS))?;
            }
            self.value[i] = t;
            for a in 0..self.axes.len() {
                let stride = self.axes[a].0;
                for j in [i - stride, i + stride] {
                    match tag_of(self.value[j]) {
                        TRIAL => {
                            let tn = self.update::<SECOND>(j);
                            self.change(j, tn);
                        }
                        FAR => {
                            let tn = self.update::<SECOND>(j);
                            self.push(j, tn);
                        }
                        _ => {}
                    }
                }
            }
        }
        Ok(())
    }
}

/// The array voxels of one side: the least and one past the largest coordinate per axis
/// (empty: `lo > hi`).
type Bounds = ([usize; 3], [usize; 3]);

/// The box a side marches on: its `bounds` grown by two voxels (the march reads up to two
/// voxels from a voxel of its side) and clipped to the array of `dims` (`lo..hi`), padded
/// by `pad` wall voxels per side along each axis longer than one voxel (`padded` voxels
/// along each axis).
struct SideBox {
    lo: [usize; 3],
    hi: [usize; 3],
    pad: [usize; 3],
    padded: [usize; 3],
}

impl SideBox {
    fn new(bounds: &Bounds, dims: [usize; 3]) -> SideBox {
        let pad = dims.map(|n| usize::from(n > 1));
        let lo = [0, 1, 2].map(|a| bounds.0[a].saturating_sub(2));
        let hi = [0, 1, 2].map(|a| (bounds.1[a] + 2).min(dims[a]));
        let padded = [0, 1, 2].map(|a| hi[a] - lo[a] + 2 * pad[a]);
        SideBox { lo, hi, pad, padded }
    }

    /// Voxels of the padded box.
    fn len(&self) -> usize {
        self.padded.iter().product()
    }
}

/// The padded box of the side `inside` over `bounds` (the side's open voxels, see
/// [`SideBox`]): the interface frozen with its distance estimates (Bærentzen Sec. 4; see
/// `freeze_interface`: every open voxel with a 6-neighbour of the other sign, or φ = 0),
/// the side's other open voxels far, the rest walls; and the first trial layer (every far
/// voxel next to the interface, with its update from the interface) in the heap. Returns
/// the march and the number of interface voxels in its box.
fn side(
    phi: &[f32],
    lattice: &Lattice,
    inside: bool,
    bounds: Bounds,
    second: bool,
) -> (Flat, usize) {
    let dims = lattice.dims;
    let sb = SideBox::new(&bounds, dims);
    let SideBox { lo, hi, pad, padded: pd } = sb;
    let m = [0, 1, 2].map(|a| hi[a] - lo[a]);
    let strides = [1, pd[0], pd[0] * pd[1]];
    let total = sb.len();
    let axes: Vec<(usize, f64)> =
        (0..3).filter(|&a| dims[a] > 1).map(|a| (strides[a], lattice.ratios[a].powi(2))).collect();
    let [nx, ny, nz] = dims;
    let blocked = lattice.blocked.as_deref();
    let open = |i: usize| !blocked.is_some_and(|b| b[i]);
    let mut value = vec![boxed(WALL, 0); total];
    let (far, wall) = (boxed(FAR, 0), boxed(WALL, 0));
    // One padded row (along x) per task (2-D arrays have one slab only); per row of the
    // box (y, then z), the array x of its interface voxels.
    let rows: Vec<Option<Vec<u32>>> = value
        .par_chunks_mut(pd[0])
        .enumerate()
        .map(|(r, out)| {
            let (py, pz) = (r % pd[1], r / pd[1]);
            let y = py.checked_sub(pad[1]).filter(|&y| y < m[1])? + lo[1];
            let z = pz.checked_sub(pad[2]).filter(|&z| z < m[2])? + lo[2];
            let base = nx * (y + ny * z);
            let c = &phi[base..base + nx];
            // The rows of the four neighbours across y and z (a missing one: this row,
            // which never differs in sign from itself).
            let ym = if y > 0 { &phi[base - nx..base] } else { c };
            let yp = if y + 1 < ny { &phi[base + nx..base + 2 * nx] } else { c };
            let zm = if z > 0 { &phi[base - nx * ny..][..nx] } else { c };
            let zp = if z + 1 < nz { &phi[base + nx * ny..][..nx] } else { c };
            let out = &mut out[pad[0]..pad[0] + m[0]];
            let mut xs = Vec::new();
            for x in lo[0]..hi[0] {
                let v = c[x];
                let below = v < 0.0;
                // Without obstacles, an open voxel is on the interface only if it is 0 or a
                // 6-neighbour differs in sign: that test alone first, without branches,
                // so that the voxels away from the interface (nearly all of them) build no
                // star (see decision 0020 for the time it saved).
                let crosses = ((c[x.saturating_sub(1)] < 0.0) != below)
                    | ((c[(x + 1).min(nx - 1)] < 0.0) != below)
                    | ((ym[x] < 0.0) != below)
                    | ((yp[x] < 0.0) != below)
                    | ((zm[x] < 0.0) != below)
                    | ((zp[x] < 0.0) != below);
                if !(crosses || v == 0.0 || blocked.is_some()) {
                    out[x - lo[0]] = if below == inside { far } else { wall };
                    continue;
                }
                let i = base + x;
                if !open(i) {
                    continue;
                }
                // The six neighbours: (in the array, index).
                let six = [
                    (x > 0, i.wrapping_sub(1)),
                    (x + 1 < nx, i + 1),
                    (y > 0, i.wrapping_sub(nx)),
                    (y + 1 < ny, i + nx),
                    (z > 0, i.wrapping_sub(nx * ny)),
                    (z + 1 < nz, i + nx * ny),
                ];
                // `interface_distance` answers `None` unless an open neighbour lies on
                // the other side.
                let crosses = six.iter().any(|&(ok, j)| ok && (phi[j] < 0.0) != below && open(j));
                let d = if crosses {
                    let star = six.map(|(ok, j)| (ok && open(j)).then(|| phi[j]));
                    interface_distance(v, &star, f32::INFINITY, lattice.ratios)
                } else {
                    None
                };
                let d = if d.is_none() && v == 0.0 { Some(0.0) } else { d };
                out[x - lo[0]] = match d {
                    // Stored as the march's time: the signed value times the side's sign
                    // (negation is exact, so the times are those of `sign · value`).
                    Some(d) => {
                        xs.push(x as u32);
                        if below == inside {
                            d
                        } else {
                            -d
                        }
                    }
                    // Not on the interface, an open voxel has no open neighbour of the
                    // other sign (`interface_distance` answers for every voxel that has
                    // one): the sides' far voxels never touch, and the march of one
                    // side reaches exactly the far voxels of its sign.
                    None if below == inside => far,
                    None => wall,
                };
            }
            Some(xs)
        })
        .collect();
    let rows: Vec<Vec<u32>> = rows.into_iter().flatten().collect();
    let interface = rows.iter().map(Vec::len).sum();
    let mut flat = Flat {
        value,
        sign: if inside { -1.0 } else { 1.0 },
        lo,
        pad,
        strides,
        axes,
        heap: Vec::new(),
    };
    // The first trial layer: the far 6-neighbours of the interface voxels (all in the
    // box: it holds every voxel within two of the side's). The update reads only frozen
    // voxels (the interface), so the order does not matter; one row per task.
    let trial: Vec<Vec<(usize, f64)>> = (0..m[1] * m[2])
        .into_par_iter()
        .map(|r| {
            let (ry, rz) = (r % m[1], r / m[1]);
            let mut xs: Vec<u32> = Vec::new();
            for &x in &rows[r] {
                xs.extend([x.wrapping_sub(1), x + 1]);
            }
            for (ok, q) in [
                (ry > 0, r.wrapping_sub(1)),
                (ry + 1 < m[1], r + 1),
                (rz > 0, r.wrapping_sub(m[1])),
                (rz + 1 < m[2], r + m[1]),
            ] {
                if ok {
                    xs.extend(&rows[q]);
                }
            }
            xs.sort_unstable();
            xs.dedup();
            let (y, z) = (lo[1] + ry, lo[2] + rz);
            let f = &flat;
            xs.iter()
                .map(|&x| x as usize)
                .filter(|x| (lo[0]..hi[0]).contains(x))
                .filter_map(|x| {
                    let i = f.index(x, y, z);
                    (tag_of(f.value[i]) == FAR).then(|| {
                        (i, if second { f.update::<true>(i) } else { f.update::<false>(i) })
                    })
                })
                .collect()
        })
        .collect();
    flat.heap.reserve(trial.iter().map(Vec::len).sum());
    for &(i, t) in trial.iter().flatten() {
        flat.push(i, t);
    }
    (flat, interface)
}

/// The signed distance (march units, φ < 0 inside) of the dense array `phi` on
/// `lattice` (no periodic axis), as [`super::march::Marcher`] computes it from the
/// interface of [`super::source::freeze_interface`]; `f` maps a frozen voxel's value
/// to the output. Returns the values and reached flags in the array's order, `None` when
/// the array has no interface.
///
/// The inside and the outside march separately, on two threads: a voxel's update reads
/// the frozen voxels of its own side and the interface only, and the far voxels of the
/// two sides never touch (see [`side`]), so each side freezes its voxels in the order,
/// and with the values, of the one march over both (the order of the heap restricted to
/// one side), on any thread count.
pub(super) fn distance(
    phi: &[f32],
    lattice: &Lattice,
    second: bool,
    limit: f64,
    progress: &Progress,
    f: impl Fn(f64) -> f32 + Sync,
) -> Result<Option<DenseMarch>, FmmError> {
    debug_assert!(!lattice.periodic.contains(&true));
    let dims = lattice.dims;
    let [nx, ny, nz] = dims;
    let blocked = lattice.blocked.as_deref();
    let open = |i: usize| !blocked.is_some_and(|b| b[i]);
    // The bounds of each side's open voxels: [outside, inside].
    let empty: Bounds = ([usize::MAX; 3], [0; 3]);
    let grow = |b: &mut Bounds, p: [usize; 3]| {
        for (a, &c) in p.iter().enumerate() {
            b.0[a] = b.0[a].min(c);
            b.1[a] = b.1[a].max(c + 1);
        }
    };
    let join = |mut a: [Bounds; 2], b: [Bounds; 2]| {
        for s in 0..2 {
            if b[s].0[0] <= b[s].1[0] {
                grow(&mut a[s], b[s].0);
                grow(&mut a[s], b[s].1.map(|v| v - 1));
            }
        }
        a
    };
    let bounds = (0..ny * nz)
        .into_par_iter()
        .map(|r| {
            let (y, z) = (r % ny, r / ny);
            let mut b = [empty; 2];
            let row = &phi[nx * r..nx * (r + 1)];
            if blocked.is_none() {
                // The first and last voxel of each sign.
                let ends = |f: fn(f32) -> bool| {
                    Some((row.iter().position(|&v| f(v))?, row.iter().rposition(|&v| f(v))?))
                };
                // Outside: not below 0 (NaN was refused before).
                let sides: [fn(f32) -> bool; 2] = [|v| v >= 0.0, |v| v < 0.0];
                for (s, f) in sides.into_iter().enumerate() {
                    if let Some((a, e)) = ends(f) {
                        grow(&mut b[s], [a, y, z]);
                        grow(&mut b[s], [e, y, z]);
                    }
                }
            } else {
                for (x, &v) in row.iter().enumerate() {
                    if open(x + nx * r) {
                        grow(&mut b[usize::from(v < 0.0)], [x, y, z]);
                    }
                }
            }
            b
        })
        .reduce(|| [empty; 2], join);
    let present = bounds.map(|b| b.0[0] <= b.1[0]);
    let bytes: f64 = (0..2)
        .filter(|&s| present[s])
        .map(|s| SideBox::new(&bounds[s], dims).len() as f64 * 8.0)
        .sum();
    crate::memory::check(bytes, "the fast-marching array (one value per voxel)")?;

    let (outside, inside) = rayon::join(
        || present[0].then(|| side(phi, lattice, false, bounds[0], second)),
        || present[1].then(|| side(phi, lattice, true, bounds[1], second)),
    );
    let interface = outside.as_ref().map_or(0, |s| s.1) + inside.as_ref().map_or(0, |s| s.1);
    if interface == 0 {
        return Ok(None);
    }
    let (mut outside, mut inside) = (outside.map(|s| s.0), inside.map(|s| s.0));

    let expected = (nx * ny * nz) as u64;
    let ticker = progress.start(PROGRESS_UNITS);
    let popped = AtomicU64::new(0);
    let march = |flat: &mut Option<Flat>| -> Result<(), FmmError> {
        match flat {
            Some(fl) if second => fl.run::<true>(limit, expected, &ticker, &popped),
            Some(fl) => fl.run::<false>(limit, expected, &ticker, &popped),
            None => Ok(()),
        }
    };
    let (a, b) = rayon::join(|| march(&mut outside), || march(&mut inside));
    a?;
    b?;
    ticker.set(PROGRESS_UNITS)?;

    // The frozen voxels' values, in the array's order, each from the march of its side.
    let n = nx * ny * nz;
    let mut values = vec![0f32; n];
    let mut reached = vec![false; n];
    let sides = [outside.as_ref(), inside.as_ref()];
    values.par_chunks_mut(nx).zip(reached.par_chunks_mut(nx)).enumerate().for_each(
        |(r, (vals, reach))| {
            let (y, z) = (r % ny, r / ny);
            for x in 0..nx {
                let i = x + nx * r;
                if !open(i) {
                    continue;
                }
                let fl = sides[usize::from(phi[i] < 0.0)].expect("the side of an open voxel");
                let t = fl.value[fl.index(x, y, z)];
                if !t.is_nan() {
                    vals[x] = f(fl.sign * t);
                    reach[x] = true;
                }
            }
        },
    );
    Ok(Some(DenseMarch { values, reached }))
}
