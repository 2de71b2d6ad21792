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
    // One instance per count, so that each unrolls its loops (same operations in the
    // same order, so the same bits). `dense_distance` of docs/python_bench.py's torus at
    // 96³, order 2, in a Rust timing binary (fastest of 5, three alternating runs, 2-core
    // AMD EPYC, 2026-11-30): 180 / 164 / 166 ms with the slice's loops, 151 / 159 / 162
    // ms with these instances. Each copies the terms into an array of its own and back:
    // the slice viewed in place as `&mut [Term; N]` (`try_into`) gave the same bits but
    // took 163–166 ms against 140–145 ms (`sl.distance(phi, order=2)` of that torus, fastest
    // of 7, two alternated pairs of wheels, same machine, 2026-11-30).
    match terms {
        [t] => solve_n(&mut [*t], cost),
        [a, b] => {
            let mut t = [*a, *b];
            let r = solve_n(&mut t, cost);
            terms.copy_from_slice(&t);
            r
        }
        _ => {
            let mut t = [terms[0], terms[1], terms[2]];
            let r = solve_n(&mut t, cost);
            terms.copy_from_slice(&t);
            r
        }
    }
}

/// [`solve_terms`] for `N` terms.
#[inline(always)]
fn solve_n<const N: usize>(terms: &mut [Term; N], cost: f64) -> f64 {
    // Sorting network for at most three terms (a library sort call costs more here).
    let n = N;
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
    let mut n = N;
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

/// A bounded box of voxels with per-axis spacing, periodic axes and obstacles: what a
/// march over a dense array adds to the plain box of [`Marcher::new`].
#[derive(Clone, Debug)]
pub(crate) struct Lattice {
    /// The box's first voxel.
    pub lo: Coord,
    /// Voxels along x, y, z (each ≥ 1; the product fits in memory).
    pub dims: [usize; 3],
    /// Per axis, `h₀ / hₐ` with `hₐ` the axis's spacing and `h₀` the unit the march
    /// measures lengths in; the axis's terms in the quadratic carry the factor
    /// `(h₀ / hₐ)²` (the one-sided differences divided by `hₐ`). All 1 for an isotropic
    /// lattice.
    pub ratios: [f64; 3],
    /// Axes whose neighbours wrap around (voxel `n` of an axis of length `n` is voxel 0).
    pub periodic: [bool; 3],
    /// Obstacles, x fastest: never entered, never frozen, never read by an update.
    pub blocked: Option<Vec<bool>>,
}

impl Lattice {
    /// Index of `c` (inside the box) in x-fastest order.
    #[inline]
    pub(crate) fn index(&self, c: Coord) -> usize {
        let [nx, ny, _] = self.dims;
        let x = (c.x - self.lo.x) as usize;
        let y = (c.y - self.lo.y) as usize;
        let z = (c.z - self.lo.z) as usize;
        (z * ny + y) * nx + x
    }

    /// `c + d · axis` within the box (wrapped along a periodic axis), `None` beyond a
    /// non-periodic face or on an obstacle.
    #[inline]
    pub(crate) fn step(&self, c: Coord, axis: usize, d: i32) -> Option<Coord> {
        let n = self.dims[axis] as i64;
        let lo = [self.lo.x, self.lo.y, self.lo.z][axis] as i64;
        let v = [c.x, c.y, c.z][axis] as i64 + d as i64 - lo;
        let v = if self.periodic[axis] {
            v.rem_euclid(n)
        } else if (0..n).contains(&v) {
            v
        } else {
            return None;
        };
        // In range: the box is representable.
        let v = (v + lo) as i32;
        let nb = match axis {
            0 => Coord::new(v, c.y, c.z),
            1 => Coord::new(c.x, v, c.z),
            _ => Coord::new(c.x, c.y, v),
        };
        match &self.blocked {
            Some(b) if b[self.index(nb)] => None,
            _ => Some(nb),
        }
    }
}

/// Extension of a field from the interface along the characteristics of the march
/// (Adalsteinsson & Sethian 1999): one value per voxel of the lattice's box, set for the
/// initial voxels by the caller and for every voxel the march freezes.
pub(crate) struct Extension {
    pub values: Vec<f64>,
}

/// A march over a [`Store`] (see the module docs of [`super`]).
pub(crate) struct Marcher<C: Cost> {
    pub(crate) store: Store,
    heap: IndexedHeap,
    second_order: bool,
    /// Inclusive voxel box the march may enter (`None`: the whole i32 range).
    domain: Option<(Coord, Coord)>,
    /// Spacing, periodic axes and obstacles of a dense array (`None`: unit spacing, no
    /// wrap, no obstacle, the box of `domain`).
    lattice: Option<Lattice>,
    /// The term factors `(h₀ / hₐ)²` (all 1 without a lattice).
    weights: [f64; 3],
    /// Per axis, whether it wraps (its neighbours are then looked up by coordinate).
    wraps: [bool; 3],
    /// The extended field, if one is carried along.
    pub(crate) extension: Option<Extension>,
    /// Voxels expected to freeze, for the progress of a march without a finite limit.
    expected: u64,
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
            lattice: None,
            weights: [1.0; 3],
            wraps: [false; 3],
            extension: None,
            expected: 0,
            cost,
            initial: Vec::new(),
            next_memory_check: MEMORY_CHECK_BLOCKS,
        }
    }

    /// A march over the box of `lattice` with its spacing, periodic axes and obstacles.
    pub(crate) fn on_lattice(second_order: bool, lattice: Lattice, cost: C) -> Self {
        let hi = Coord::new(
            lattice.lo.x + lattice.dims[0] as i32 - 1,
            lattice.lo.y + lattice.dims[1] as i32 - 1,
            lattice.lo.z + lattice.dims[2] as i32 - 1,
        );
        let mut m = Marcher::new(second_order, Some((lattice.lo, hi)), cost);
        m.weights = lattice.ratios.map(|r| r * r);
        m.wraps = lattice.periodic;
        m.expected = lattice.dims.iter().product::<usize>() as u64;
        m.lattice = Some(lattice);
        m
    }

    /// The lattice of [`Marcher::on_lattice`].
    pub(crate) fn lattice(&self) -> Option<&Lattice> {
        self.lattice.as_ref()
    }

    /// `c + d · axis` when it exists (in the i32 range and the domain; on a lattice:
    /// wrapped along periodic axes, not an obstacle).
    #[inline(always)]
    fn step(&self, c: Coord, axis: usize, d: i32) -> Option<Coord> {
        self.step_in::<true>(c, axis, d)
    }

    /// [`Marcher::step`], the lattice looked at only when `LATTICE` (a march without one
    /// pays nothing for it: the run loop is compiled once for each).
    #[inline(always)]
    fn step_in<const LATTICE: bool>(&self, c: Coord, axis: usize, d: i32) -> Option<Coord> {
        if LATTICE && let Some(l) = &self.lattice {
            return l.step(c, axis, d);
        }
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

    /// The voxels frozen initially, in the order they were given.
    pub(crate) fn initial(&self) -> &[Coord] {
        &self.initial
    }

    /// Replaces the value of every initial voxel `c` by `f(c, value)` (before
    /// [`Marcher::run`]; `f` must keep the sign).
    pub(crate) fn map_initial(&mut self, f: impl Fn(Coord, f64) -> f64) {
        for &c in &self.initial {
            let id = self.store.find(c).expect("frozen voxels are stored") as usize;
            self.store.vox[id].value = f(c, self.store.vox[id].value);
        }
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
    #[inline(always)]
    fn frozen_at(&self, c: Coord, id: u32, axis: usize, d: i32) -> Option<(f64, u8)> {
        self.frozen_in::<true>(c, id, axis, d)
    }

    /// [`Marcher::frozen_at`], periodic axes looked at only when `LATTICE`.
    #[inline(always)]
    fn frozen_in<const LATTICE: bool>(
        &self,
        c: Coord,
        id: u32,
        axis: usize,
        d: i32,
    ) -> Option<(f64, u8)> {
        if LATTICE && self.wraps[axis] {
            // Across a periodic face the neighbour is not the next voxel in the store.
            let n = self.step(c, axis, d)?;
            let v = &self.store.vox[self.store.find(n)? as usize];
            (v.state & 3 == FROZEN).then_some((v.value, v.state))
        } else {
            self.store.frozen_step(id, axis, d)
        }
    }

    /// The voxel id of the neighbour `n = c + d · axis` (from [`Marcher::step`]),
    /// creating its block when needed.
    #[inline(always)]
    fn neighbour_id<const LATTICE: bool>(&mut self, id: u32, axis: usize, d: i32, n: Coord) -> u32 {
        if LATTICE && self.wraps[axis] {
            self.store.find_or_insert(n)
        } else {
            self.store.step_or_insert(id, axis, d, n)
        }
    }

    /// The extended value at a voxel just frozen with time `t` (side convention): the
    /// discrete `∇f · ∇T = 0` of Adalsteinsson & Sethian, *The Fast Construction of
    /// Extension Velocities in Level Set Methods*, J. Comput. Phys. 148 (1999) 2–22:
    /// `Σₐ (f − f_a) gₐ / hₐ² = 0` over the upwind neighbour `a` of each axis (the
    /// smaller usable frozen one, as in [`Marcher::update`]), with `f − f_a` the
    /// first-order difference of the extended field and `gₐ / hₐ` the axis's component of
    /// `∇T`: the second-order one-sided difference `(3T − 4T₁ + T₂) / 2` where the voxel
    /// two steps away is frozen and not larger (Bærentzen 2001, Sec. 4, eq. (7)), else
    /// `T − T₁`; only positive components count. So `f` is the average of the upwind
    /// neighbours' values weighted by `gₐ / hₐ²` — the neighbours that determined `T`,
    /// each by its share — and never leaves their range. (scikit-fmm weighs by the
    /// first-order `T − T₁`; the second-order component, when the march has frozen the
    /// voxel two steps away, gives the characteristics' direction more accurately, in
    /// either order of the march.)
    fn extend(&mut self, c: Coord, id: u32, inside: bool, t: f64) {
        let Some(l) = &self.lattice else { return };
        let Some(ext) = &self.extension else { return };
        let s = if inside { -1.0 } else { 1.0 };
        let side = if inside { INSIDE } else { 0 };
        let usable = |st: u8| st & INITIAL != 0 || st & INSIDE == side;
        let (mut num, mut den, mut sum, mut cnt) = (0.0, 0.0, 0.0, 0.0);
        for axis in 0..3 {
            // The upwind neighbour (value, direction), as in `update`.
            let mut best: Option<(f64, i32)> = None;
            for d in [-1, 1] {
                let Some((tn, st)) = self.frozen_at(c, id, axis, d) else { continue };
                if usable(st) && best.is_none_or(|(b, _)| s * tn < b) {
                    best = Some((s * tn, d));
                }
            }
            let Some((t1, d)) = best else { continue };
            let n = self.step(c, axis, d).expect("a frozen neighbour exists");
            let f = ext.values[l.index(n)];
            // The axis's component of ∇T (times hₐ): the second-order one-sided
            // difference (3T − 4T₁ + T₂)/2 where the voxel beyond is frozen and not
            // larger, else T − T₁.
            let g = match self.frozen_at(c, id, axis, 2 * d) {
                Some((t2, st2)) if usable(st2) && s * t2 <= t1 => {
                    (3.0 * t - 4.0 * t1 + s * t2) / 2.0
                }
                _ => t - t1,
            };
            if g > 0.0 {
                let w = self.weights[axis] * g;
                num += w * f;
                den += w;
            }
            sum += f;
            cnt += 1.0;
        }
        // A voxel is frozen from at least one upwind neighbour below its time; the plain
        // average only guards against a zero weight sum.
        let f = if den > 0.0 { num / den } else { sum / cnt };
        let i = l.index(c);
        if let Some(ext) = &mut self.extension {
            ext.values[i] = f;
        }
    }

    #[inline]
    fn update<const SECOND: bool, const LATTICE: bool>(
        &self,
        c: Coord,
        id: u32,
        inside: bool,
    ) -> Result<f64, FmmError> {
        let s = if inside { -1.0 } else { 1.0 };
        let side = if inside { INSIDE } else { 0 };
        let usable = |st: u8| st & INITIAL != 0 || st & INSIDE == side;
        let mut terms = [Term { a: 0.0, k: 0.0 }; 3];
        let mut n = 0;
        for axis in 0..3 {
            let mut v1 = f64::INFINITY;
            let mut v2 = None;
            for d in [-1, 1] {
                let Some((t1, st1)) = self.frozen_in::<LATTICE>(c, id, axis, d) else { continue };
                if !usable(st1) {
                    continue;
                }
                let t1 = s * t1;
                if t1 < v1 {
                    v1 = t1;
                    v2 = None;
                    if SECOND && let Some((t2, st2)) = self.frozen_in::<LATTICE>(c, id, axis, 2 * d)
                    {
                        let t2 = s * t2;
                        if usable(st2) && t2 <= t1 {
                            v2 = Some(t2);
                        }
                    }
                }
            }
            if v1 < f64::INFINITY {
                let w = if LATTICE { self.weights[axis] } else { 1.0 };
                terms[n] = match v2 {
                    Some(v2) => Term { a: w * (9.0 / 4.0), k: (4.0 * v1 - v2) / 3.0 },
                    None => Term { a: w, k: v1 },
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
        match (self.second_order, self.lattice.is_some()) {
            (true, true) => self.run_impl::<true, true>(limit, &ticker),
            (true, false) => self.run_impl::<true, false>(limit, &ticker),
            (false, true) => self.run_impl::<false, true>(limit, &ticker),
            (false, false) => self.run_impl::<false, false>(limit, &ticker),
        }
    }

    fn run_impl<const SECOND: bool, const LATTICE: bool>(
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
                    let Some(n) = self.step_in::<LATTICE>(c, axis, d) else { continue };
                    let nid = self.neighbour_id::<LATTICE>(id as u32, axis, d, n) as usize;
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
            let t = self.update::<SECOND, LATTICE>(c, id, inside)?;
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
                // Without a finite limit (a dense array marched whole), the share of the
                // array's voxels frozen.
                let share = if limit.is_finite() || self.expected == 0 {
                    t / limit
                } else {
                    popped as f64 / self.expected as f64
                };
                ticker.set(((share * PROGRESS_UNITS as f64) as u64).min(PROGRESS_UNITS))?;
            }
            let inside_bit = self.store.vox[id as usize].state & INSIDE;
            let inside = inside_bit != 0;
            self.store.vox[id as usize].state = FROZEN | inside_bit;
            self.store.vox[id as usize].value = if inside { -t } else { t };
            if LATTICE && self.extension.is_some() {
                self.extend(c, id, inside, t);
            }
            for axis in 0..3 {
                for d in [-1, 1] {
                    let Some(n) = self.step_in::<LATTICE>(c, axis, d) else { continue };
                    let nid = self.neighbour_id::<LATTICE>(id, axis, d, n) as usize;
                    match self.store.vox[nid].state & 3 {
                        FROZEN => {}
                        TRIAL => {
                            let inside_n = self.store.vox[nid].state & INSIDE != 0;
                            let t = self.update::<SECOND, LATTICE>(n, nid as u32, inside_n)?;
                            let h = self.store.vox[nid].handle;
                            if self.heap.key(h) != t {
                                self.heap.update(h, t);
                            }
                        }
                        _ => {
                            self.store.vox[nid].state = TRIAL | inside_bit;
                            let t = self.update::<SECOND, LATTICE>(n, nid as u32, inside)?;
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
