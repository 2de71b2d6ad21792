//! Constant-time stencil access (paper Sec. 3.3, Appendix C).

use super::access::Locator;
use super::iter::{Cursor, Step};
use super::DtGrid;
use crate::coord::{Coord, NEIGHBOURHOOD};
use crate::grid::GridError;

/// A stencil: a list of voxel offsets from the centre. [`StencilIter::values`] returns
/// one value per offset, in this order. Offsets may be anything (also repeated or far
/// away); the centre need not be among them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stencil {
    offsets: Vec<Coord>,
}

impl Stencil {
    /// A stencil from offsets (at least one).
    pub fn new(offsets: Vec<Coord>) -> Result<Stencil, GridError> {
        if offsets.is_empty() {
            return Err(GridError::InvalidParameter("a stencil needs at least one offset".into()));
        }
        Ok(Stencil { offsets })
    }

    /// The 7-point star: `[centre, -x, +x, -y, +y, -z, +z]`.
    pub fn star7() -> Stencil {
        let mut offsets = vec![Coord::new(0, 0, 0)];
        for a in [Coord::new(1, 0, 0), Coord::new(0, 1, 0), Coord::new(0, 0, 1)] {
            offsets.push(Coord::new(-a.x, -a.y, -a.z));
            offsets.push(a);
        }
        Stencil { offsets }
    }

    /// The 3×3×3 box in the order of [`crate::coord::NEIGHBOURHOOD`]: index
    /// `9 (dz+1) + 3 (dy+1) + (dx+1)`, centre at 13.
    pub fn box27() -> Stencil {
        Stencil { offsets: NEIGHBOURHOOD.to_vec() }
    }

    /// The 19-point WENO5 star: the centre at index 0, then for each axis x, y, z (in that
    /// order) the offsets -3, -2, -1, +1, +2, +3 along it: axis `a` (0 = x) and step `s`
    /// sit at index `1 + 6a + (s + 3)` for `s < 0` and `6a + (s + 3)` for `s > 0`.
    pub fn weno5() -> Stencil {
        let mut offsets = vec![Coord::new(0, 0, 0)];
        for a in 0..3 {
            for s in [-3, -2, -1, 1, 2, 3] {
                let mut o = [0; 3];
                o[a] = s;
                offsets.push(Coord::new(o[0], o[1], o[2]));
            }
        }
        Stencil { offsets }
    }

    #[inline]
    pub fn offsets(&self) -> &[Coord] {
        &self.offsets
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.offsets.len()
    }

    /// Always `false`: a stencil has at least one offset.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.offsets.is_empty()
    }

    /// Position of an offset in the stencil.
    pub fn index_of(&self, offset: Coord) -> Option<usize> {
        self.offsets.iter().position(|&o| o == offset)
    }
}

/// The per-follower state touched on every step of the centre along x. A follower is
/// either *inside* (its target is stored at value index `iv`; the component's last point
/// is `last`) or *outside* (its value is `±γ` and stays so for `wait` more unit steps,
/// until the target reaches the next component of its p-column; `u32::MAX` when none
/// follows). `iv < last` is the Appendix C fast path.
#[derive(Clone, Copy, Debug, Default)]
struct Hot {
    iv: u32,
    last: u32,
    wait: u32,
}

/// The rest of a follower: its x offset, its column group, its position among the x
/// components of its target p-column (`c3` advances monotonically in `lo..hi`), and,
/// while inside, the length of the gap after its component.
#[derive(Clone, Copy, Debug)]
struct Follower {
    dx: i64,
    group: usize,
    has_column: bool,
    inside: bool,
    c3: u32,
    lo: u32,
    hi: u32,
    gap: u32,
}

/// The 2D part of the followers with one (dy, dz): where their target p-column is
/// (incrementUntil on the 1D and 2D constituents).
#[derive(Clone, Copy, Debug)]
struct ColumnFollower {
    dy: i64,
    dz: i64,
    /// Target z of the last seek (`i64::MIN` before the first).
    tz: i64,
    /// Level 1: first z component ending at or after `tz`; `z_ok` when `tz` is stored.
    c1: usize,
    z_ok: bool,
    /// Level 2: first y component of z column `tz` ending at or after the target y, and
    /// the end of that z column's components.
    c2: usize,
    c2_hi: usize,
    /// Level 3 range of the target p-column when it is stored.
    has_column: bool,
    lo: u32,
    hi: u32,
}

impl ColumnFollower {
    /// Moves to the p-column (tz, ty), which is lexicographically after the previous
    /// target: the components skipped are never revisited, so the total cost over a
    /// sweep is O(C₁ + C₂) per column follower.
    #[inline]
    fn seek(&mut self, g: &DtGrid, tz: i64, ty: i64) {
        if tz != self.tz {
            self.tz = tz;
            let nc = &g.l1.ncoord;
            let mut k = self.c1;
            while k < nc.len() && (nc[k + 1] as i64) < tz {
                k += 2;
            }
            self.c1 = k;
            self.z_ok = k < nc.len() && nc[k] as i64 <= tz;
            if self.z_ok {
                let iv1 = (g.l1.acc[k / 2] as i64 + tz - nc[k] as i64) as usize;
                self.c2 = g.l1.value[iv1].ic as usize;
                self.c2_hi = g.l1.value[iv1 + 1].ic as usize;
            }
        }
        self.has_column = false;
        if !self.z_ok {
            return;
        }
        let nc = &g.l2.ncoord;
        let mut k = self.c2;
        while k < self.c2_hi && (nc[k + 1] as i64) < ty {
            k += 2;
        }
        self.c2 = k;
        if k < self.c2_hi && nc[k] as i64 <= ty {
            let iv2 = (g.l2.acc[k / 2] as i64 + ty - nc[k] as i64) as usize;
            self.has_column = true;
            self.lo = g.l2.value[iv2].ic;
            self.hi = g.l2.value[iv2 + 1].ic;
        }
    }
}

/// The grid arrays the followers read, borrowed once per step.
#[derive(Clone, Copy)]
struct Top<'a> {
    nc: &'a [i32],
    acc: &'a [u32],
    values: &'a [f32],
    gamma: f32,
}

impl Top<'_> {
    #[inline(always)]
    fn background(self, v: f32) -> f32 {
        if v < 0.0 {
            -self.gamma
        } else {
            self.gamma
        }
    }

    /// incrementUntil along x (Appendix C, step 1 within a p-column): skip components
    /// ending before `t`, then read the point or apply the sign rule (step 2, with our
    /// rule for gaps), and set the follower's countdowns.
    #[inline(never)]
    fn seek_x(self, f: &mut Follower, h: &mut Hot, t: i64) -> f32 {
        if !f.has_column {
            f.inside = false;
            *h = Hot { iv: 0, last: 0, wait: u32::MAX };
            return self.gamma;
        }
        let nc = self.nc;
        let (mut k, hi) = (f.c3 as usize, f.hi as usize);
        while k < hi && (nc[k + 1] as i64) < t {
            k += 2;
        }
        f.c3 = k as u32;
        if k < hi && nc[k] as i64 <= t {
            return self.enter(f, h, k, (t - nc[k] as i64) as u32);
        }
        f.inside = false;
        let wait =
            if k < hi { (nc[k] as i64 - t - 1).min(u32::MAX as i64) as u32 } else { u32::MAX };
        *h = Hot { iv: 0, last: 0, wait };
        // Before the column's first component: its first value; otherwise the last value
        // before the gap (or the column's last value).
        let idx = self.acc[k / 2] as usize - (k != f.lo as usize) as usize;
        self.background(self.values[idx])
    }

    /// A jump of `d ≥ 1` along x inside the same p-column (the centre moved to its next
    /// component): stays in the component, lands in the gap after it, or stays in the
    /// current gap when the countdowns allow, else searches.
    #[inline(always)]
    fn jump_x(self, f: &mut Follower, h: &mut Hot, v: f32, d: u32, t: i64) -> f32 {
        if f.inside {
            let left = h.last - h.iv;
            if d <= left {
                h.iv += d;
                return self.values[h.iv as usize];
            }
            let past = d - left;
            if past <= f.gap {
                let last = self.values[h.last as usize];
                f.inside = false;
                f.c3 += 2;
                *h = Hot { iv: 0, last: 0, wait: f.gap - past };
                return self.background(last);
            }
        } else if d <= h.wait {
            h.wait -= d;
            return v;
        }
        self.seek_x(f, h, t)
    }

    /// A unit step along x that the fast paths did not take: either the follower just
    /// left its component (its value `v` was the component's last, whose sign the gap
    /// takes; the gap length is known, so no search), or its wait ran out.
    #[inline(always)]
    fn step_x(self, f: &mut Follower, h: &mut Hot, v: f32, t: i64) -> f32 {
        if f.inside {
            f.inside = false;
            f.c3 += 2;
            *h = Hot { iv: 0, last: 0, wait: f.gap - 1 };
            return self.background(v);
        }
        if !f.has_column {
            return v;
        }
        // The wait ran out: `t` is the start of the next component, `c3`.
        let k = f.c3 as usize;
        debug_assert!(k < f.hi as usize && self.nc[k] as i64 == t);
        self.enter(f, h, k, 0)
    }

    /// Puts the follower on point `offset` of component `k` of its p-column.
    #[inline(always)]
    fn enter(self, f: &mut Follower, h: &mut Hot, k: usize, offset: u32) -> f32 {
        let iv = self.acc[k / 2] + offset;
        *h = Hot { iv, last: self.acc[k / 2 + 1] - 1, wait: 0 };
        f.inside = true;
        let nc = self.nc;
        f.gap = if k + 2 < f.hi as usize {
            (nc[k + 2] as i64 - nc[k + 1] as i64 - 1) as u32
        } else {
            u32::MAX
        };
        self.values[iv as usize]
    }
}

/// Sweeps a [`Stencil`] over every stored point in order, giving the stencil's values at
/// each centre in O(1) amortised per stencil point (paper Sec. 3.3, Appendix C).
///
/// The centre is an [`super::Iter`]-style cursor (Appendix B). Each stencil offset has
/// its own follower iterator that only moves forward and rests on the smallest stored
/// point at or after its target `centre + offset` (incrementUntil, Appendix C step 1);
/// an unstored target reads `±γ` by the sign rule of the [module docs](super) (step 2,
/// with our rule for gaps). How a follower moves depends on how the centre moved:
/// * **+1 in x inside its component** (the common case): the Appendix C fast path. A
///   follower whose point and its successor lie in one component does `iv += 1` and one
///   load. An outside follower counts down the voxels left in its gap and does nothing
///   else; one leaving its component takes the gap's sign from its last value without a
///   search; one whose gap ends enters the next component directly.
/// * **to the next component of the same p-column**: followers stay in their p-columns
///   (Appendix C, first remark); those whose component or gap covers the jump move in
///   O(1), the others advance over the x components of their column.
/// * **into a new p-column**: the target p-column is found by advancing over the 1D and
///   2D constituents. Followers with the same (dy, dz) share this 2D part (one
///   `ColumnFollower` per distinct (dy, dz)): their 2D positions are identical anyway.
///
/// Every follower passes over each component of the grid at most once, so a full sweep
/// costs O(S·(M + C)) for a stencil of S points. Coordinates are offset in i64, so
/// stencils reaching past the i32 range are fine (such targets read as not stored).
///
/// ```
/// # use sparse_levelset::{storage::dtgrid::{DtGrid, Stencil, StencilIter}, Coord, GridSpec};
/// # let g = DtGrid::from_sorted(GridSpec::default(), [(Coord::new(0, 0, 0), -1.0)]).unwrap();
/// let mut it = StencilIter::new(&g, &Stencil::box27());
/// while it.advance() {
///     let (c, v) = (it.center(), it.values());
///     assert_eq!(v[13], g.values()[it.center_index()]);
///     assert_eq!(v[14], g.value(Coord::new(c.x + 1, c.y, c.z)));
/// }
/// ```
#[derive(Clone, Debug)]
pub struct StencilIter<'a> {
    grid: &'a DtGrid,
    center: Option<Cursor>,
    started: bool,
    hot: Vec<Hot>,
    followers: Vec<Follower>,
    columns: Vec<ColumnFollower>,
    values: Vec<f32>,
}

impl<'a> StencilIter<'a> {
    /// A stencil iterator before the first point; call [`StencilIter::advance`].
    pub fn new(grid: &'a DtGrid, stencil: &Stencil) -> StencilIter<'a> {
        let mut columns: Vec<ColumnFollower> = Vec::new();
        let mut followers = Vec::with_capacity(stencil.len());
        for o in stencil.offsets() {
            let (dy, dz) = (o.y as i64, o.z as i64);
            let group = match columns.iter().position(|c| c.dy == dy && c.dz == dz) {
                Some(i) => i,
                None => {
                    columns.push(ColumnFollower {
                        dy,
                        dz,
                        tz: i64::MIN,
                        c1: 0,
                        z_ok: false,
                        c2: 0,
                        c2_hi: 0,
                        has_column: false,
                        lo: 0,
                        hi: 0,
                    });
                    columns.len() - 1
                }
            };
            followers.push(Follower {
                dx: o.x as i64,
                group,
                has_column: false,
                inside: false,
                c3: 0,
                lo: 0,
                hi: 0,
                gap: 0,
            });
        }
        StencilIter {
            grid,
            center: None,
            started: false,
            hot: vec![Hot::default(); stencil.len()],
            followers,
            columns,
            values: vec![grid.gamma(); stencil.len()],
        }
    }

    /// Moves to the next centre (the first one on the first call); `false` when every
    /// stored point has been visited.
    #[inline]
    pub fn advance(&mut self) -> bool {
        let g = self.grid;
        let mut from_x = 0;
        let step = match self.center.as_mut() {
            Some(c) => {
                from_x = c.x as i64;
                c.advance(g)
            }
            None if !self.started => {
                self.started = true;
                match Cursor::first(g) {
                    Some(c) => {
                        self.center = Some(c);
                        Step::NextColumn
                    }
                    None => return false,
                }
            }
            None => return false,
        };
        let top = Top { nc: &g.l3.ncoord, acc: &g.l3.acc, values: &g.l3.value, gamma: g.gamma };
        let c = match step {
            Step::End => {
                self.center = None;
                return false;
            }
            Step::SameComponent => {
                let cx = self.center.as_ref().unwrap().x as i64;
                // Appendix C fast path for stored followers; outside followers count down their
                // gap; the rest take a step that may search.
                for ((h, f), v) in
                    self.hot.iter_mut().zip(&mut self.followers).zip(&mut self.values)
                {
                    if h.iv < h.last {
                        h.iv += 1;
                        // An unchecked load here measured within noise of this one
                        // (`levelset-speedup --storage`, DT-Grid smooth7/star19), so it
                        // stays safe.
                        *v = top.values[h.iv as usize];
                    } else if h.wait > 0 {
                        h.wait -= 1;
                    } else {
                        *v = top.step_x(f, h, *v, cx + f.dx);
                    }
                }
                return true;
            }
            Step::SameColumn => {
                // The centre jumped over a gap of its p-column: followers whose state
                // covers the jump move without a search.
                let cx = self.center.as_ref().unwrap().x as i64;
                let d = (cx - from_x) as u32;
                for ((h, f), v) in
                    self.hot.iter_mut().zip(&mut self.followers).zip(&mut self.values)
                {
                    *v = top.jump_x(f, h, *v, d, cx + f.dx);
                }
                return true;
            }
            Step::NextColumn => {
                let c = self.center.unwrap();
                let (cy, cz) = (c.col.y as i64, c.col.z as i64);
                for col in &mut self.columns {
                    col.seek(g, cz + col.dz, cy + col.dy);
                }
                for f in &mut self.followers {
                    let col = &self.columns[f.group];
                    f.has_column = col.has_column;
                    f.lo = col.lo;
                    f.hi = col.hi;
                    f.c3 = col.lo;
                }
                c
            }
        };
        let cx = c.x as i64;
        for ((h, f), v) in self.hot.iter_mut().zip(&mut self.followers).zip(&mut self.values) {
            *v = top.seek_x(f, h, cx + f.dx);
        }
        true
    }

    /// The current centre. Meaningful after [`StencilIter::advance`] returned `true`.
    #[inline]
    pub fn center(&self) -> Coord {
        self.center.map_or(Coord::default(), |c| c.coord())
    }

    /// Value index of the current centre (into [`DtGrid::values`]).
    #[inline]
    pub fn center_index(&self) -> usize {
        self.center.map_or(0, |c| c.iv)
    }

    /// The locator of the current centre, for neighbour access beyond the stencil.
    pub fn locator(&self) -> Option<Locator> {
        self.center.map(|c| c.locator())
    }

    /// One value per stencil offset, in the stencil's order.
    #[inline]
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Runs `f(centre, centre value index, stencil values)` for every remaining centre.
    #[inline]
    pub fn for_each(mut self, mut f: impl FnMut(Coord, usize, &[f32])) {
        while self.advance() {
            let c = self.center.as_ref().unwrap();
            f(c.coord(), c.iv, &self.values);
        }
    }
}
