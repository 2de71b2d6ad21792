//! The march itself: initialisation from a frozen set, the central loop (Bærentzen
//! Sec. 2.1, Fig. 3) and the distance update of Sec. 3 (first order) and Sec. 4 /
//! Appendix A (second order, the "high accuracy" FMM).

use super::heap::IndexedHeap;
use super::store::{Store, FAR, FROZEN, INITIAL, INSIDE, TRIAL};
use super::FmmError;
use crate::coord::Coord;
use crate::progress::{Progress, Ticker};

/// Cost of crossing one voxel at a voxel: the right-hand side `h / F(x)` of the discrete
/// eikonal equation (eq. (4)/(7), with the grid spacing moved to the right). Distances
/// march in voxel units with cost 1.
/// Units of the progress of one march, and how many voxels are frozen between reports.
const PROGRESS_UNITS: u64 = 1000;
const PROGRESS_EVERY: u64 = 1 << 14;

pub(crate) trait Cost {
    fn cost(&self, c: Coord) -> Result<f64, FmmError>;
}

/// Unit speed in voxel units: arrival time = distance in voxels.
pub(crate) struct UnitCost;

impl Cost for UnitCost {
    #[inline(always)]
    fn cost(&self, _: Coord) -> Result<f64, FmmError> {
        Ok(1.0)
    }
}

const AXES: [Coord; 3] = [Coord::new(1, 0, 0), Coord::new(0, 1, 0), Coord::new(0, 0, 1)];

/// Blocks between two memory checks.
const MEMORY_CHECK_BLOCKS: usize = 1 << 14;

/// One term `a (T − k)²` of the discrete eikonal equation: `a = 1`, `k = G[x−1]` for a
/// first-order one-sided difference (eq. (5)); `a = 9/4`, `k = (4 G[x−1] − G[x−2]) / 3`
/// for the second-order one (eq. (9)–(10)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Term {
    pub a: f64,
    pub k: f64,
}

/// The largest root `T` of `Σ a_i (T − k_i)² = cost²` over the upwind terms, solved
/// robustly: the terms are sorted by `k`; when the discriminant is negative, or the
/// root lies below the largest `k` in use (the solution would not be upwind of that
/// direction), the direction with the largest `k` is dropped and the equation solved
/// again. One term always has the root `k + cost / √a`. (The paper's Appendix A returns
/// "no solution" in that case without saying what to do; dropping the largest
/// contributing direction is Sethian's rule.) The equation is solved for `T − k_min`, so
/// large arrival times lose no precision to cancellation.
///
/// `terms` must hold 1 to 3 entries.
#[inline]
pub(crate) fn solve_terms(terms: &mut [Term], cost: f64) -> f64 {
    debug_assert!(!terms.is_empty() && terms.len() <= 3);
    // Sorting network for at most three terms (a library sort call costs more here).
    let n = terms.len();
    let mut swap = |i: usize, j: usize| {
        if terms[j].k < terms[i].k {
            terms.swap(i, j);
        }
    };
    if n >= 2 {
        swap(0, 1);
    }
    if n == 3 {
        swap(1, 2);
        swap(0, 1);
    }
    let k0 = terms[0].k;
    let c2 = cost * cost;
    let mut n = terms.len();
    while n > 1 {
        let (mut a, mut b, mut c) = (0.0, 0.0, -c2);
        for t in &terms[..n] {
            let s = t.k - k0;
            a += t.a;
            b += t.a * s;
            c += t.a * s * s;
        }
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let u = (b + disc.sqrt()) / a;
            if u >= terms[n - 1].k - k0 {
                return k0 + u;
            }
        }
        n -= 1;
    }
    k0 + cost / terms[0].a.sqrt()
}

/// A march over a [`Store`] (see the module docs of [`super`]).
pub(crate) struct Marcher<C: Cost> {
    pub(crate) store: Store,
    heap: IndexedHeap,
    second_order: bool,
    /// Inclusive voxel box the march may enter (`None`: the whole i32 range).
    domain: Option<(Coord, Coord)>,
    cost: C,
    /// The initial frozen voxels, in the order they were given.
    initial: Vec<Coord>,
    next_memory_check: usize,
}

impl<C: Cost> Marcher<C> {
    pub(crate) fn new(second_order: bool, domain: Option<(Coord, Coord)>, cost: C) -> Self {
        Marcher {
            store: Store::new(),
            heap: IndexedHeap::new(),
            second_order,
            domain,
            cost,
            initial: Vec::new(),
            next_memory_check: MEMORY_CHECK_BLOCKS,
        }
    }

    /// `c + d · axis` when it exists (in the i32 range and the domain).
    #[inline(always)]
    fn step(&self, c: Coord, axis: usize, d: i32) -> Option<Coord> {
        let a = AXES[axis];
        let n = c.checked_add(Coord::new(a.x * d, a.y * d, a.z * d))?;
        match self.domain {
            Some((lo, hi))
                if n.x < lo.x
                    || n.y < lo.y
                    || n.z < lo.z
                    || n.x > hi.x
                    || n.y > hi.y
                    || n.z > hi.z =>
            {
                None
            }
            _ => Some(n),
        }
    }

    /// Refuses to grow past the memory available (an arrival-time march with a large
    /// `max_time` could otherwise fill the machine).
    fn check_memory(&mut self) -> Result<(), FmmError> {
        let blocks = self.store.num_blocks();
        if blocks >= self.next_memory_check {
            self.next_memory_check = blocks + MEMORY_CHECK_BLOCKS;
            let bytes = (self.next_memory_check * Store::BLOCK_BYTES) as f64;
            crate::memory::check(bytes, "the fast-marching band")?;
        }
        Ok(())
    }

    /// Freezes `c` with the signed value `value` (march units; `inside` selects the side,
    /// whose arrival time is `−value`). A voxel given twice keeps its first value.
    pub(crate) fn freeze_initial(
        &mut self,
        c: Coord,
        value: f64,
        inside: bool,
    ) -> Result<(), FmmError> {
        let id = self.store.find_or_insert(c) as usize;
        if self.store.vox[id].state & 3 == FROZEN {
            return Ok(());
        }
        self.store.vox[id].value = value;
        self.store.vox[id].state = FROZEN | INITIAL | if inside { INSIDE } else { 0 };
        self.initial.push(c);
        self.check_memory()
    }

    /// Number of voxels frozen initially.
    pub(crate) fn initial_len(&self) -> usize {
        self.initial.len()
    }

    /// The arrival time at `c` (in the side's own sign convention) from its frozen
    /// neighbours: eq. (5) / (8) of the paper, Appendix A's `recompute`, then
    /// [`solve_terms`]. Per axis the smaller frozen neighbour `G[x∓1]` is used; with
    /// second order, when `G[x∓2]` beyond it is frozen and not larger, the second-order
    /// difference is used, else the first-order one (Sec. 4). (Appendix A's listing
    /// resets `val2` when the *other* neighbour of the axis is not frozen, which would
    /// throw away a valid second-order difference; the text of Sec. 4 does not, and
    /// neither does this.)
    ///
    /// Neighbours are read through the store without range or domain checks: only
    /// voxels inside the domain and the i32 range are ever frozen (the march creates
    /// voxels through [`Marcher::step`]), and no block beyond the range exists, so a
    /// neighbour that does not exist never reads as frozen.
    ///
    /// A voxel reads only frozen voxels of its own side, and the initial (interface)
    /// voxels of either side, whose signed values continue the distance across the
    /// interface (they serve as `G[x−2]` of the second-order difference). Should the
    /// input have a sign change the interface layer missed (a band that does not separate
    /// inside from outside), the two sides still cannot feed each other beyond that
    /// layer, so arrival times keep growing away from it and the march stays within the
    /// half-width.
    #[inline]
    fn update<const SECOND: bool>(&self, c: Coord, id: u32, inside: bool) -> Result<f64, FmmError> {
        let s = if inside { -1.0 } else { 1.0 };
        let side = if inside { INSIDE } else { 0 };
        let usable = |st: u8| st & INITIAL != 0 || st & INSIDE == side;
        let mut terms = [Term { a: 0.0, k: 0.0 }; 3];
        let mut n = 0;
        for axis in 0..3 {
            let mut v1 = f64::INFINITY;
            let mut v2 = None;
            for d in [-1, 1] {
                let Some((t1, st1)) = self.store.frozen_step(id, axis, d) else { continue };
                if !usable(st1) {
                    continue;
                }
                let t1 = s * t1;
                if t1 < v1 {
                    v1 = t1;
                    v2 = None;
                    if SECOND {
                        if let Some((t2, st2)) = self.store.frozen_step(id, axis, 2 * d) {
                            let t2 = s * t2;
                            if usable(st2) && t2 <= t1 {
                                v2 = Some(t2);
                            }
                        }
                    }
                }
            }
            if v1 < f64::INFINITY {
                terms[n] = match v2 {
                    Some(v2) => Term { a: 9.0 / 4.0, k: (4.0 * v1 - v2) / 3.0 },
                    None => Term { a: 1.0, k: v1 },
                };
                n += 1;
            }
        }
        if n == 0 {
            // Only reachable from a frozen neighbour of the other side (an interface the
            // initialisation missed): no usable value, so the voxel stays out of reach.
            return Ok(f64::INFINITY);
        }
        let cost = self.cost.cost(c)?;
        Ok(solve_terms(&mut terms[..n], cost))
    }

    /// Initialisation and loop of Fig. 3: computes the trial voxels next to the frozen
    /// set, then freezes voxels in order of arrival time while the smallest time is
    /// `≤ limit` (march units). Voxels left in the heap stay [`TRIAL`]; unvisited ones
    /// [`FAR`].
    ///
    /// The side of a voxel the march reaches is the side of the frozen voxel that reaches
    /// it first. This is exact when the initial frozen set holds both voxels of every
    /// edge whose ends differ in sign (as every initialisation here does): a voxel that
    /// is not frozen then has no 6-neighbour of the other sign, so the sign spreads
    /// unchanged. The two sides share one heap; they interact only through the fixed
    /// frozen set, so this equals two separate marches.
    /// `progress` hears the marched distance as a share of `limit` (in thousandths).
    pub(crate) fn run(&mut self, limit: f64, progress: &Progress) -> Result<(), FmmError> {
        let ticker = progress.start(PROGRESS_UNITS);
        if self.second_order {
            self.run_impl::<true>(limit, &ticker)
        } else {
            self.run_impl::<false>(limit, &ticker)
        }
    }

    fn run_impl<const SECOND: bool>(
        &mut self,
        limit: f64,
        ticker: &Ticker,
    ) -> Result<(), FmmError> {
        // Initialisation: every non-frozen neighbour of the frozen set becomes trial with
        // the value computed from all frozen voxels (so the order of `initial` does not
        // matter).
        let initial = std::mem::take(&mut self.initial);
        let mut trial = Vec::new();
        for &c in &initial {
            let id = self.store.find(c).expect("frozen voxels are stored") as usize;
            let inside = self.store.vox[id].state & INSIDE;
            for axis in 0..3 {
                for d in [-1, 1] {
                    let Some(n) = self.step(c, axis, d) else { continue };
                    let nid = self.store.step_or_insert(id as u32, axis, d, n) as usize;
                    let st = &mut self.store.vox[nid].state;
                    if *st == FAR {
                        *st = TRIAL | inside;
                        trial.push(n);
                    } else if *st & 3 == TRIAL {
                        // Next to initial voxels of both sides (only when the input's
                        // interface layer missed a sign change): outside wins, whatever
                        // the order of `initial`.
                        *st &= !INSIDE | inside;
                    }
                }
            }
            self.check_memory()?;
        }
        self.initial = initial;
        for &c in &trial {
            let id = self.store.find(c).expect("trial voxels are stored");
            let inside = self.store.vox[id as usize].state & INSIDE != 0;
            let t = self.update::<SECOND>(c, id, inside)?;
            self.store.vox[id as usize].handle = self.heap.push(t, c, id);
        }
        // The loop.
        let mut popped = 0u64;
        while let Some(key) = self.heap.peek_key() {
            if key > limit {
                break;
            }
            let (t, c, id) = self.heap.pop().expect("non-empty");
            popped += 1;
            if popped.is_multiple_of(PROGRESS_EVERY) {
                ticker.set((t / limit * PROGRESS_UNITS as f64) as u64)?;
            }
            let inside_bit = self.store.vox[id as usize].state & INSIDE;
            let inside = inside_bit != 0;
            self.store.vox[id as usize].state = FROZEN | inside_bit;
            self.store.vox[id as usize].value = if inside { -t } else { t };
            for axis in 0..3 {
                for d in [-1, 1] {
                    let Some(n) = self.step(c, axis, d) else { continue };
                    let nid = self.store.step_or_insert(id, axis, d, n) as usize;
                    match self.store.vox[nid].state & 3 {
                        FROZEN => {}
                        TRIAL => {
                            let inside_n = self.store.vox[nid].state & INSIDE != 0;
                            let t = self.update::<SECOND>(n, nid as u32, inside_n)?;
                            let h = self.store.vox[nid].handle;
                            if self.heap.key(h) != t {
                                self.heap.update(h, t);
                            }
                        }
                        _ => {
                            self.store.vox[nid].state = TRIAL | inside_bit;
                            let t = self.update::<SECOND>(n, nid as u32, inside)?;
                            self.store.vox[nid].handle = self.heap.push(t, n, nid as u32);
                        }
                    }
                }
            }
            self.check_memory()?;
        }
        // The march is done, whether it reached the limit or ran out of voxels (a small
        // array): the progress reaches its total.
        ticker.set(PROGRESS_UNITS)?;
        // Trial voxels keep their tentative value (> limit): callers clamp or drop them.
        Ok(())
    }
}
