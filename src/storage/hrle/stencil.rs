//! Cached random access, neighbour access (Sec. 5.2) and the stencil iterator (Sec. 5.3)
//! of the H-RLE level set.

use super::{for_each_element, in_box, Block, HrleGrid, NEG, POS};
use crate::coord::Coord;
use crate::storage::levelset::Accessor;

/// A monotone reader of one segment: lookups at non-decreasing coordinates cost O(1)
/// amortised (a stencil's iterators "pass over the grid once", Sec. 5.3).
#[derive(Clone, Copy)]
pub(crate) struct RunCursor<'a> {
    codes: &'a [u32],
    breaks: &'a [i32],
    r: usize,
}

impl<'a> RunCursor<'a> {
    /// A cursor over segment `s` of `block`.
    pub fn new(block: &'a Block, s: usize) -> Self {
        let (codes, breaks) = block.segment(s);
        RunCursor { codes, breaks, r: 0 }
    }

    /// A cursor over a column with no segment: one undefined run.
    pub fn constant(code: &'a u32) -> Self {
        RunCursor { codes: std::slice::from_ref(code), breaks: &[], r: 0 }
    }

    /// The code at `q` (undefined code, or the element's target); `q` must not decrease
    /// between calls.
    #[inline(always)]
    pub fn at(&mut self, q: i32) -> u32 {
        while self.r < self.breaks.len() && self.breaks[self.r] <= q {
            self.r += 1;
        }
        let code = self.codes[self.r];
        if code >= POS {
            code
        } else {
            code + (q - self.breaks[self.r - 1]) as u32
        }
    }
}

impl HrleGrid {
    /// A cursor over column (z, y).
    pub(crate) fn column_cursor<'a>(
        &'a self,
        z: i32,
        y: i32,
        scratch: &'a mut u32,
    ) -> RunCursor<'a> {
        let outside_domain =
            self.domain.is_some_and(|(lo, hi)| !in_box(Coord::new(lo.x, y, z), lo, hi));
        match self.column(z, y) {
            Ok(xs) if !outside_domain => RunCursor::new(&self.blocks[2], xs),
            Ok(_) => {
                *scratch = POS;
                RunCursor::constant(scratch)
            }
            Err(code) => {
                *scratch = if outside_domain { POS } else { code };
                RunCursor::constant(scratch)
            }
        }
    }

    #[inline(always)]
    pub(crate) fn read(&self, code: u32) -> f32 {
        if code >= POS {
            self.spec.background(code == NEG)
        } else {
            self.values[code as usize]
        }
    }

    /// Calls `f(voxel, value index, star)` for every stored voxel in [`Coord`] order, with
    /// `star` = φ at the voxel and at its −x, +x, −y, +y, −z, +z neighbours: the 7-point
    /// stencil of the upwind and curvature schemes, read with one run cursor per
    /// neighbouring column, O(1) amortised per voxel (Sec. 5.3).
    pub fn for_each_star(&self, mut f: impl FnMut(Coord, usize, [f32; 7])) {
        let mut scratch = [0u32; 4];
        let dx = self.domain.map_or((i32::MIN, i32::MAX), |(lo, hi)| (lo.x, hi.x));
        self.for_each_column(|z, y, xs| {
            let [s0, s1, s2, s3] = &mut scratch;
            let mut n = [
                self.column_cursor(z, y - 1, s0),
                self.column_cursor(z, y + 1, s1),
                self.column_cursor(z - 1, y, s2),
                self.column_cursor(z + 1, y, s3),
            ];
            let mut left = RunCursor::new(&self.blocks[2], xs);
            let mut right = left;
            for_each_element(&self.blocks[2], xs, |x, i| {
                let side = |c: &mut RunCursor, q: i32| {
                    if q < dx.0 || q > dx.1 {
                        self.spec.background(false)
                    } else {
                        self.read(c.at(q))
                    }
                };
                let star = [
                    self.values[i as usize],
                    side(&mut left, x - 1),
                    side(&mut right, x + 1),
                    side(&mut n[0], x),
                    side(&mut n[1], x),
                    side(&mut n[2], x),
                    side(&mut n[3], x),
                ];
                f(Coord::new(x, y, z), i as usize, star);
            });
        });
    }

    /// Where voxel `c` lies: its column and run, for [`HrleGrid::neighbour`].
    pub fn locate(&self, c: Coord) -> Location {
        let inside_domain = self.domain.is_none_or(|(lo, hi)| in_box(c, lo, hi));
        match self.column(c.z, c.y) {
            Ok(xs) if inside_domain => {
                let (_, breaks) = self.blocks[2].segment(xs);
                let run = breaks.partition_point(|&b| b <= c.x);
                Location { coord: c, column: Ok(xs), run }
            }
            Ok(_) => Location { coord: c, column: Err(POS), run: 0 },
            Err(code) => {
                Location { coord: c, column: Err(if inside_domain { code } else { POS }), run: 0 }
            }
        }
    }

    /// φ at a located voxel.
    pub fn value_at(&self, loc: &Location) -> f32 {
        match loc.column {
            Err(code) => self.read(code),
            Ok(xs) => {
                let (codes, breaks) = self.blocks[2].segment(xs);
                let code = codes[loc.run];
                self.read(if code >= POS {
                    code
                } else {
                    code + (loc.coord.x - breaks[loc.run - 1]) as u32
                })
            }
        }
    }

    /// The neighbour of a located voxel one step along `axis` (0 = x, 1 = y, 2 = z) in
    /// direction `step` (±1): O(1) along x, one segment search along y and z (Sec. 5.2).
    pub fn neighbour(&self, loc: &Location, axis: usize, step: i32) -> Location {
        debug_assert!(step == 1 || step == -1);
        let c = loc.coord;
        match (axis, loc.column) {
            (0, Ok(xs)) => {
                let x = c.x + step;
                let nc = Coord::new(x, c.y, c.z);
                if self.domain.is_some_and(|(lo, hi)| !in_box(nc, lo, hi)) {
                    return Location { coord: nc, column: Err(POS), run: 0 };
                }
                let (_, breaks) = self.blocks[2].segment(xs);
                let mut run = loc.run;
                if step > 0 && run < breaks.len() && breaks[run] <= x {
                    run += 1;
                } else if step < 0 && run > 0 && breaks[run - 1] > x {
                    run -= 1;
                }
                Location { coord: nc, column: Ok(xs), run }
            }
            (0, Err(_)) => self.locate(Coord::new(c.x + step, c.y, c.z)),
            (1, _) => self.locate(Coord::new(c.x, c.y + step, c.z)),
            _ => self.locate(Coord::new(c.x, c.y, c.z + step)),
        }
    }
}

/// A voxel found by [`HrleGrid::locate`]: its column's x-segment (or undefined code) and
/// its run, so that x-neighbours are found in O(1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    /// The voxel.
    pub coord: Coord,
    column: Result<usize, u32>,
    run: usize,
}

/// Random access with the last column cached: lookups along one x-line search only that
/// column's runs (Sec. 5.1 restricted to the bottom block).
pub struct HrleAccessor<'a> {
    grid: &'a HrleGrid,
    key: Option<(i32, i32)>,
    column: Result<usize, u32>,
}

impl<'a> HrleAccessor<'a> {
    /// An empty cache over `grid`.
    pub fn new(grid: &'a HrleGrid) -> Self {
        HrleAccessor { grid, key: None, column: Err(POS) }
    }
}

impl Accessor for HrleAccessor<'_> {
    #[inline]
    fn value(&mut self, c: Coord) -> f32 {
        let g = self.grid;
        if let Some((lo, hi)) = g.domain
            && !in_box(c, lo, hi)
        {
            return g.spec.background(false);
        }
        if self.key != Some((c.z, c.y)) {
            self.key = Some((c.z, c.y));
            self.column = g.column(c.z, c.y);
        }
        match self.column {
            Err(code) => g.read(code),
            Ok(xs) => g.read(g.blocks[2].lookup(xs, c.x)),
        }
    }
}
