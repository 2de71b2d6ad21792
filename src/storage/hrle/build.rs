//! Building an H-RLE level set in one pass over voxels in [`Coord`] order: every block is
//! written as a stream of runs (the RLE encoding of Sec. 4, applied level by level), and
//! the codes of the undefined runs come from a [`SignOracle`].

use super::{grow_box, Block, Field, HrleGrid, COORD_RANGE, NEG, POS};
use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::storage::levelset::{Accessor, LevelSet};

/// Where the undefined runs of a level set being built are inside (`true`, [`NEG`]) or
/// outside ([`POS`]). Each query names one voxel, column or plane of a gap that holds no
/// stored voxel; the whole gap takes its answer.
pub trait SignOracle {
    /// Sign of the gap of an x-column that starts (or, before the column's first stored
    /// voxel, ends) at `c`.
    fn inside(&mut self, c: Coord) -> bool;
    /// Sign of column (z, y), which holds no stored voxel.
    fn column_inside(&mut self, z: i32, y: i32) -> bool;
    /// Sign of plane z, which holds no stored voxel.
    fn plane_inside(&mut self, z: i32) -> bool;
}

/// The signs a level set reads: at the gap's voxel, and for a column or plane without
/// stored voxels at one representative voxel of it (inside the domain when the source is
/// clipped). For the band of a distance field a column or plane without band voxels
/// holds no crossing, so one voxel gives its sign.
pub(crate) struct LevelSetSigns<A> {
    acc: A,
    rep: Coord,
}

/// The signs `ls` reads, columns and planes at the corner of its bounding box.
pub(crate) fn level_set_signs<G: LevelSet + ?Sized>(ls: &G) -> LevelSetSigns<impl Accessor + '_> {
    let rep = ls.bounding_box().map(|b| b.0).unwrap_or_default();
    LevelSetSigns { acc: ls.accessor(), rep }
}

impl<'a> LevelSetSigns<super::HrleAccessor<'a>> {
    /// The signs of an H-RLE grid, read at `rep` for columns and planes.
    pub fn of_hrle(g: &'a HrleGrid, rep: Coord) -> Self {
        LevelSetSigns { acc: super::HrleAccessor::new(g), rep }
    }
}

impl<A: Accessor> SignOracle for LevelSetSigns<A> {
    fn inside(&mut self, c: Coord) -> bool {
        self.acc.value(c) < 0.0
    }
    fn column_inside(&mut self, z: i32, y: i32) -> bool {
        self.acc.value(Coord::new(self.rep.x, y, z)) < 0.0
    }
    fn plane_inside(&mut self, z: i32) -> bool {
        self.acc.value(Coord::new(self.rep.x, self.rep.y, z)) < 0.0
    }
}

fn code(inside: bool) -> u32 {
    if inside {
        NEG
    } else {
        POS
    }
}

/// Writes one block as a stream of segments and runs.
#[derive(Default)]
struct Writer {
    block: Block,
    /// Exclusive end of the last run when it is defined.
    defined_end: Option<i32>,
    /// Target of the next defined element.
    next: u32,
}

impl Writer {
    fn new() -> Self {
        Writer { block: Block::new(), defined_end: None, next: 0 }
    }

    /// Opens a segment whose first run (from −∞) has `first`.
    fn begin(&mut self, first: u32) {
        self.block.codes.push(first);
        self.defined_end = None;
    }

    /// An undefined run from `start` (merged into the previous run when it has the same
    /// code).
    fn undefined(&mut self, start: i32, code: u32) {
        if self.defined_end.is_none() && self.block.codes.last() == Some(&code) {
            return;
        }
        self.block.codes.push(code);
        self.block.breaks.push(start);
        self.defined_end = None;
    }

    /// A defined element at `q`, right after the last one or after an undefined run; its
    /// target.
    fn element(&mut self, q: i32) -> u32 {
        let t = self.next;
        self.next += 1;
        if self.defined_end != Some(q) {
            debug_assert!(self.defined_end.is_none(), "a gap without an undefined run");
            self.block.codes.push(t);
            self.block.breaks.push(q);
        }
        self.defined_end = Some(q + 1);
        t
    }

    /// Closes the segment with its last run (to +∞).
    fn end(&mut self, last: u32) {
        match self.defined_end {
            Some(e) => {
                self.block.codes.push(last);
                self.block.breaks.push(e);
            }
            None => {
                if self.block.codes.last() != Some(&last) {
                    // An undefined run cannot change code without a break; a segment
                    // that ends undefined already ends with its last code.
                    debug_assert!(false, "segment ends undefined with another code");
                }
            }
        }
        self.defined_end = None;
        self.block.seg.push(self.block.codes.len() as u32);
    }
}

/// Builds an [`HrleGrid`] from voxels pushed in strictly increasing [`Coord`] order, the
/// undefined runs between them signed by a [`SignOracle`].
///
/// ```
/// use sparse_levelset::{storage::hrle::{Builder, SignOracle}, Coord, GridSpec, LevelSet};
///
/// struct Outside;
/// impl SignOracle for Outside {
///     fn inside(&mut self, _: Coord) -> bool { false }
///     fn column_inside(&mut self, _: i32, _: i32) -> bool { false }
///     fn plane_inside(&mut self, _: i32) -> bool { false }
/// }
/// let mut b = Builder::new(GridSpec::default(), Outside);
/// b.push(Coord::new(0, 0, 0), -0.5).unwrap();
/// b.push(Coord::new(1, 0, 0), 0.5).unwrap();
/// let g = b.finish();
/// assert_eq!((g.value(Coord::new(1, 0, 0)), g.value(Coord::new(2, 0, 0))), (0.5, 3.0));
/// assert_eq!(g.runs(), [3, 3, 3]);
/// ```
pub struct Builder<S> {
    spec: GridSpec,
    gamma: f32,
    oracle: S,
    w: [Writer; 3],
    values: Vec<f32>,
    last: Option<Coord>,
    band: usize,
    bbox: Option<(Coord, Coord)>,
}

impl<S: SignOracle> Builder<S> {
    /// An empty builder.
    pub fn new(spec: GridSpec, oracle: S) -> Self {
        Self::with_capacity(spec, oracle, 0)
    }

    /// An empty builder with room for `n` values.
    pub fn with_capacity(spec: GridSpec, oracle: S, n: usize) -> Self {
        Builder {
            spec,
            gamma: spec.gamma(),
            oracle,
            w: [Writer::new(), Writer::new(), Writer::new()],
            values: Vec::with_capacity(n),
            last: None,
            band: 0,
            bbox: None,
        }
    }

    /// Appends voxel `c` with value `v` (in `[−γ, γ]`); nothing changes on an error.
    pub fn push(&mut self, c: Coord, v: f32) -> Result<(), GridError> {
        if v.is_nan() {
            return Err(GridError::NaN { coord: c });
        }
        if v.abs() > self.gamma {
            return Err(GridError::InvalidParameter(format!(
                "value {v} at {c} lies outside the band [-γ, γ], γ = {}",
                self.gamma
            )));
        }
        if ![c.x, c.y, c.z].iter().all(|q| COORD_RANGE.contains(q)) {
            return Err(GridError::OutOfRange { coord: c });
        }
        if let Some(last) = self.last
            && c.key() <= last.key()
        {
            return Err(GridError::NotSorted { last, coord: c });
        }
        if self.values.len() >= super::MAX_VALUES {
            return Err(GridError::InvalidParameter(format!(
                "more than {} voxels exceed the H-RLE limit",
                super::MAX_VALUES
            )));
        }
        let o = &mut self.oracle;
        let [wz, wy, wx] = &mut self.w;
        match self.last {
            None => {
                wz.begin(code(o.plane_inside(c.z - 1)));
                wz.element(c.z);
                wy.begin(code(o.column_inside(c.z, c.y - 1)));
                wy.element(c.y);
                wx.begin(code(o.inside(Coord::new(c.x - 1, c.y, c.z))));
            }
            Some(l) if l.z == c.z && l.y == c.y => {
                if c.x > l.x + 1 {
                    wx.undefined(l.x + 1, code(o.inside(Coord::new(l.x + 1, l.y, l.z))));
                }
            }
            Some(l) => {
                wx.end(code(o.inside(Coord::new(l.x + 1, l.y, l.z))));
                if l.z == c.z {
                    if c.y > l.y + 1 {
                        wy.undefined(l.y + 1, code(o.column_inside(l.z, l.y + 1)));
                    }
                } else {
                    wy.end(code(o.column_inside(l.z, l.y + 1)));
                    if c.z > l.z + 1 {
                        wz.undefined(l.z + 1, code(o.plane_inside(l.z + 1)));
                    }
                    wz.element(c.z);
                    wy.begin(code(o.column_inside(c.z, c.y - 1)));
                }
                wy.element(c.y);
                wx.begin(code(o.inside(Coord::new(c.x - 1, c.y, c.z))));
            }
        }
        wx.element(c.x);
        self.values.push(v);
        self.band += (v.abs() < self.gamma) as usize;
        self.bbox = Some(grow_box(self.bbox, c));
        self.last = Some(c);
        Ok(())
    }

    /// The level set.
    pub fn finish(self) -> HrleGrid {
        self.finish_with(None, Vec::new())
    }

    pub(crate) fn finish_with(
        mut self,
        domain: Option<(Coord, Coord)>,
        fields: Vec<Field>,
    ) -> HrleGrid {
        let o = &mut self.oracle;
        let [wz, wy, wx] = &mut self.w;
        match self.last {
            Some(l) => {
                wx.end(code(o.inside(Coord::new(l.x + 1, l.y, l.z))));
                wy.end(code(o.column_inside(l.z, l.y + 1)));
                wz.end(code(o.plane_inside(l.z + 1)));
            }
            None => {
                let inside = o.plane_inside(0);
                wz.begin(code(inside));
                wz.end(code(inside));
            }
        }
        let [wz, wy, wx] = self.w;
        let g = HrleGrid {
            spec: self.spec,
            blocks: [wz.block, wy.block, wx.block],
            values: self.values,
            fields,
            band: self.band,
            bbox: self.bbox,
            domain,
        };
        g.debug_check();
        g
    }
}
