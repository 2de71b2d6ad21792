//! The hierarchical run-length encoded (H-RLE) level set (Houston et al. 2006, Sec. 4–5):
//! a narrow band stored as one RLE block per axis over a single array of defined values, with
//! explicit *negative* and *positive* runs, so that it can also hold **unenclosed** level sets
//! (Sec. 3, Fig. 9) that the DT-Grid and the tile list cannot.
//!
//! # Layout (Sec. 4.1–4.2)
//! With our coordinate order ([`Coord`]: z first, x fastest) the top block encodes z, the
//! middle block y and the bottom block x:
//!
//! | block | segments | a defined element points at |
//! |---|---|---|
//! | z | one | the y-segment of that z plane |
//! | y | one per stored z plane | the x-segment of that (z, y) column |
//! | x | one per stored column | the value of that voxel |
//!
//! A segment is a scan line through all of ℤ, cut into runs. Run `k` of a segment has a
//! *run code* (`codes`) and, for `k > 0`, a *run break* (`breaks`): the coordinate where
//! it starts. The first run starts at −∞ and the last one ends at +∞, so the first and the
//! last run of every segment are undefined ([`NEG`] or [`POS`]); this replaces the
//! paper's per-block `[min, max + 1]` extents (the bounding box is kept beside the
//! blocks) and makes every coordinate's run well defined. A defined run's code is the
//! index of its first element's target; the element at `start + i` points at `code + i`.
//! Segment `s` of a block holds runs `seg[s] .. seg[s + 1]` and, since each segment has
//! one break fewer than runs, breaks `seg[s] − s .. seg[s + 1] − s − 1`: no array of
//! break offsets is needed.
//!
//! The builders assign targets in [`Coord`] order, so the values array is the band in
//! [`Coord`] order and a defined run's targets are consecutive.
//!
//! # Outside the band
//! A voxel in a [`NEG`] run reads `−γ`, in a [`POS`] run `+γ`. The codes are stored, not
//! inferred from neighbouring values (the DT-Grid's sign rule): the same band can be
//! closed or, after [`HrleGrid::clip`], unenclosed.
//!
//! # Costs (Sec. 5)
//! [`HrleGrid::value`]: one binary search per block over one segment's runs (Sec. 5.1);
//! [`HrleGrid::for_each_defined`]: O(1) per voxel (Sec. 5.3); [`HrleGrid::for_each_star`]:
//! the 7-point stencil with one run cursor per neighbouring column, O(1) amortised per
//! voxel (Sec. 5.3, last paragraph); [`HrleGrid::neighbour`]: O(1) along x, a segment
//! search along y and z (Sec. 5.2); [`HrleGrid::dilate`]: O(D) for a fixed width (Sec.
//! 5.4). Memory: per stored value 4 bytes, per run 8 bytes (code and break), per segment
//! 4 bytes — within about 10 % of the DT-Grid for a closed band (see
//! `docs/benchmarks.md`), less for an unenclosed one.
//!
//! ```
//! use sparse_levelset::{storage::convert, storage::hrle::HrleGrid, storage::shapes::Shape, Coord, GridSpec, LevelSet};
//!
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let h = HrleGrid::from_level_set(&tiles).unwrap();
//! assert_eq!(h.checksum(), tiles.checksum());
//! assert_eq!(h.value(Coord::new(0, 0, 0)), -3.0);
//! // Clipped to x ≤ 0 the sphere is an open hemisphere: nothing is added on the cut.
//! let open = h.clip(Coord::new(-20, -20, -20), Coord::new(0, 20, 20)).unwrap();
//! assert!(open.band_voxels() < h.band_voxels() / 2 + 2000);
//! assert_eq!(open.value(Coord::new(1, 0, 0)), 3.0); // beyond the cut: outside
//! ```

mod build;
mod dilate;
mod fields;
mod stencil;
#[cfg(test)]
mod tests;

pub use build::{Builder, SignOracle};
pub use fields::{Field, FieldData};
pub use stencil::{HrleAccessor, Location};

use crate::coord::Coord;
use crate::grid::{vec_bytes, GridError, GridSpec, MemoryReport};
use crate::storage::levelset::{Accessor, LevelSet};

/// Run code of an undefined run inside the interface (φ ≤ −γ).
pub const NEG: u32 = u32::MAX;
/// Run code of an undefined run outside the interface (φ ≥ γ).
pub const POS: u32 = u32::MAX - 1;
/// Most values an [`HrleGrid`] holds (codes below [`POS`] are indices).
pub const MAX_VALUES: usize = (u32::MAX - 2) as usize;

/// Coordinates an H-RLE level set can hold on every axis: a run break must exist one past
/// the last defined coordinate and one before the first, so the extremes of `i32` are
/// excluded.
pub const COORD_RANGE: std::ops::RangeInclusive<i32> = (i32::MIN + 1)..=(i32::MAX - 1);

/// One RLE block (Sec. 4.1): the runs of its segments. See the [module docs](self).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Block {
    /// `seg[s]` is the first run of segment `s`; one more entry than segments.
    pub seg: Vec<u32>,
    /// Run codes: [`NEG`], [`POS`] or the target of the run's first element.
    pub codes: Vec<u32>,
    /// Start coordinate of every run but the first of its segment.
    pub breaks: Vec<i32>,
}

impl Block {
    fn new() -> Self {
        Block { seg: vec![0], codes: Vec::new(), breaks: Vec::new() }
    }

    /// Number of segments.
    #[inline]
    pub fn segments(&self) -> usize {
        self.seg.len() - 1
    }

    /// The codes and breaks of segment `s`: `breaks.len() == codes.len() - 1`.
    #[inline(always)]
    pub fn segment(&self, s: usize) -> (&[u32], &[i32]) {
        let (a, b) = (self.seg[s] as usize, self.seg[s + 1] as usize);
        (&self.codes[a..b], &self.breaks[a - s..b - s - 1])
    }

    /// The run of segment `s` holding coordinate `q`, as (code, start of the run; start is
    /// `i32::MIN` for the first run).
    #[inline(always)]
    pub fn find(&self, s: usize, q: i32) -> (u32, i32) {
        let (codes, breaks) = self.segment(s);
        let r = breaks.partition_point(|&b| b <= q);
        (codes[r], if r == 0 { i32::MIN } else { breaks[r - 1] })
    }

    /// Code at `q` in segment `s`: an undefined code, or the target of the element at `q`.
    #[inline(always)]
    pub fn lookup(&self, s: usize, q: i32) -> u32 {
        let (code, start) = self.find(s, q);
        if code >= POS {
            code
        } else {
            code + (q - start) as u32
        }
    }

    fn bytes(&self) -> (usize, usize) {
        let mut used = 0;
        let mut slack = 0;
        for (u, s) in [vec_bytes(&self.seg), vec_bytes(&self.codes), vec_bytes(&self.breaks)] {
            used += u;
            slack += s;
        }
        (used, slack)
    }
}

/// A 3D hierarchical RLE level set with optional augmented fields sharing its encoding
/// (Sec. 4, Fig. 4). See the [module docs](self) for the layout.
///
/// # Invariants
/// * the z block has one segment; the y block one segment per defined z element; the x
///   block one segment per defined y element; `values` one entry per defined x element;
/// * every segment has at least one run, its first and last runs are undefined, its
///   breaks strictly increase, and two neighbouring runs never carry the same undefined
///   code nor form one defined run (a defined run followed directly by a defined run
///   whose targets continue it);
/// * defined targets are assigned in order: the first defined run of the block points at
///   0 and each further one continues where the last ended;
/// * breaks lie in [`COORD_RANGE`] plus one past its end; values are not NaN and lie in
///   `[−γ, γ]`; every field has one entry per value.
///
/// [`HrleGrid::check_invariants`] verifies all of it in O(size); it runs under
/// `debug_assert!` after every construction and when a file is read.
#[derive(Clone, Debug, PartialEq)]
pub struct HrleGrid {
    pub(crate) spec: GridSpec,
    /// z, y, x blocks.
    pub(crate) blocks: [Block; 3],
    pub(crate) values: Vec<f32>,
    pub(crate) fields: Vec<Field>,
    /// Stored values with |φ| < γ.
    pub(crate) band: usize,
    /// Inclusive box of the stored voxels.
    pub(crate) bbox: Option<(Coord, Coord)>,
    /// Inclusive box outside which every voxel reads `+γ` (`None`: all of ℤ³).
    pub(crate) domain: Option<(Coord, Coord)>,
}

impl HrleGrid {
    /// An empty level set: everything outside (`+γ`).
    pub fn new(spec: GridSpec) -> Self {
        let mut blocks = [Block::new(), Block::new(), Block::new()];
        blocks[0].codes.push(POS);
        blocks[0].seg.push(1);
        HrleGrid {
            spec,
            blocks,
            values: Vec::new(),
            fields: Vec::new(),
            band: 0,
            bbox: None,
            domain: None,
        }
    }

    /// Voxel size, origin and half-width.
    pub fn spec(&self) -> GridSpec {
        self.spec
    }

    /// Stored (defined) values, in [`Coord`] order; a dilation stores `±γ` values too.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Number of stored (defined) voxels.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// No voxel stored.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Stored voxels with |φ| < γ.
    pub fn band_voxels(&self) -> usize {
        self.band
    }

    /// Runs per block (z, y, x).
    pub fn runs(&self) -> [usize; 3] {
        [0, 1, 2].map(|b| self.blocks[b].codes.len())
    }

    /// Segments per block (z, y, x).
    pub fn segments(&self) -> [usize; 3] {
        [0, 1, 2].map(|b| self.blocks[b].segments())
    }

    /// Inclusive box of the stored voxels, `None` when empty.
    pub fn bounding_box(&self) -> Option<(Coord, Coord)> {
        self.bbox
    }

    /// The domain: the inclusive box outside which every voxel reads `+γ`, `None` for a
    /// level set that is not clipped.
    pub fn domain(&self) -> Option<(Coord, Coord)> {
        self.domain
    }

    /// Where `c` is stored: `Ok(value index)`, or `Err(inside)` for an undefined run
    /// or a voxel outside the domain (Sec. 5.1: one binary search per block).
    #[inline]
    pub fn locate_index(&self, c: Coord) -> Result<usize, bool> {
        if let Some((lo, hi)) = self.domain
            && !in_box(c, lo, hi)
        {
            return Err(false);
        }
        let mut s = 0usize;
        for (b, q) in [(0, c.z), (1, c.y), (2, c.x)] {
            let code = self.blocks[b].lookup(s, q);
            if code >= POS {
                return Err(code == NEG);
            }
            s = code as usize;
        }
        Ok(s)
    }

    /// φ at any voxel: the stored value, or `±γ` by the run code.
    #[inline]
    pub fn value(&self, c: Coord) -> f32 {
        match self.locate_index(c) {
            Ok(i) => self.values[i],
            Err(inside) => self.spec.background(inside),
        }
    }

    /// Calls `f(coord, value index)` for every stored voxel in [`Coord`] order (Sec. 5.3).
    pub fn for_each_defined(&self, mut f: impl FnMut(Coord, usize)) {
        let [bz, by, bx] = &self.blocks;
        for_each_element(bz, 0, |z, ys| {
            for_each_element(by, ys as usize, |y, xs| {
                for_each_element(bx, xs as usize, |x, i| f(Coord::new(x, y, z), i as usize))
            })
        });
    }

    /// Calls `f(z, y, x-segment)` for every stored column in [`Coord`] order.
    pub(crate) fn for_each_column(&self, mut f: impl FnMut(i32, i32, usize)) {
        let [bz, by, _] = &self.blocks;
        for_each_element(bz, 0, |z, ys| {
            for_each_element(by, ys as usize, |y, xs| f(z, y, xs as usize))
        });
    }

    /// The x-segment of column (z, y), or the column's undefined code.
    #[inline]
    pub(crate) fn column(&self, z: i32, y: i32) -> Result<usize, u32> {
        let ys = self.blocks[0].lookup(0, z);
        if ys >= POS {
            return Err(ys);
        }
        let xs = self.blocks[1].lookup(ys as usize, y);
        if xs >= POS {
            Err(xs)
        } else {
            Ok(xs as usize)
        }
    }

    /// Bytes used: values (and fields), run codes/breaks/segment starts as indices.
    pub fn memory(&self) -> MemoryReport {
        let (mut v, mut slack) = vec_bytes(&self.values);
        for f in &self.fields {
            let (u, s) = f.bytes();
            v += u;
            slack += s;
        }
        let mut indices = 0;
        for b in &self.blocks {
            let (u, s) = b.bytes();
            indices += u;
            slack += s;
        }
        MemoryReport { values: v, indices, flags: 0, slack }
    }

    /// Releases unused capacity.
    pub fn shrink_to_fit(&mut self) {
        for b in &mut self.blocks {
            b.seg.shrink_to_fit();
            b.codes.shrink_to_fit();
            b.breaks.shrink_to_fit();
        }
        self.values.shrink_to_fit();
        for f in &mut self.fields {
            f.shrink_to_fit();
        }
    }

    /// A grid from its parts (a decoded file), checked: every invariant must hold.
    pub(crate) fn from_parts(
        spec: GridSpec,
        blocks: [Block; 3],
        values: Vec<f32>,
        domain: Option<(Coord, Coord)>,
    ) -> Result<HrleGrid, String> {
        let mut g =
            HrleGrid { spec, blocks, values, fields: Vec::new(), band: 0, bbox: None, domain };
        g.check_structure()?;
        let gamma = spec.gamma();
        g.band = g.values.iter().filter(|v| v.abs() < gamma).count();
        let mut bbox = None;
        g.for_each_defined(|c, _| bbox = Some(grow_box(bbox, c)));
        g.bbox = bbox;
        g.check_invariants()?;
        Ok(g)
    }

    /// Checks every invariant of [`HrleGrid`] (O(size)); the message says which failed.
    pub fn check_invariants(&self) -> Result<(), String> {
        self.check_structure()?;
        let gamma = self.spec.gamma();
        let mut band = 0;
        for (i, v) in self.values.iter().enumerate() {
            if v.is_nan() || v.abs() > gamma {
                return Err(format!("value {i} = {v} is NaN or outside [-γ, γ] (γ = {gamma})"));
            }
            band += (v.abs() < gamma) as usize;
        }
        if band != self.band {
            return Err(format!("band count {} but {band} values with |φ| < γ", self.band));
        }
        for f in &self.fields {
            if f.len() != self.values.len() {
                return Err(format!(
                    "field {:?} has {} entries for {} values",
                    f.name,
                    f.len(),
                    self.values.len()
                ));
            }
        }
        let mut bbox: Option<(Coord, Coord)> = None;
        self.for_each_defined(|c, _| bbox = Some(grow_box(bbox, c)));
        if bbox != self.bbox {
            return Err(format!("bounding box {:?}, stored voxels span {bbox:?}", self.bbox));
        }
        if let Some((lo, hi)) = self.domain {
            if lo.x > hi.x || lo.y > hi.y || lo.z > hi.z {
                return Err(format!("empty domain {lo}..{hi}"));
            }
            if let Some((a, b)) = bbox
                && (!in_box(a, lo, hi) || !in_box(b, lo, hi))
            {
                return Err(format!("stored voxels {a}..{b} leave the domain {lo}..{hi}"));
            }
        }
        Ok(())
    }

    /// The block structure: segment counts, run order and targets, value count.
    fn check_structure(&self) -> Result<(), String> {
        let mut targets = 1u64; // the z block has one segment above it
        for (b, block) in self.blocks.iter().enumerate() {
            let axis = ["z", "y", "x"][b];
            if block.seg.first() != Some(&0) {
                return Err(format!("{axis} block: segment starts must begin at 0"));
            }
            if block.segments() as u64 != targets {
                return Err(format!(
                    "{axis} block: {} segments for {targets} defined elements above",
                    block.segments()
                ));
            }
            if *block.seg.last().unwrap() as usize != block.codes.len() {
                return Err(format!("{axis} block: segment starts do not end at the run count"));
            }
            if block.breaks.len() + block.segments() != block.codes.len() {
                return Err(format!("{axis} block: breaks and runs disagree"));
            }
            let mut next = 0u64;
            for s in 0..block.segments() {
                if block.seg[s] >= block.seg[s + 1] {
                    return Err(format!("{axis} block: segment {s} has no run"));
                }
                let (codes, breaks) = block.segment(s);
                if codes[0] < POS || codes[codes.len() - 1] < POS {
                    return Err(format!(
                        "{axis} block: segment {s} starts or ends with a defined run"
                    ));
                }
                for r in 1..codes.len() {
                    let start = breaks[r - 1];
                    if r >= 2 && breaks[r - 2] >= start {
                        return Err(format!(
                            "{axis} block: segment {s}: run breaks not increasing"
                        ));
                    }
                    if start == i32::MIN {
                        return Err(format!("{axis} block: segment {s}: a run starts at i32::MIN"));
                    }
                    let (prev, code) = (codes[r - 1], codes[r]);
                    if prev >= POS && prev == code {
                        return Err(format!(
                            "{axis} block: segment {s}: two equal undefined runs meet"
                        ));
                    }
                    if code < POS {
                        if code as u64 != next {
                            return Err(format!(
                                "{axis} block: segment {s}: defined run points at {code}, expected {next}"
                            ));
                        }
                        if prev < POS {
                            return Err(format!(
                                "{axis} block: segment {s}: two defined runs meet"
                            ));
                        }
                        let len = breaks[r] as i64 - start as i64;
                        if len <= 0 {
                            return Err(format!(
                                "{axis} block: segment {s}: run breaks not increasing"
                            ));
                        }
                        next += len as u64;
                    }
                }
            }
            targets = next;
        }
        if targets != self.values.len() as u64 {
            return Err(format!("{} values for {targets} defined voxels", self.values.len()));
        }
        Ok(())
    }

    pub(crate) fn debug_check(&self) {
        #[cfg(debug_assertions)]
        if let Err(e) = self.check_invariants() {
            panic!("H-RLE invariant broken: {e}");
        }
    }

    /// The H-RLE level set holding the same band as `ls`, with the same value at every
    /// voxel for a closed band of a distance field: undefined runs take the sign `ls`
    /// reads there ([`SignOracle`] for a level set). Fails on a voxel outside
    /// [`COORD_RANGE`] or more than [`MAX_VALUES`] band voxels.
    pub fn from_level_set<G: LevelSet + ?Sized>(ls: &G) -> Result<Self, GridError> {
        if ls.band_voxels() > MAX_VALUES {
            return Err(GridError::InvalidParameter(format!(
                "{} band voxels exceed the H-RLE limit of {MAX_VALUES}",
                ls.band_voxels()
            )));
        }
        let oracle = build::level_set_signs(ls);
        let mut b = Builder::with_capacity(ls.spec(), oracle, ls.band_voxels());
        let mut err = Ok(());
        ls.for_each_band_voxel(&mut |c, v| {
            if err.is_ok() {
                err = b.push(c, v);
            }
        });
        err?;
        Ok(b.finish())
    }
}

/// Calls `f(coordinate, target)` for every defined element of segment `s` of `block`.
#[inline(always)]
pub(crate) fn for_each_element(block: &Block, s: usize, mut f: impl FnMut(i32, u32)) {
    let (codes, breaks) = block.segment(s);
    for r in 1..codes.len().saturating_sub(1) {
        let code = codes[r];
        if code < POS {
            let (a, b) = (breaks[r - 1], breaks[r]);
            for (k, q) in (a..b).enumerate() {
                f(q, code + k as u32);
            }
        }
    }
}

#[inline]
pub(crate) fn in_box(c: Coord, lo: Coord, hi: Coord) -> bool {
    (lo.x..=hi.x).contains(&c.x) && (lo.y..=hi.y).contains(&c.y) && (lo.z..=hi.z).contains(&c.z)
}

pub(crate) fn grow_box(b: Option<(Coord, Coord)>, c: Coord) -> (Coord, Coord) {
    match b {
        None => (c, c),
        Some((lo, hi)) => (
            Coord::new(lo.x.min(c.x), lo.y.min(c.y), lo.z.min(c.z)),
            Coord::new(hi.x.max(c.x), hi.y.max(c.y), hi.z.max(c.z)),
        ),
    }
}

impl HrleGrid {
    /// The H-RLE grid behind `ls`, when it is one ([`LevelSet::storage`]).
    pub fn of<L: LevelSet + ?Sized>(ls: &L) -> Option<&HrleGrid> {
        ls.storage()?.downcast_ref()
    }
}

impl LevelSet for HrleGrid {
    fn spec(&self) -> GridSpec {
        self.spec
    }
    fn value(&self, voxel: Coord) -> f32 {
        HrleGrid::value(self, voxel)
    }
    fn accessor(&self) -> impl Accessor + '_ {
        HrleAccessor::new(self)
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.spec.gamma();
        self.for_each_defined(|c, i| {
            let v = self.values[i];
            if v.abs() < g {
                f(c, v)
            }
        });
    }
    fn band_voxels(&self) -> usize {
        self.band
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        self.bbox
    }
    fn memory(&self) -> MemoryReport {
        HrleGrid::memory(self)
    }
    fn storage(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }
}
