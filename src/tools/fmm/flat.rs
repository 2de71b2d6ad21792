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
//! sequence. The heap here is 4-ary (half the depth of a binary heap, and the four
//! children of a node are adjacent in memory). Its entries carry a handle, recycled when
//! popped, and the heap position of each handle lives in an array as long as the largest
//! heap (kilobytes, in cache), not in one as long as the box: a trial voxel holds its
//! handle in place of its value (its time is the key of its entry).
//!
//! The interface initialisation (each voxel's distance estimate from its own star) and
//! the first trial layer (each voxel's update from the frozen interface) depend on
//! nothing the march changes, so they run on all threads, one z-slab per task, and give
//! the same values on any thread count.

use super::march::{solve_terms, Lattice, Term};
use super::source::interface_distance;
use super::store::{FAR, FROZEN, INITIAL, INSIDE, TRIAL};
use super::FmmError;
use crate::progress::Progress;
use rayon::prelude::*;

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

/// State of a padding voxel or an obstacle (neither far, trial nor frozen).
const WALL: u8 = 3;
const STATE: u8 = 3;

/// Units of the progress, and how many voxels are frozen between reports (as the sparse
/// march).
const PROGRESS_UNITS: u64 = 1000;
const PROGRESS_EVERY: u64 = 1 << 14;

/// A heap entry: the arrival time's bits in total order (bits 64..128), the padded index
/// (bits 32..64) and the handle (bits 0..32), so that the least entry is the least (time,
/// coordinate); the handle never decides (a voxel has one entry).
#[inline(always)]
fn entry(t: f64, i: usize, h: u32) -> u128 {
    let b = t.to_bits();
    // The bits of an f64 as an unsigned key in `f64::total_cmp` order.
    let k = if b >> 63 == 1 { !b } else { b | 1 << 63 };
    ((k as u128) << 64) | ((i as u128) << 32) | h as u128
}

/// The padded index of an entry.
#[inline(always)]
fn index_of(e: u128) -> usize {
    (e >> 32) as u32 as usize
}

/// The handle of an entry.
#[inline(always)]
fn handle_of(e: u128) -> usize {
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

/// The padded box and the march over it.
struct Flat {
    /// Per voxel of the padded box: the signed value in march units of a frozen voxel
    /// (a trial voxel: its heap handle, as the value's bits) and the state, two arrays (the
    /// states, read most, stay dense in cache).
    value: Vec<f64>,
    state: Vec<u8>,
    /// The heap position of each handle, and the handles free for reuse.
    pos: Vec<u32>,
    free: Vec<u32>,
    /// Per active axis (longer than one voxel), in axis order: the stride and the term
    /// factor `(h₀ / hₐ)²`.
    axes: Vec<(usize, f64)>,
    /// The trial voxels' entries, a 4-ary min-heap (the children of slot `p` are
    /// `4p + 1 ..= 4p + 4`).
    heap: Vec<u128>,
}

impl Flat {
    /// Places `e` at heap slot `p` or above.
    #[inline(always)]
    fn sift_up(&mut self, mut p: usize, e: u128) {
        while p > 0 {
            let parent = (p - 1) / 4;
            let pe = self.heap[parent];
            if pe <= e {
                break;
            }
            self.heap[p] = pe;
            self.pos[handle_of(pe)] = p as u32;
            p = parent;
        }
        self.heap[p] = e;
        self.pos[handle_of(e)] = p as u32;
    }

    /// Places `e` at heap slot `p` or below.
    #[inline(always)]
    fn sift_down(&mut self, mut p: usize, e: u128) {
        let n = self.heap.len();
        loop {
            let first = 4 * p + 1;
            if first >= n {
                break;
            }
            let (c, ce) = if first + 4 <= n {
                // Four children: a tournament of two independent comparisons and a
                // third (entries are distinct, so the least is the loop's below). The
                // loop's dependent chain of three comparisons made `sl.distance(phi,
                // order=2)` of docs/python_bench.py 6–10 % slower: 197 → 185 ms at 96³,
                // 1223 → 1105–1125 ms at 160³, 147 → 140 ms at 1024² (fastest of 2–5,
                // two runs; 2-core AMD EPYC, 2026-11-28).
                let k = &self.heap[first..first + 4];
                let (a, ea) = if k[1] < k[0] { (1, k[1]) } else { (0, k[0]) };
                let (b, eb) = if k[3] < k[2] { (3, k[3]) } else { (2, k[2]) };
                if eb < ea {
                    (first + b, eb)
                } else {
                    (first + a, ea)
                }
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
            self.heap[p] = ce;
            self.pos[handle_of(ce)] = p as u32;
            p = c;
        }
        self.heap[p] = e;
        self.pos[handle_of(e)] = p as u32;
    }

    /// Makes voxel `i` trial with time `t`: a new entry, the voxel holding its handle.
    #[inline(always)]
    fn push(&mut self, i: usize, t: f64) {
        let h = match self.free.pop() {
            Some(h) => h,
            None => {
                self.pos.push(0);
                (self.pos.len() - 1) as u32
            }
        };
        self.value[i] = f64::from_bits(h as u64);
        self.heap.push(0);
        self.sift_up(self.heap.len() - 1, entry(t, i, h));
    }

    /// Removes the least entry (the heap is not empty) and frees its handle.
    #[inline(always)]
    fn pop(&mut self) {
        let top = self.heap[0];
        self.free.push(handle_of(top) as u32);
        let last = self.heap.pop().expect("a non-empty heap");
        if !self.heap.is_empty() {
            self.sift_down(0, last);
        }
    }

    /// Sets the time of the trial voxel `i` to `t` (smaller or larger), if it differs.
    #[inline(always)]
    fn change(&mut self, i: usize, t: f64) {
        let h = self.value[i].to_bits() as u32;
        let p = self.pos[h as usize] as usize;
        let old = self.heap[p];
        if time_of(old) != t {
            let e = entry(t, i, h);
            if e < old {
                self.sift_up(p, e);
            } else {
                self.sift_down(p, e);
            }
        }
    }

    /// The arrival time at the trial voxel `i` of side `inside` from its frozen
    /// neighbours: [`super::march`]'s `update` (a voxel reads the frozen voxels of its own
    /// side and the initial ones of either side; per axis the smaller usable neighbour,
    /// with the second-order difference where the voxel beyond it is frozen, usable and
    /// not larger).
    #[inline(always)]
    fn update<const SECOND: bool>(&self, i: usize, inside: bool) -> f64 {
        let s = if inside { -1.0 } else { 1.0 };
        let side = if inside { INSIDE } else { 0 };
        let usable = |st: u8| st & STATE == FROZEN && (st & INITIAL != 0 || st & INSIDE == side);
        let (value, state) = (&self.value[..], &self.state[..]);
        let mut terms = [Term { a: 0.0, k: 0.0 }; 3];
        let mut n = 0;
        for &(stride, w) in &self.axes {
            let mut v1 = f64::INFINITY;
            let mut v2 = None;
            for j in [i - stride, i + stride] {
                if !usable(state[j]) {
                    continue;
                }
                let t1 = s * value[j];
                if t1 < v1 {
                    v1 = t1;
                    v2 = None;
                    if SECOND {
                        // In range: the frozen voxel `j` is in the box, `j ± stride` at
                        // worst in the padding.
                        let k = 2 * j - i;
                        let t2 = s * value[k];
                        if usable(state[k]) && t2 <= t1 {
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

    /// The loop of Fig. 3 (see [`super::march`]'s `run`): freezes voxels in order of
    /// arrival time while it is `≤ limit`.
    fn run<const SECOND: bool>(
        &mut self,
        limit: f64,
        expected: u64,
        progress: &Progress,
    ) -> Result<(), FmmError> {
        let ticker = progress.start(PROGRESS_UNITS);
        let mut popped = 0u64;
        while let Some(&e) = self.heap.first() {
            let t = time_of(e);
            if t > limit {
                break;
            }
            self.pop();
            let i = index_of(e);
            let st = self.state[i];
            popped += 1;
            if popped.is_multiple_of(PROGRESS_EVERY) {
                let share = if limit.is_finite() || expected == 0 {
                    t / limit
                } else {
                    popped as f64 / expected as f64
                };
                ticker.set(((share * PROGRESS_UNITS as f64) as u64).min(PROGRESS_UNITS))?;
            }
            let inside_bit = st & INSIDE;
            let inside = inside_bit != 0;
            self.value[i] = if inside { -t } else { t };
            self.state[i] = FROZEN | inside_bit;
            for a in 0..self.axes.len() {
                let stride = self.axes[a].0;
                for j in [i - stride, i + stride] {
                    let sj = self.state[j];
                    match sj & STATE {
                        TRIAL => {
                            let tn = self.update::<SECOND>(j, sj & INSIDE != 0);
                            self.change(j, tn);
                        }
                        FAR => {
                            let tn = self.update::<SECOND>(j, inside);
                            self.state[j] = TRIAL | inside_bit;
                            self.push(j, tn);
                        }
                        _ => {}
                    }
                }
            }
        }
        ticker.set(PROGRESS_UNITS)?;
        Ok(())
    }
}

/// The signed distance (march units, φ < 0 inside) of the dense array `phi` on
/// `lattice` (no periodic axis), as [`super::march::Marcher`] computes it from the
/// interface of [`super::source::freeze_interface`]; `f` maps a frozen voxel's value
/// to the output. Returns the values and reached flags in the array's order, `None` when
/// the array has no interface.
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
    let pad = dims.map(|n| usize::from(n > 1));
    let pd = [0, 1, 2].map(|a| dims[a] + 2 * pad[a]);
    let strides = [1, pd[0], pd[0] * pd[1]];
    let total = pd[0] * pd[1] * pd[2];
    crate::memory::check(
        (total * 9) as f64,
        "the fast-marching array (one value and state per voxel)",
    )?;
    let axes: Vec<(usize, f64)> =
        (0..3).filter(|&a| dims[a] > 1).map(|a| (strides[a], lattice.ratios[a].powi(2))).collect();
    let [nx, ny, nz] = dims;
    let blocked = lattice.blocked.as_deref();
    let open = |i: usize| !blocked.is_some_and(|b| b[i]);
    // Padded index of array voxel (x, y, z).
    let padded = |x: usize, y: usize, z: usize| {
        (x + pad[0]) + strides[1] * (y + pad[1]) + strides[2] * (z + pad[2])
    };
    let slab = strides[2];

    // The interface (Bærentzen Sec. 4; see `freeze_interface`): every open voxel with a
    // 6-neighbour of the other sign, or φ = 0, frozen with its distance estimate.
    let mut value = vec![0f64; total];
    let mut state = vec![WALL; total];
    let interface: usize = value
        .par_chunks_mut(slab)
        .zip(state.par_chunks_mut(slab))
        .enumerate()
        .map(|(pz, (out_value, out_state))| {
            let Some(z) = pz.checked_sub(pad[2]).filter(|&z| z < nz) else { return 0 };
            let mut count = 0;
            for y in 0..ny {
                for x in 0..nx {
                    let i = x + nx * (y + ny * z);
                    if !open(i) {
                        continue;
                    }
                    let v = phi[i];
                    let inside = v < 0.0;
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
                    // the other side: that test alone first, so that the voxels away from
                    // the interface (nearly all of them) build no star.
                    let crosses =
                        six.iter().any(|&(ok, j)| ok && (phi[j] < 0.0) != inside && open(j));
                    let d = if crosses {
                        let star = six.map(|(ok, j)| (ok && open(j)).then(|| phi[j]));
                        interface_distance(v, &star, f32::INFINITY, lattice.ratios)
                    } else {
                        None
                    };
                    let d = if d.is_none() && v == 0.0 { Some(0.0) } else { d };
                    let k = (x + pad[0]) + strides[1] * (y + pad[1]);
                    out_state[k] = match d {
                        Some(d) => {
                            count += 1;
                            out_value[k] = if inside { -d } else { d };
                            FROZEN | INITIAL | if inside { INSIDE } else { 0 }
                        }
                        None => FAR,
                    };
                }
            }
            count
        })
        .sum();
    if interface == 0 {
        return Ok(None);
    }

    // The first trial layer: every far voxel next to the interface, on the inside when
    // all its interface neighbours are (outside wins, as in the sparse march), with its
    // update from the interface.
    let ax = &axes;
    let trial: Vec<Vec<(usize, f64, bool)>> = (0..nz)
        .into_par_iter()
        .map(|z| {
            let mut out = Vec::new();
            let state = &state[..];
            for y in 0..ny {
                for x in 0..nx {
                    let i = padded(x, y, z);
                    if state[i] & STATE != FAR {
                        continue;
                    }
                    let (mut any, mut inside) = (false, true);
                    for &(stride, _) in ax {
                        for j in [i - stride, i + stride] {
                            let s = state[j];
                            if s & STATE == FROZEN {
                                any = true;
                                inside &= s & INSIDE != 0;
                            }
                        }
                    }
                    if any {
                        out.push((i, 0.0, inside));
                    }
                }
            }
            out
        })
        .collect();
    let mut flat = Flat { value, state, pos: Vec::new(), free: Vec::new(), axes, heap: Vec::new() };
    // Sides first (the update reads only frozen voxels, so the order does not matter).
    for &(i, _, inside) in trial.iter().flatten() {
        flat.state[i] = TRIAL | if inside { INSIDE } else { 0 };
    }
    let trial: Vec<Vec<(usize, f64, bool)>> = trial
        .into_par_iter()
        .map(|layer| {
            layer
                .into_iter()
                .map(|(i, _, inside)| {
                    let t = if second {
                        flat.update::<true>(i, inside)
                    } else {
                        flat.update::<false>(i, inside)
                    };
                    (i, t, inside)
                })
                .collect()
        })
        .collect();
    flat.heap.reserve(trial.iter().map(Vec::len).sum());
    for &(i, t, _) in trial.iter().flatten() {
        flat.push(i, t);
    }
    let expected = (nx * ny * nz) as u64;
    if second {
        flat.run::<true>(limit, expected, progress)?;
    } else {
        flat.run::<false>(limit, expected, progress)?;
    }

    // The frozen voxels' values, in the array's order.
    let n = nx * ny * nz;
    let mut values = vec![0f32; n];
    let mut reached = vec![false; n];
    let (value, state) = (&flat.value, &flat.state);
    values.par_chunks_mut(nx * ny).zip(reached.par_chunks_mut(nx * ny)).enumerate().for_each(
        |(z, (vals, reach))| {
            for y in 0..ny {
                for x in 0..nx {
                    let i = padded(x, y, z);
                    if state[i] & STATE == FROZEN {
                        vals[x + nx * y] = f(value[i]);
                        reach[x + nx * y] = true;
                    }
                }
            }
        },
    );
    Ok(Some(DenseMarch { values, reached }))
}
