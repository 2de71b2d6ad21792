//! Sequential access (paper Sec. 3.2, Appendix B): cursors that step through the
//! constituents in O(1) per point.

use super::access::Locator;
use super::DtGrid;
use crate::coord::Coord;

/// A cursor over the (z, y) p-columns of a grid: the 2D part of the Appendix B increment,
/// with the 1D part nested inside it. Fields are the per-level locator (`c*` are `ncoord`
/// indices of the current component, `i*` value indices) plus the current component end,
/// cached so the common step is one comparison.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ColCursor {
    pub c1: usize,
    pub i1: usize,
    pub z: i32,
    pub z_end: i32,
    pub c2: usize,
    pub i2: usize,
    pub y: i32,
    pub y_end: i32,
}

impl ColCursor {
    /// At the first p-column, `None` for an empty grid.
    #[inline]
    pub fn first(g: &DtGrid) -> Option<ColCursor> {
        let (nc1, nc2) = (&g.l1.ncoord, &g.l2.ncoord);
        if nc2.is_empty() {
            return None;
        }
        Some(ColCursor {
            c1: 0,
            i1: 0,
            z: nc1[0],
            z_end: nc1[1],
            c2: 0,
            i2: 0,
            y: nc2[0],
            y_end: nc2[1],
        })
    }

    /// Steps to the next p-column; `false` (and the cursor is spent) after the last one.
    #[inline]
    pub fn advance(&mut self, g: &DtGrid) -> bool {
        self.i2 += 1;
        if self.i2 == g.l2.points() {
            return false;
        }
        if self.y < self.y_end {
            self.y += 1;
            return true;
        }
        let nc2 = &g.l2.ncoord;
        self.c2 += 2;
        self.y = nc2[self.c2];
        self.y_end = nc2[self.c2 + 1];
        // Leaving the component may also leave the z column: the next z column starts
        // exactly at this component (Appendix B, second test).
        if g.l1.value[self.i1 + 1].ic as usize == self.c2 {
            self.i1 += 1;
            if self.z < self.z_end {
                self.z += 1;
            } else {
                let nc1 = &g.l1.ncoord;
                self.c1 += 2;
                self.z = nc1[self.c1];
                self.z_end = nc1[self.c1 + 1];
            }
        }
        true
    }
}

/// How a [`Cursor`] moved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    /// x + 1 in the same component.
    SameComponent,
    /// To the next component of the same p-column.
    SameColumn,
    /// To the first point of the next p-column.
    NextColumn,
    /// Past the last point.
    End,
}

/// A cursor over the stored voxels: the full 3D Appendix B increment.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cursor {
    pub col: ColCursor,
    pub c3: usize,
    pub iv: usize,
    pub x: i32,
    pub x_end: i32,
}

impl Cursor {
    #[inline]
    pub fn first(g: &DtGrid) -> Option<Cursor> {
        let col = ColCursor::first(g)?;
        let nc3 = &g.l3.ncoord;
        Some(Cursor { col, c3: 0, iv: 0, x: nc3[0], x_end: nc3[1] })
    }

    #[inline(always)]
    pub fn coord(&self) -> Coord {
        Coord::new(self.x, self.col.y, self.col.z)
    }

    #[inline]
    pub fn locator(&self) -> Locator {
        Locator {
            iv1: self.col.i1 as u32,
            ic1: self.col.c1 as u32,
            iv2: self.col.i2 as u32,
            ic2: self.col.c2 as u32,
            iv3: self.iv as u32,
            ic3: self.c3 as u32,
            coord: self.coord(),
        }
    }

    /// Steps to the next stored voxel (Appendix B).
    #[inline(always)]
    pub fn advance(&mut self, g: &DtGrid) -> Step {
        self.iv += 1;
        if self.iv == g.l3.value.len() {
            return Step::End;
        }
        if self.x < self.x_end {
            self.x += 1;
            return Step::SameComponent;
        }
        let nc3 = &g.l3.ncoord;
        self.c3 += 2;
        self.x = nc3[self.c3];
        self.x_end = nc3[self.c3 + 1];
        if g.l2.value[self.col.i2 + 1].ic as usize != self.c3 {
            return Step::SameColumn;
        }
        let more = self.col.advance(g);
        debug_assert!(more);
        Step::NextColumn
    }
}

/// Iterator over the stored points in lexicographic [`Coord`] order, yielding
/// `(coordinate, value)`; O(1) per point (Appendix B). The `k`-th item has value index
/// `k`, so `.enumerate()` gives the index into [`DtGrid::values`].
#[derive(Clone, Debug)]
pub struct Iter<'a> {
    grid: &'a DtGrid,
    cur: Option<Cursor>,
    left: usize,
}

impl<'a> Iter<'a> {
    /// The locator of the point the next call to `next` yields, `None` at the end.
    pub fn peek_locator(&self) -> Option<Locator> {
        self.cur.map(|c| c.locator())
    }
}

impl DtGrid {
    /// Iterates over the stored points in order (see [`Iter`]).
    pub fn iter(&self) -> Iter<'_> {
        Iter { grid: self, cur: Cursor::first(self), left: self.len() }
    }
}

impl<'a> IntoIterator for &'a DtGrid {
    type Item = (Coord, f32);
    type IntoIter = Iter<'a>;
    fn into_iter(self) -> Iter<'a> {
        self.iter()
    }
}

impl Iterator for Iter<'_> {
    type Item = (Coord, f32);

    #[inline]
    fn next(&mut self) -> Option<(Coord, f32)> {
        let cur = self.cur.as_mut()?;
        let item = (cur.coord(), self.grid.l3.value[cur.iv]);
        self.left -= 1;
        if cur.advance(self.grid) == Step::End {
            self.cur = None;
        }
        Some(item)
    }

    #[inline]
    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.left, Some(self.left))
    }

    /// Nested loops over components instead of one `next` per point.
    fn fold<B, F>(self, init: B, mut f: F) -> B
    where
        F: FnMut(B, (Coord, f32)) -> B,
    {
        let Some(cur) = self.cur else { return init };
        let g = self.grid;
        let mut acc = init;
        let mut col = cur.col;
        let (nc3, vals) = (&g.l3.ncoord, &g.l3.value);
        // Finish the current column from the cursor's position, then whole columns.
        let mut c3 = cur.c3;
        let mut x0 = cur.x;
        let mut iv = cur.iv;
        loop {
            let hi = g.l2.value[col.i2 + 1].ic as usize;
            while c3 < hi {
                for x in x0..=nc3[c3 + 1] {
                    acc = f(acc, (Coord::new(x, col.y, col.z), vals[iv]));
                    iv += 1;
                }
                c3 += 2;
                if c3 < hi {
                    x0 = nc3[c3];
                }
            }
            if !col.advance(g) {
                return acc;
            }
            x0 = nc3[c3];
        }
    }
}

impl ExactSizeIterator for Iter<'_> {}
impl std::iter::FusedIterator for Iter<'_> {}
