//! Random access (paper Sec. 3.4, Appendix D) and locator-based neighbour access
//! (Sec. 3.5).

use super::DtGrid;
use crate::coord::Coord;

/// A coordinate axis. `X` is the fastest axis (the paper's `x_N`), `Z` the slowest (`x_1`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// The unit offset along this axis.
    pub fn unit(self) -> Coord {
        match self {
            Axis::X => Coord::new(1, 0, 0),
            Axis::Y => Coord::new(0, 1, 0),
            Axis::Z => Coord::new(0, 0, 1),
        }
    }
}

/// Where a stored point sits in every constituent (paper Sec. 3.5, `LocatorND`): per
/// level, the value index `iv` of the point (the z value, the (z, y) p-column, the voxel)
/// and the `ncoord` index `ic` of the start of the component holding it.
///
/// A locator is only meaningful for the grid that produced it (via [`DtGrid::locate`],
/// [`DtGrid::neighbour_locator`] or [`super::StencilIter::locator`]) and only until that
/// grid's structure changes (push, clear). Using it with another grid gives wrong values
/// or a panic, never undefined behaviour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Locator {
    pub(crate) iv1: u32,
    pub(crate) ic1: u32,
    pub(crate) iv2: u32,
    pub(crate) ic2: u32,
    pub(crate) iv3: u32,
    pub(crate) ic3: u32,
    pub(crate) coord: Coord,
}

impl Locator {
    /// The located point.
    #[inline]
    pub fn coord(&self) -> Coord {
        self.coord
    }

    /// Its index into [`DtGrid::values`].
    #[inline]
    pub fn index(&self) -> usize {
        self.iv3 as usize
    }
}

/// First component (even `ncoord` index) in `lo..hi` whose end is `≥ t`, or `hi`.
/// `lo..hi` is one p-column, so ends increase strictly.
#[inline(always)]
pub(crate) fn first_end_at_least(nc: &[i32], lo: usize, hi: usize, t: i64) -> usize {
    let (pairs, _) = nc[lo..hi].as_chunks::<2>();
    lo + 2 * pairs.partition_point(|p| (p[1] as i64) < t)
}

/// `t - start` for `t ≥ start`, as an index offset.
#[inline(always)]
fn offset(t: i64, start: i32) -> u32 {
    (t - start as i64) as u32
}

impl DtGrid {
    /// Level 1: the z-projection is a single p-column. `(iv1, ic1)` when z is stored.
    #[inline]
    fn find_z(&self, z: i64) -> Option<(u32, u32)> {
        let nc = &self.l1.ncoord;
        let k = first_end_at_least(nc, 0, nc.len(), z);
        if k == nc.len() || z < nc[k] as i64 {
            return None;
        }
        Some((self.l1.acc[k / 2] + offset(z, nc[k]), k as u32))
    }

    /// Level 2: `(iv2, ic2)` of p-column (z, y) given the z point `iv1`.
    #[inline]
    fn find_y(&self, iv1: u32, y: i64) -> Option<(u32, u32)> {
        let v = &self.l1.value;
        let (lo, hi) = (v[iv1 as usize].ic as usize, v[iv1 as usize + 1].ic as usize);
        let nc = &self.l2.ncoord;
        let k = first_end_at_least(nc, lo, hi, y);
        if k == hi || y < nc[k] as i64 {
            return None;
        }
        Some((self.l2.acc[k / 2] + offset(y, nc[k]), k as u32))
    }

    /// Level 3: `Ok((iv3, ic3))` when x is stored in p-column `iv2`, else `Err(inside)`
    /// by the sign rule of the [module docs](super).
    #[inline]
    fn find_x(&self, iv2: u32, x: i64) -> Result<(u32, u32), bool> {
        let v = &self.l2.value;
        let (lo, hi) = (v[iv2 as usize].ic as usize, v[iv2 as usize + 1].ic as usize);
        self.resolve_x(lo, hi, first_end_at_least(&self.l3.ncoord, lo, hi, x), x)
    }

    /// Given the first component `k` of column `lo..hi` whose end is `≥ x` (or `hi`).
    #[inline(always)]
    fn resolve_x(&self, lo: usize, hi: usize, k: usize, x: i64) -> Result<(u32, u32), bool> {
        let nc = &self.l3.ncoord;
        let acc = &self.l3.acc;
        if k < hi && x >= nc[k] as i64 {
            return Ok((acc[k / 2] + offset(x, nc[k]), k as u32));
        }
        // Before the first component: the column's first value; otherwise the last value
        // of the component before `k` (the gap's left side, or the column's last value).
        let idx = acc[k / 2] as usize - (k != lo) as usize;
        Err(self.l3.value[idx] < 0.0)
    }

    /// Random access (Appendix D), recursive over the levels: `Ok(value index)` when `c`
    /// is stored, else `Err(inside)` by the sign rule of the [module docs](super).
    /// O(log C) per level; for one or two components per column the binary search is a
    /// handful of comparisons.
    #[inline]
    pub fn find(&self, c: Coord) -> Result<usize, bool> {
        let (iv1, _) = self.find_z(c.z as i64).ok_or(false)?;
        let (iv2, _) = self.find_y(iv1, c.y as i64).ok_or(false)?;
        self.find_x(iv2, c.x as i64).map(|(iv, _)| iv as usize)
    }

    /// φ at any voxel: the stored value, or `±γ` outside the band (sign rule of the
    /// [module docs](super)).
    #[inline]
    pub fn value(&self, c: Coord) -> f32 {
        match self.find(c) {
            Ok(i) => self.l3.value[i],
            Err(inside) => self.spec.background(inside),
        }
    }

    /// Whether `c` is stored.
    #[inline]
    pub fn contains(&self, c: Coord) -> bool {
        self.find(c).is_ok()
    }

    /// Whether `c` is inside (φ < 0), stored or not.
    #[inline]
    pub fn is_inside(&self, c: Coord) -> bool {
        match self.find(c) {
            Ok(i) => self.l3.value[i] < 0.0,
            Err(inside) => inside,
        }
    }

    /// The p-column (z, y) as its level-2 point index, `None` when no point of it is
    /// stored (then every voxel of it is outside).
    #[inline]
    pub(crate) fn column(&self, y: i32, z: i32) -> Option<u32> {
        let (iv1, _) = self.find_z(z as i64)?;
        self.find_y(iv1, y as i64).map(|(iv2, _)| iv2)
    }

    /// φ at x in the p-column `iv2` of [`DtGrid::column`]: the stored value or `±γ`.
    #[inline]
    pub(crate) fn value_in_column(&self, iv2: u32, x: i32) -> f32 {
        match self.find_x(iv2, x as i64) {
            Ok((iv, _)) => self.l3.value[iv as usize],
            Err(inside) => self.spec.background(inside),
        }
    }

    /// The [`Locator`] of a stored point, `None` when `c` is not stored. Same cost as
    /// [`DtGrid::find`].
    pub fn locate(&self, c: Coord) -> Option<Locator> {
        let (iv1, ic1) = self.find_z(c.z as i64)?;
        let (iv2, ic2) = self.find_y(iv1, c.y as i64)?;
        let (iv3, ic3) = self.find_x(iv2, c.x as i64).ok()?;
        Some(Locator { iv1, ic1, iv2, ic2, iv3, ic3, coord: c })
    }

    /// The stored value at a locator.
    #[inline]
    pub fn value_at(&self, loc: &Locator) -> f32 {
        self.l3.value[loc.iv3 as usize]
    }

    /// φ at `loc.coord() + delta · axis` (paper Sec. 3.5), `±γ` outside the band by the
    /// sign rule. Along x this is O(1) while the target is in the locator's component or
    /// next to it (`delta = ±1` always is); along y it is O(1) in the level-2 component
    /// plus a binary search of the target p-column; along z a search of the z column is
    /// added. Targets beyond the i32 range read as not stored.
    #[inline]
    pub fn neighbour(&self, loc: &Locator, axis: Axis, delta: i32) -> f32 {
        match self.neighbour_locator(loc, axis, delta) {
            Ok(l) => self.l3.value[l.iv3 as usize],
            Err(inside) => self.spec.background(inside),
        }
    }

    /// Like [`DtGrid::neighbour`], returning the neighbour's [`Locator`] when it is
    /// stored and `Err(inside)` otherwise.
    pub fn neighbour_locator(
        &self,
        loc: &Locator,
        axis: Axis,
        delta: i32,
    ) -> Result<Locator, bool> {
        let d = delta as i64;
        let c = loc.coord;
        match axis {
            Axis::X => {
                let t = c.x as i64 + d;
                let nc = &self.l3.ncoord;
                let k = loc.ic3 as usize;
                let (s, e) = (nc[k] as i64, nc[k + 1] as i64);
                if s <= t && t <= e {
                    return Ok(Locator {
                        iv3: (loc.iv3 as i64 + d) as u32,
                        coord: Coord::new(t as i32, c.y, c.z),
                        ..*loc
                    });
                }
                let v = &self.l2.value;
                let (lo, hi) =
                    (v[loc.iv2 as usize].ic as usize, v[loc.iv2 as usize + 1].ic as usize);
                // Components are separated by gaps, so e + 1 and s - 1 are never stored
                // and the first component ending at or after them is known: O(1).
                let k2 = if t == e + 1 {
                    k + 2
                } else if t == s - 1 {
                    k
                } else if t > e {
                    first_end_at_least(nc, k + 2, hi, t)
                } else {
                    first_end_at_least(nc, lo, k, t)
                };
                let (iv3, ic3) = self.resolve_x(lo, hi, k2, t)?;
                Ok(Locator { iv3, ic3, coord: Coord::new(t as i32, c.y, c.z), ..*loc })
            }
            Axis::Y => {
                let t = c.y as i64 + d;
                let nc = &self.l2.ncoord;
                let k = loc.ic2 as usize;
                let (iv2, ic2) = if nc[k] as i64 <= t && t <= nc[k + 1] as i64 {
                    ((loc.iv2 as i64 + d) as u32, loc.ic2)
                } else {
                    self.find_y(loc.iv1, t).ok_or(false)?
                };
                let (iv3, ic3) = self.find_x(iv2, c.x as i64)?;
                Ok(Locator { iv2, ic2, iv3, ic3, coord: Coord::new(c.x, t as i32, c.z), ..*loc })
            }
            Axis::Z => {
                let t = c.z as i64 + d;
                let nc = &self.l1.ncoord;
                let k = loc.ic1 as usize;
                let (iv1, ic1) = if nc[k] as i64 <= t && t <= nc[k + 1] as i64 {
                    ((loc.iv1 as i64 + d) as u32, loc.ic1)
                } else {
                    self.find_z(t).ok_or(false)?
                };
                let (iv2, ic2) = self.find_y(iv1, c.y as i64).ok_or(false)?;
                let (iv3, ic3) = self.find_x(iv2, c.x as i64)?;
                Ok(Locator { iv1, ic1, iv2, ic2, iv3, ic3, coord: Coord::new(c.x, c.y, t as i32) })
            }
        }
    }
}

/// Random access with a cache of p-columns (the levels 1 and 2 of a lookup): a
/// direct-mapped table over the low two bits of y and z, so the columns of a 3×3 cross or
/// a 2×2 cell never evict each other. A lookup in a cached column is the level-3 search
/// alone, over the few components of one column. The same values as [`DtGrid::value`].
pub struct DtAccessor<'a> {
    grid: &'a DtGrid,
    keys: [(i32, i32); 16],
    columns: [Option<u32>; 16],
    filled: u16,
}

impl<'a> DtAccessor<'a> {
    /// An empty cache over `grid`.
    pub fn new(grid: &'a DtGrid) -> Self {
        DtAccessor { grid, keys: [(0, 0); 16], columns: [None; 16], filled: 0 }
    }

    /// φ at `c`.
    #[inline]
    pub fn value(&mut self, c: Coord) -> f32 {
        let i = ((c.y & 3) | (c.z & 3) << 2) as usize;
        if self.filled & (1 << i) == 0 || self.keys[i] != (c.y, c.z) {
            self.keys[i] = (c.y, c.z);
            self.filled |= 1 << i;
            self.columns[i] = self.grid.column(c.y, c.z);
        }
        match self.columns[i] {
            Some(iv2) => self.grid.value_in_column(iv2, c.x),
            // An absent p-column is outside.
            None => self.grid.spec.background(false),
        }
    }
}
