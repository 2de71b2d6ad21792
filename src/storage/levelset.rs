//! The one read interface of a narrow-band level set, which every storage implements and
//! every tool takes.
//!
//! A [`LevelSet`] answers what a tool needs to read a band, whatever stores it: its
//! [`GridSpec`], the value at any voxel (stored, or ±γ outside the band), a cached
//! [`Accessor`] for runs of nearby lookups (OpenVDB's `ValueAccessor`), the band voxels in
//! [`Coord`] order, a bounding box and the memory used. The Sorted Tile List
//! ([`TileGrid`]), the DT-Grid ([`DtGrid`]), the H-RLE level set
//! ([`crate::storage::hrle::HrleGrid`]), a CSG view ([`crate::tools::csg::Csg`]) and a running
//! simulation's current state ([`crate::evolve::Simulation`]) implement it; the tools take
//! any of them through one function each with one options struct:
//!
//! | tool | function |
//! |---|---|
//! | ray-traced image | [`crate::tools::render::render`] |
//! | triangle mesh | [`crate::tools::mesh::isosurface`] |
//! | reinitialisation by fast marching | [`crate::tools::fmm::reinitialize`] |
//! | dense field, `.npy` | [`crate::storage::convert::to_dense`], [`crate::storage::convert::export_npy`] |
//! | band voxels, volume, area | [`crate::tools::measure::measure`] |
//! | conversion | [`crate::storage::convert::tiles_from`], [`crate::storage::convert::dtgrid_from`], [`crate::storage::hrle::HrleGrid::from_level_set`] |
//! | `.sls` file | [`crate::io::sls::save`] (and [`crate::io::sls::load`] into an H-RLE) |
//!
//! Progress and cancellation are a field of the options ([`crate::progress::Progress`]),
//! not a second family of functions. Inputs that are not a level set have their own
//! functions: dense arrays ([`crate::tools::fmm::distance_dense`], [`crate::tools::mesh::isosurface_dense`])
//! and seed voxels ([`crate::tools::fmm::arrival_times`]).
//!
//! ```
//! use sparse_levelset::{storage::convert, grid::GridSpec, storage::levelset::LevelSet, storage::shapes::Shape, Coord};
//!
//! fn inside_voxels(ls: &impl LevelSet) -> usize {
//!     let mut n = 0;
//!     ls.for_each_band_voxel(&mut |_, v| n += (v < 0.0) as usize);
//!     n
//! }
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let dt = convert::dtgrid_from(&tiles);
//! assert_eq!(inside_voxels(&tiles), inside_voxels(&dt));
//! assert_eq!(tiles.value(Coord::new(0, 0, 0)), -3.0);
//! ```

use crate::coord::Coord;
use crate::grid::{GridSpec, MemoryReport};
use crate::storage::dtgrid::DtGrid;
use crate::storage::tiles::{tile_of, voxel_of, TileGrid};

/// A narrow-band level set as the tools read it (φ < 0 inside, world units; see
/// [`GridSpec`] for the band semantics every implementation follows).
///
/// # Contract
/// * [`value`](LevelSet::value) is defined at every voxel: a stored value in `[−γ, γ]`, or
///   ±γ with the sign of the region for a voxel the storage does not hold.
/// * [`for_each_band_voxel`](LevelSet::for_each_band_voxel) visits exactly the voxels with
///   `|φ| < γ`, each once, in [`Coord`] order, with the values `value` returns.
/// * An [`Accessor`] returns what `value` returns.
/// * Two implementations holding the same band give the same results in every tool.
pub trait LevelSet: Sync {
    /// Voxel size, origin and half-width.
    fn spec(&self) -> GridSpec;

    /// φ at any voxel: the stored value inside the band, ±γ outside.
    fn value(&self, voxel: Coord) -> f32;

    /// A reader for many lookups close to each other (a ray, a stencil), which may cache
    /// what it found; one per thread.
    fn accessor(&self) -> impl Accessor + '_;

    /// Calls `f` with every band voxel (|φ| < γ) and its value, in [`Coord`] order.
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32));

    /// Number of band voxels.
    fn band_voxels(&self) -> usize;

    /// An inclusive voxel box holding every band voxel, `None` when there is none. It may
    /// be larger than the band's own box (the tile grid returns the box of its tiles);
    /// [`LevelSet::band_bounding_box`] is the tight one.
    fn bounding_box(&self) -> Option<(Coord, Coord)>;

    /// Bytes the storage uses.
    fn memory(&self) -> MemoryReport;

    /// The storage as a Sorted Tile List when it is one: tools that run tile by tile
    /// (meshing) use it directly and convert any other storage with
    /// [`crate::storage::convert::tiles_from`].
    fn as_tiles(&self) -> Option<&TileGrid> {
        None
    }

    /// The storage as a DT-Grid when it is one.
    fn as_dtgrid(&self) -> Option<&DtGrid> {
        None
    }

    /// The storage as an H-RLE level set when it is one (its domain and fields are then
    /// available, e.g. to [`crate::io::sls::save`]).
    fn as_hrle(&self) -> Option<&crate::storage::hrle::HrleGrid> {
        None
    }

    /// The tight inclusive box of the band voxels (one pass over them).
    fn band_bounding_box(&self) -> Option<(Coord, Coord)> {
        let mut b: Option<(Coord, Coord)> = None;
        self.for_each_band_voxel(&mut |c, _| {
            b = Some(match b {
                None => (c, c),
                Some((lo, hi)) => (
                    Coord::new(lo.x.min(c.x), lo.y.min(c.y), lo.z.min(c.z)),
                    Coord::new(hi.x.max(c.x), hi.y.max(c.y), hi.z.max(c.z)),
                ),
            })
        });
        b
    }

    /// FNV-1a over the band voxels' coordinates and value bits in [`Coord`] order: equal
    /// bands give equal checksums, whatever stores them.
    fn checksum(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bytes: [u8; 4]| {
            for b in bytes {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        self.for_each_band_voxel(&mut |c, v| {
            eat(c.x.to_le_bytes());
            eat(c.y.to_le_bytes());
            eat(c.z.to_le_bytes());
            eat(v.to_bits().to_le_bytes());
        });
        h
    }
}

/// Random access with a cache (OpenVDB's `ValueAccessor`): the same values as
/// [`LevelSet::value`], faster for lookups that stay close to each other.
pub trait Accessor {
    /// φ at `voxel`.
    fn value(&mut self, voxel: Coord) -> f32;
}

/// The tile accessor: a direct-mapped table over the low two bits of each tile
/// coordinate, so the 2×2×2 tiles around any cell, or the 3×3×3 around a tile, take
/// distinct slots. A slot holds the tile's list position, or the ±γ of an absent tile.
/// (For the renderer the random tile searches were two thirds of the time without it.)
pub struct TileAccessor<'a> {
    grid: &'a TileGrid,
    keys: [Coord; 64],
    /// `Ok(list position)` or `Err(value of every voxel of the absent tile)`.
    slots: [Result<usize, f32>; 64],
    filled: u64,
}

impl<'a> TileAccessor<'a> {
    /// An empty cache over `grid`.
    pub fn new(grid: &'a TileGrid) -> Self {
        TileAccessor { grid, keys: [Coord::default(); 64], slots: [Err(0.0); 64], filled: 0 }
    }
}

impl Accessor for TileAccessor<'_> {
    #[inline]
    fn value(&mut self, voxel: Coord) -> f32 {
        let (t, l) = tile_of(voxel);
        let i = ((t.x & 3) | (t.y & 3) << 2 | (t.z & 3) << 4) as usize;
        if self.filled & (1 << i) == 0 || self.keys[i] != t {
            self.keys[i] = t;
            self.filled |= 1 << i;
            self.slots[i] = self.grid.find_tile(t).map_err(|_| self.grid.value(voxel_of(t, 0)));
        }
        match self.slots[i] {
            Ok(pos) => self.grid.tile(pos).0[l],
            Err(v) => v,
        }
    }
}

impl LevelSet for TileGrid {
    fn spec(&self) -> GridSpec {
        *TileGrid::spec(self)
    }
    fn value(&self, voxel: Coord) -> f32 {
        TileGrid::value(self, voxel)
    }
    fn accessor(&self) -> impl Accessor + '_ {
        TileAccessor::new(self)
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.gamma();
        self.for_each_voxel_sorted(|c, v| {
            if v.abs() < g {
                f(c, v)
            }
        });
    }
    fn band_voxels(&self) -> usize {
        TileGrid::band_voxels(self)
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        TileGrid::bounding_box(self)
    }
    fn memory(&self) -> MemoryReport {
        TileGrid::memory(self)
    }
    fn as_tiles(&self) -> Option<&TileGrid> {
        Some(self)
    }
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
    fn as_dtgrid(&self) -> Option<&DtGrid> {
        Some(self)
    }
}

/// The accessor of a simulation's state: the tile or DT-Grid accessor, random access on
/// the dense reference. (One lives on the stack per ray or row: its size does not
/// matter, an indirection per lookup would.)
#[allow(clippy::large_enum_variant)]
enum SimulationAccessor<'a> {
    Tiles(TileAccessor<'a>),
    DtGrid(crate::storage::dtgrid::DtAccessor<'a>),
    Other(&'a crate::evolve::Simulation),
}

impl Accessor for SimulationAccessor<'_> {
    #[inline]
    fn value(&mut self, voxel: Coord) -> f32 {
        match self {
            SimulationAccessor::Tiles(a) => a.value(voxel),
            SimulationAccessor::DtGrid(a) => a.value(voxel),
            SimulationAccessor::Other(s) => s.value(voxel),
        }
    }
}

/// A simulation's current state (tiles, DT-Grid or the dense reference).
impl LevelSet for crate::evolve::Simulation {
    fn spec(&self) -> GridSpec {
        crate::evolve::Simulation::spec(self)
    }
    fn value(&self, voxel: Coord) -> f32 {
        crate::evolve::Simulation::value(self, voxel)
    }
    fn accessor(&self) -> impl Accessor + '_ {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => SimulationAccessor::Tiles(TileAccessor::new(t)),
            (_, Some(d)) => SimulationAccessor::DtGrid(crate::storage::dtgrid::DtAccessor::new(d)),
            _ => SimulationAccessor::Other(self),
        }
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        crate::evolve::Simulation::for_each_band_voxel(self, f)
    }
    fn band_voxels(&self) -> usize {
        crate::evolve::Simulation::band_voxels(self)
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => t.bounding_box(),
            (_, Some(d)) => d.bounding_box(),
            _ => self.band_bounding_box(),
        }
    }
    fn memory(&self) -> MemoryReport {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => t.memory(),
            (_, Some(d)) => d.memory(),
            _ => MemoryReport { values: self.stored_voxels() * 4, ..Default::default() },
        }
    }
    fn as_tiles(&self) -> Option<&TileGrid> {
        self.tiles()
    }
}

impl Accessor for crate::storage::dtgrid::DtAccessor<'_> {
    #[inline]
    fn value(&mut self, voxel: Coord) -> f32 {
        crate::storage::dtgrid::DtAccessor::value(self, voxel)
    }
}
