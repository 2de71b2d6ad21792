//! The Dynamic Tubular Grid (Nielsen & Museth 2006, Sec. 2–3 and Appendices A–F) in 3D: the
//! reference every speed and correctness claim of the tile engine is measured against.
//!
//! # Layout (paper Sec. 2.1)
//! The grid is defined recursively. With our coordinate order ([`Coord`]: z first, then
//! y, then x, x fastest) the paper's `x_1` is our z, `x_2` our y and `x_N` our x:
//!
//! | constituent | its points | `value` holds | `ncoord` holds |
//! |---|---|---|---|
//! | 1D (`proj1D`) | z values that occur | `IndexPair` into the 2D constituent | z-runs |
//! | 2D (`proj2D`) | (z, y) p-columns of the 3D grid | `IndexPair` into the 3D level | y-runs |
//! | 3D | stored voxels | `f32` level-set values | x-runs |
//!
//! Every constituent stores its points lexicographically in `value`, the start/end
//! coordinate of each connected component (a maximal run of adjacent points inside one
//! p-column) in `ncoord`, and in `acc` the value index of each component's first point.
//! An `IndexPair` of a lower constituent points at the first value (`iv`) and the first
//! `ncoord` entry (`ic`) of its p-column one level up.
//!
//! Two sentinels (a choice of this implementation, not the paper's) remove every
//! "is this the last column?" branch: `value` of the 1D and 2D constituents ends with an
//! extra `IndexPair` holding the sizes of the level above, so a p-column always ends
//! where the next pair starts (the paper uses `value[i+1].ic` the same way in Appendix D,
//! step 1c, without saying what happens for the last column); and every `acc` ends with
//! the number of points of its level, so component `k` holds `acc[k+1] - acc[k]` points.
//!
//! # Outside the band: the sign rule
//! A voxel the grid does not store reads `-γ` inside and `+γ` outside (Sec. 3.3, 3.4).
//! Inside/outside is decided from stored values, identically in random access
//! ([`DtGrid::value`]), neighbour access ([`DtGrid::neighbour`]), the stencil iterator
//! ([`StencilIter`]) and the new points of dilation ([`DtGrid::dilate`]):
//!
//! 1. p-column (z, y) not stored → outside (`+γ`). A bounded interior has band voxels in
//!    every column that crosses it, so an absent column cannot pass through the interior.
//! 2. x before the column's first component → the sign of the column's first value.
//! 3. x after the column's last component → the sign of the column's last value.
//!    (Appendix D, step 2 returns `+γ` in both cases 2 and 3; that is the same on a valid
//!    band of a bounded interior, and our rule stays right for any band.)
//! 4. x in the gap between components k and k+1 → the sign of the **last** value of
//!    component k. Appendix D, step 4b names the *first* value of component k instead;
//!    for a column that enters the interior that value lies on the outer side of the band
//!    and gives the wrong sign, so we use the value next to the gap.
//!
//! A value is "inside" when it is `< 0`; `0.0` and `-0.0` count as outside. The rule is
//! exact for a band of a 1-Lipschitz field (a signed distance) whose half-width exceeds
//! one voxel: adjacent voxels then cannot straddle the band with opposite signs.
//!
//! # Costs (paper Table II)
//! [`DtGrid::push`] O(1); [`Iter`] O(1) per point; [`StencilIter`] O(1) amortised per
//! stencil point; [`DtGrid::value`] O(Σ log C) over the p-columns visited;
//! [`DtGrid::neighbour`] O(1) along x, logarithmic along y and z; [`DtGrid::dilate`] and
//! [`DtGrid::rebuild`] O(C) allocation plus O(M) copy.
//!
//! ```
//! use sparse_levelset::{storage::dtgrid::{DtGrid, Stencil, StencilIter}, Coord, GridSpec};
//!
//! let mut g = DtGrid::new(GridSpec::default()); // γ = 3
//! for x in -2..=2 {
//!     g.push(Coord::new(x, 0, 0), x as f32 * 0.5).unwrap();
//! }
//! assert_eq!(g.value(Coord::new(1, 0, 0)), 0.5);
//! assert_eq!(g.value(Coord::new(-9, 0, 0)), -3.0); // before the run: sign of -1.0
//! assert_eq!(g.value(Coord::new(9, 0, 0)), 3.0);
//! let mut it = StencilIter::new(&g, &Stencil::star7());
//! let mut centres = 0;
//! while it.advance() {
//!     assert_eq!(it.values()[0], g.values()[it.center_index()]);
//!     centres += 1;
//! }
//! assert_eq!(centres, 5);
//! let d = g.dilate(1).unwrap();
//! assert_eq!(d.len(), 7 * 3 * 3);
//! ```

mod access;
mod dilate;
mod iter;
mod stencil;
#[cfg(test)]
mod tests;

pub use access::{Axis, DtAccessor, Locator};
pub use iter::Iter;
pub use stencil::{Stencil, StencilIter};

use crate::coord::Coord;
use crate::grid::{vec_bytes, GridError, GridSpec, MemoryReport};
use crate::storage::levelset::{Accessor, LevelSet};
use std::fmt;

/// Most points a [`DtGrid`] holds: indices are `u32`, and the x-run array of the 3D
/// level may hold two entries per point.
pub const MAX_POINTS: usize = i32::MAX as usize;

/// A pointer from a point of a lower constituent to its p-column one level up
/// (paper Sec. 2.1, `proj(N-1)D`; Appendix B): `iv` is the value index of the column's
/// first point and `ic` the `ncoord` index of the column's first component start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct IndexPair {
    pub iv: u32,
    pub ic: u32,
}

/// One constituent: values, component start/end coordinates, component first-value
/// indices (paper Sec. 2.1). See [`DtGrid`] for the invariants.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Level<T> {
    pub value: Vec<T>,
    pub ncoord: Vec<i32>,
    pub acc: Vec<u32>,
}

impl<T> Level<T> {
    fn empty(value: Vec<T>) -> Self {
        Level { value, ncoord: Vec::new(), acc: vec![0] }
    }

    /// Points of this level (the `acc` sentinel).
    #[inline(always)]
    pub fn points(&self) -> usize {
        self.acc[self.acc.len() - 1] as usize
    }

    /// Appends point `p` to the p-column currently last in this level: extends the last
    /// component when `p` is adjacent to it, else opens a new one (Appendix A, cases 2
    /// and 3). `new_column` forces a new component (Appendix A, case 1).
    #[inline(always)]
    fn append(&mut self, p: i32, new_column: bool) {
        let total = self.acc[self.acc.len() - 1];
        match self.ncoord.last_mut() {
            Some(end) if !new_column && *end as i64 + 1 == p as i64 => {
                *end = p;
                *self.acc.last_mut().unwrap() = total + 1;
            }
            _ => {
                self.ncoord.push(p);
                self.ncoord.push(p);
                self.acc.push(total + 1);
            }
        }
    }

    fn clear(&mut self) {
        self.value.clear();
        self.ncoord.clear();
        self.acc.clear();
        self.acc.push(0);
    }

    fn add_memory(&self, indices: &mut usize, slack: &mut usize) {
        for (u, s) in [vec_bytes(&self.ncoord), vec_bytes(&self.acc)] {
            *indices += u;
            *slack += s;
        }
    }
}

/// A 3D Dynamic Tubular Grid: the narrow band of a level set, stored as three
/// recursively defined constituents (see the [module docs](self)).
///
/// Build it with [`DtGrid::push`] in increasing [`Coord`] order, or with
/// [`DtGrid::dilate`] / [`DtGrid::rebuild`]. Read it with [`DtGrid::iter`],
/// [`StencilIter`], [`DtGrid::value`] and [`DtGrid::locate`] + [`DtGrid::neighbour`].
///
/// # Invariants
/// Writing `n1`, `n2`, `n3` for the points of the 1D, 2D and 3D levels (`n3 = len()`):
/// * every `ncoord` has even length `2·C` (start/end pairs) with `start ≤ end`; every
///   `acc` has `C + 1` entries, `acc[0] = 0`, `acc[k+1] = acc[k] + end_k - start_k + 1`,
///   and its last entry (a sentinel) is the level's point count;
/// * the 1D level is a single p-column; for `i < n1`, p-column `i` of the 2D level is
///   `ncoord₂[value₁[i].ic .. value₁[i+1].ic]`, non-empty, with
///   `value₁[i].iv = acc₂[value₁[i].ic / 2]`; `value₁` has `n1 + 1` entries, the last a
///   sentinel `(n2, len ncoord₂)`; likewise between the 2D and 3D levels;
/// * inside every p-column, components are sorted and separated by at least one missing
///   coordinate (`start_{k+1} > end_k + 1`), so points are in strictly increasing
///   [`Coord`] order in `values()`;
/// * values are not NaN and lie in `[-γ, γ]`; `n3 ≤` [`MAX_POINTS`];
/// * the empty grid has empty `ncoord`s, `acc = [0]` and the sentinel `(0, 0)` only.
///
/// [`DtGrid::check_invariants`] verifies all of this (O(M)); it runs under
/// `debug_assert!` after dilation and rebuild. Only [`DtGrid::values_mut`] can break the
/// value invariant; no method relies on it for memory safety.
#[derive(Clone, PartialEq)]
pub struct DtGrid {
    spec: GridSpec,
    gamma: f32,
    /// 1D constituent: points are z values.
    l1: Level<IndexPair>,
    /// 2D constituent: points are (z, y) p-columns of the 3D grid.
    l2: Level<IndexPair>,
    /// 3D level: points are voxels, values are φ.
    l3: Level<f32>,
}

// The grid is plain data: shareable across threads.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<DtGrid>();
};

impl Default for DtGrid {
    fn default() -> Self {
        DtGrid::new(GridSpec::default())
    }
}

impl fmt::Debug for DtGrid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("DtGrid")
            .field("spec", &self.spec)
            .field("len", &self.len())
            .field("columns", &self.l2.points())
            .field("components", &self.num_components())
            .field("bounding_box", &self.bounding_box())
            .finish()
    }
}

impl DtGrid {
    /// An empty grid (every voxel reads `+γ`).
    pub fn new(spec: GridSpec) -> DtGrid {
        let sentinel = || vec![IndexPair::default()];
        DtGrid {
            spec,
            gamma: spec.gamma(),
            l1: Level::empty(sentinel()),
            l2: Level::empty(sentinel()),
            l3: Level::empty(Vec::new()),
        }
    }

    /// An empty grid with room for `points` values.
    pub fn with_capacity(spec: GridSpec, points: usize) -> DtGrid {
        let mut g = DtGrid::new(spec);
        g.l3.value.reserve(points);
        g
    }

    /// Builds a grid from points in strictly increasing [`Coord`] order (see
    /// [`DtGrid::push`]).
    pub fn from_sorted<I>(spec: GridSpec, points: I) -> Result<DtGrid, GridError>
    where
        I: IntoIterator<Item = (Coord, f32)>,
    {
        let points = points.into_iter();
        let mut g = DtGrid::with_capacity(spec, points.size_hint().0);
        for (c, v) in points {
            g.push(c, v)?;
        }
        Ok(g)
    }

    /// Releases unused capacity of every array (what `memory()` reports as slack).
    pub fn shrink_to_fit(&mut self) {
        for l in [&mut self.l1.ncoord, &mut self.l2.ncoord, &mut self.l3.ncoord] {
            l.shrink_to_fit();
        }
        for a in [&mut self.l1.acc, &mut self.l2.acc, &mut self.l3.acc] {
            a.shrink_to_fit();
        }
        self.l1.value.shrink_to_fit();
        self.l2.value.shrink_to_fit();
        self.l3.value.shrink_to_fit();
    }

    /// Removes every point, keeping the allocations.
    pub fn clear(&mut self) {
        self.l1.clear();
        self.l1.value.push(IndexPair::default());
        self.l2.clear();
        self.l2.value.push(IndexPair::default());
        self.l3.clear();
    }

    /// Placement and band half-width.
    #[inline]
    pub fn spec(&self) -> GridSpec {
        self.spec
    }

    /// γ = half-width × voxel size: the magnitude read outside the band.
    #[inline]
    pub fn gamma(&self) -> f32 {
        self.gamma
    }

    /// Stored points.
    #[inline]
    pub fn len(&self) -> usize {
        self.l3.value.len()
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.l3.value.is_empty()
    }

    /// Values of all stored points in lexicographic [`Coord`] order: the `k`-th point of
    /// [`DtGrid::iter`] has value index `k`.
    #[inline]
    pub fn values(&self) -> &[f32] {
        &self.l3.value
    }

    /// Mutable values, same order as [`DtGrid::values`]. The structure cannot change
    /// through this; the caller keeps values non-NaN and in `[-γ, γ]` (the sign rule
    /// reads them).
    #[inline]
    pub fn values_mut(&mut self) -> &mut [f32] {
        &mut self.l3.value
    }

    /// Swaps the values of all points with `values` (same length, same order as
    /// [`DtGrid::values`]): the double buffer of a time step. The caller keeps values
    /// finite and in `[-γ, γ]` as for [`DtGrid::values_mut`] (checked in debug builds); a
    /// length mismatch is an error and leaves the grid as it was.
    pub fn swap_values(&mut self, values: &mut Vec<f32>) -> Result<(), GridError> {
        if values.len() != self.len() {
            return Err(GridError::InvalidParameter(format!(
                "{} values for a grid of {} points",
                values.len(),
                self.len()
            )));
        }
        debug_assert!(values.iter().all(|v| v.abs() <= self.gamma), "value NaN or beyond γ");
        std::mem::swap(&mut self.l3.value, values);
        Ok(())
    }

    /// Stored points with `|φ| < γ` (the band voxels of [`GridSpec`]).
    pub fn band_voxels(&self) -> usize {
        let g = self.gamma;
        self.l3.value.iter().filter(|v| v.abs() < g).count()
    }

    /// Number of p-columns (stored (z, y) pairs).
    pub fn num_columns(&self) -> usize {
        self.l2.points()
    }

    /// Connected components of the 1D, 2D and 3D levels (`C_1, C_2, C_3`).
    pub fn num_components(&self) -> [usize; 3] {
        [self.l1.ncoord.len() / 2, self.l2.ncoord.len() / 2, self.l3.ncoord.len() / 2]
    }

    /// Smallest box `(min, max)` (both inclusive) holding every stored point, `None`
    /// when empty. O(number of z values + number of p-columns).
    pub fn bounding_box(&self) -> Option<(Coord, Coord)> {
        if self.is_empty() {
            return None;
        }
        let col_span = |nc: &[i32], pairs: &[IndexPair]| {
            let (mut lo, mut hi) = (i32::MAX, i32::MIN);
            for w in pairs.windows(2) {
                lo = lo.min(nc[w[0].ic as usize]);
                hi = hi.max(nc[w[1].ic as usize - 1]);
            }
            (lo, hi)
        };
        let (y0, y1) = col_span(&self.l2.ncoord, &self.l1.value);
        let (x0, x1) = col_span(&self.l3.ncoord, &self.l2.value);
        let nc1 = &self.l1.ncoord;
        Some((Coord::new(x0, y0, nc1[0]), Coord::new(x1, y1, nc1[nc1.len() - 1])))
    }

    /// The last stored point (the largest coordinate), `None` when empty. Each level's
    /// last `ncoord` entry ends the last component, which holds the last point.
    #[inline]
    pub fn last(&self) -> Option<Coord> {
        Some(Coord::new(*self.l3.ncoord.last()?, *self.l2.ncoord.last()?, *self.l1.ncoord.last()?))
    }

    /// Appends a point (Appendix A, generalised to 3D): O(1).
    ///
    /// `c` must be larger than every stored coordinate in [`Coord`] order, else
    /// [`GridError::NotSorted`]; a NaN value gives [`GridError::NaN`]; the value is
    /// clamped to `[-γ, γ]`. More than [`MAX_POINTS`] points give
    /// [`GridError::InvalidParameter`]. On error the grid is unchanged.
    pub fn push(&mut self, c: Coord, v: f32) -> Result<(), GridError> {
        if v.is_nan() {
            return Err(GridError::NaN { coord: c });
        }
        if let Some(last) = self.last()
            && c <= last
        {
            return Err(GridError::NotSorted { last, coord: c });
        }
        if self.len() >= MAX_POINTS {
            return Err(GridError::InvalidParameter(format!(
                "a DT-Grid holds at most {MAX_POINTS} points"
            )));
        }
        self.push_sorted(c, v.clamp(-self.gamma, self.gamma));
        Ok(())
    }

    /// [`DtGrid::push`] without the checks: `c` is larger than every stored point, `v` is
    /// in `[-γ, γ]`, the grid is not full.
    #[inline]
    pub(crate) fn push_sorted(&mut self, c: Coord, v: f32) {
        let (new_z, new_y) = match self.last() {
            None => (true, true),
            Some(last) => {
                debug_assert!(c > last);
                (c.z != last.z, c.z != last.z || c.y != last.y)
            }
        };
        // Appendix A: a point opening a p-column at one level is a new point of the level
        // below; its IndexPair is the level-below sentinel as it stands before the push
        // (the sizes of this level), so that sentinel stays and a new one is appended.
        if new_z {
            self.l1.append(c.z, false);
        }
        if new_y {
            self.l2.append(c.y, new_z);
        }
        self.l3.append(c.x, new_y);
        self.l3.value.push(v);
        let top = IndexPair { iv: self.l3.value.len() as u32, ic: self.l3.ncoord.len() as u32 };
        if new_y {
            self.l2.value.push(top);
        } else {
            *self.l2.value.last_mut().unwrap() = top;
        }
        if new_y {
            let mid = IndexPair { iv: self.l2.points() as u32, ic: self.l2.ncoord.len() as u32 };
            if new_z {
                self.l1.value.push(mid);
            } else {
                *self.l1.value.last_mut().unwrap() = mid;
            }
        }
    }

    /// Bytes used: values = 4·len; indices = every `ncoord`, `acc` and `IndexPair`
    /// array of the three levels (sentinels included); flags = 0; slack = unused vector
    /// capacity.
    pub fn memory(&self) -> MemoryReport {
        let (values, mut slack) = vec_bytes(&self.l3.value);
        let mut indices = 0;
        for v in [&self.l1.value, &self.l2.value] {
            let (u, s) = vec_bytes(v);
            indices += u;
            slack += s;
        }
        self.l1.add_memory(&mut indices, &mut slack);
        self.l2.add_memory(&mut indices, &mut slack);
        self.l3.add_memory(&mut indices, &mut slack);
        MemoryReport { values, indices, flags: 0, slack }
    }

    /// Checks every invariant listed on [`DtGrid`]; O(M). `Err` names the first
    /// violation.
    pub fn check_invariants(&self) -> Result<(), String> {
        let n3 = self.l3.value.len();
        if n3 > MAX_POINTS {
            return Err(format!("{n3} points exceed MAX_POINTS"));
        }
        check_level("3D", &self.l3.ncoord, &self.l3.acc)?;
        check_level("2D", &self.l2.ncoord, &self.l2.acc)?;
        check_level("1D", &self.l1.ncoord, &self.l1.acc)?;
        if self.l3.points() != n3 {
            return Err(format!("3D acc sentinel {} != {n3} values", self.l3.points()));
        }
        check_runs("1D", &self.l1.ncoord, 0, self.l1.ncoord.len())?;
        check_projection("1D→2D", &self.l1.value, self.l1.points(), &self.l2.ncoord, &self.l2.acc)?;
        check_projection("2D→3D", &self.l2.value, self.l2.points(), &self.l3.ncoord, &self.l3.acc)?;
        if (n3 == 0) != (self.l1.points() == 0) || (n3 == 0) != (self.l2.points() == 0) {
            return Err("levels disagree on emptiness".into());
        }
        let g = self.gamma;
        if let Some(i) = self.l3.value.iter().position(|v| v.is_nan() || v.abs() > g) {
            return Err(format!(
                "value {} at index {i} is NaN or outside [-γ, γ]",
                self.l3.value[i]
            ));
        }
        Ok(())
    }
}

/// `ncoord`/`acc` shape of one level.
fn check_level(name: &str, nc: &[i32], acc: &[u32]) -> Result<(), String> {
    if !nc.len().is_multiple_of(2) || acc.len() != nc.len() / 2 + 1 || acc[0] != 0 {
        return Err(format!("{name}: ncoord/acc shape ({} / {})", nc.len(), acc.len()));
    }
    for (k, p) in nc.as_chunks::<2>().0.iter().enumerate() {
        if p[0] > p[1] {
            return Err(format!("{name}: component {k} starts after it ends"));
        }
        let want = acc[k] as i64 + p[1] as i64 - p[0] as i64 + 1;
        if acc[k + 1] as i64 != want {
            return Err(format!("{name}: acc[{}] = {} != {want}", k + 1, acc[k + 1]));
        }
    }
    Ok(())
}

/// Components `nc[lo..hi]` of one p-column are sorted with gaps between them.
fn check_runs(name: &str, nc: &[i32], lo: usize, hi: usize) -> Result<(), String> {
    for k in (lo + 2..hi).step_by(2) {
        if nc[k] as i64 <= nc[k - 1] as i64 + 1 {
            return Err(format!("{name}: components at ncoord {} and {k} touch or overlap", k - 2));
        }
    }
    Ok(())
}

/// The IndexPairs of a lower level (with `n` points) partition the level above into
/// non-empty p-columns.
fn check_projection(
    name: &str,
    pairs: &[IndexPair],
    n: usize,
    nc: &[i32],
    acc: &[u32],
) -> Result<(), String> {
    if pairs.len() != n + 1 {
        return Err(format!("{name}: {} index pairs for {n} points", pairs.len()));
    }
    if pairs[0] != IndexPair::default() {
        return Err(format!("{name}: first pair {:?}", pairs[0]));
    }
    let end = IndexPair { iv: acc[acc.len() - 1], ic: nc.len() as u32 };
    if pairs[n] != end {
        return Err(format!("{name}: sentinel {:?} != {end:?}", pairs[n]));
    }
    for i in 0..n {
        let (a, b) = (pairs[i], pairs[i + 1]);
        if a.ic % 2 != 0 || a.ic >= b.ic || b.ic as usize > nc.len() {
            return Err(format!("{name}: p-column {i} has ncoord range {}..{}", a.ic, b.ic));
        }
        if a.iv != acc[a.ic as usize / 2] {
            return Err(format!(
                "{name}: p-column {i} iv {} != acc {}",
                a.iv,
                acc[a.ic as usize / 2]
            ));
        }
        check_runs(name, nc, a.ic as usize, b.ic as usize)?;
    }
    Ok(())
}

impl LevelSet for DtGrid {
    fn spec(&self) -> GridSpec {
        DtGrid::spec(self)
    }
    fn value(&self, voxel: Coord) -> f32 {
        DtGrid::value(self, voxel)
    }
    /// Random access (Sec. 3.4) with the p-columns of recent lookups cached, so that a
    /// stencil's lookups search only their column ([`crate::storage::dtgrid::DtAccessor`]).
    fn accessor(&self) -> impl Accessor + '_ {
        crate::storage::dtgrid::DtAccessor::new(self)
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.gamma();
        for (c, v) in self.iter() {
            if v.abs() < g {
                f(c, v);
            }
        }
    }
    fn band_voxels(&self) -> usize {
        DtGrid::band_voxels(self)
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        DtGrid::bounding_box(self)
    }
    fn memory(&self) -> MemoryReport {
        DtGrid::memory(self)
    }
    fn storage(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }
}

impl Accessor for crate::storage::dtgrid::DtAccessor<'_> {
    #[inline]
    fn value(&mut self, voxel: Coord) -> f32 {
        crate::storage::dtgrid::DtAccessor::value(self, voxel)
    }
}

impl DtGrid {
    /// The DT-Grid behind `ls`, when it is one ([`LevelSet::storage`]).
    pub fn of<L: LevelSet + ?Sized>(ls: &L) -> Option<&DtGrid> {
        ls.storage()?.downcast_ref()
    }
}
