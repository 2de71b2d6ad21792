//! The one read interface of a narrow-band level set, which every storage implements and
//! every tool takes.
//!
//! A [`LevelSet`] answers what a tool needs to read a band, whatever stores it: its
//! [`GridSpec`], the value at any voxel (stored, or ±γ outside the band), a cached
//! [`Accessor`] for runs of nearby lookups (OpenVDB's `ValueAccessor`), the band voxels in
//! [`Coord`] order, a bounding box and the memory used. The Sorted Tile List
//! ([`crate::storage::tiles::TileGrid`]), the DT-Grid ([`crate::storage::dtgrid::DtGrid`]), the H-RLE level set
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

    /// The storage behind this level set, when a tool may take a faster path on it (meshing
    /// tile by tile, a `.sls` file of an H-RLE band with its fields): see
    /// [`crate::storage::tiles::TileGrid::of`], [`crate::storage::dtgrid::DtGrid::of`] and
    /// [`crate::storage::hrle::HrleGrid::of`]. `None` for views (CSG) and the dense
    /// reference.
    fn storage(&self) -> Option<&dyn std::any::Any> {
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
