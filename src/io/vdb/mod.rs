//! OpenVDB `.vdb` files: level sets written for Blender, Houdini and OpenVDB's own tools,
//! and OpenVDB's level sets read into a [`TileGrid`].
//!
//! VDB (Museth, "VDB: High-resolution sparse volumes with dynamic topology", ACM TOG
//! 32(3), 2013) stores a grid as a shallow tree: a root table of 4096³-voxel children,
//! internal nodes of 32³ and 16³ slots, and 8³ leaves (the paper's standard "5-4-3"
//! configuration; the byte layout is not in the paper but in OpenVDB's `io/Archive.cc`,
//! `io/Compression.h`, `tree/RootNode.h`, `tree/InternalNode.h`, `tree/LeafNode.h` and
//! `math/Maps.h`, which this module follows). Each node has a value mask (active slots or voxels) and internal
//! nodes a child mask; a slot without a child is a *tile* holding one value for its whole
//! region. A level set keeps its narrow band as the active voxels of the leaves and
//! marks every other voxel and tile with ±background (−background inside).
//!
//! # What is written ([`encode`], [`save`])
//! One grid, laid out as OpenVDB's own file format version 224 (what OpenVDB 10 writes):
//! * the header: magic `0x56444220` (8 bytes), file version 224, library version 10.0,
//!   "has grid offsets" = 1, a 36-character UUID derived from the grid's bytes (so equal
//!   level sets give equal files), no file metadata, one grid;
//! * the grid descriptor: name ([`VdbOptions::grid_name`]), type `Tree_float_5_4_3`, no
//!   instance parent, and the offsets of the grid, its buffers and its end;
//! * the per-grid compression flags: always `COMPRESS_ACTIVE_MASK` (inactive values are
//!   not written, only a mask choosing between ±background where a node holds both), plus
//!   `COMPRESS_ZIP` (zlib) for [`VdbCompression::Zip`] (see there for why it is not the
//!   default);
//! * the grid metadata (sorted by name, as OpenVDB's `MetaMap` writes it): `class` =
//!   `level set`, `file_bbox_min`/`file_bbox_max` (the band's voxel box),
//!   `file_compression`, `file_mem_bytes` (an estimate of OpenVDB's in-memory size),
//!   `file_voxel_count` (band voxels) and `name`;
//! * the transform: `UniformScaleMap` (origin at 0) or `UniformScaleTranslateMap`, scale
//!   = voxel size, translation = [`GridSpec::origin`] (OpenVDB's voxel (i, j, k) lies at
//!   `(i, j, k)·h + translation`, as ours does);
//! * the tree topology: background γ = half-width × voxel size (world units, as OpenVDB's
//!   level sets store φ), root tiles (−γ, inactive) for whole 4096³ regions inside the
//!   surface, then each child depth first: child mask, value mask (empty: no active
//!   tiles), the slot values (±γ by the side of the slot's region), and finally each
//!   leaf's value mask;
//! * the buffers: each leaf's value mask again and its 512 values (active = band voxels,
//!   |φ| < γ; inactive = ±γ by the side, never stored thanks to the mask compression).
//!
//! # What is read ([`decode`], [`load`], [`load_grid`])
//! File format versions 222 to 224 (OpenVDB 3 and later), any number of grids: the first
//! `float` grid of class `level set`, or the one named (which may also be of class
//! `unknown`: many tools write level sets without the class). Compression: none, ZIP,
//! Blosc (LZ4 with or without byte shuffle: what Debian's OpenVDB 10 writes by default) and
//! the active-mask compression in all its seven forms; half-float grids
//! (`Tree_float_5_4_3_HalfFloat`) are widened to `f32`. The transform must be a uniform
//! scale with or without a translation (`UniformScaleMap`, `UniformScaleTranslateMap`,
//! a uniform `ScaleMap`/`ScaleTranslateMap`, or a `TranslationMap`); the half-width is
//! background / voxel size and must exceed 1 ([`GridSpec::new`]). Band voxels are the
//! active voxels with |φ| < γ; every other voxel, inactive tile and region without a node
//! reads ±γ with the sign of its stored value (±∞ are clamped to ±γ, so they are not band
//! voxels). Active tiles whose value lies inside the band (a whole region of band
//! voxels, which no level set tool writes) are refused.
//!
//! # Reading hostile files
//! [`decode`] never panics and never allocates more than the file justifies: every count
//! (metadata entries, string lengths, root tiles and children) is checked against the
//! bytes left before anything is sized by it, node masks bound the number of nodes by the
//! bytes each takes, every compressed block must decompress to exactly the size its node
//! needs, offsets must lie inside the file, and NaN values are refused with their voxel.
//!
//! ```
//! use sparse_levelset::{storage::convert, storage::shapes::Shape, io::vdb, GridSpec, LevelSet};
//!
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let bytes = vdb::encode(&tiles, &vdb::VdbOptions::default()).unwrap();
//! let (back, info) = vdb::decode(&bytes).unwrap();
//! assert_eq!(back.checksum(), tiles.checksum());
//! assert_eq!((info.grid_name.as_str(), info.grid_class.as_str()), ("level_set", "level set"));
//! assert!(vdb::decode(&bytes[..bytes.len() - 1]).is_err());
//! ```

mod blosc;
mod read;
mod write;

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::storage::levelset::LevelSet;
use crate::storage::tiles::TileGrid;
use std::io::Write;
use std::path::Path;

/// OpenVDB's magic number ("VDB " as a little-endian `i64`).
pub const MAGIC: i64 = 0x5644_4220;
/// The file format version written (OpenVDB 6 to 12 write 224).
pub const FILE_VERSION: u32 = 224;
/// The oldest file format version read (222: per-node mask compression).
pub const MIN_FILE_VERSION: u32 = 222;

/// zlib compression of node buffers.
pub(crate) const COMPRESS_ZIP: u32 = 0x1;
/// Inactive values left out where a mask (or nothing) can rebuild them.
pub(crate) const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// Blosc compression of node buffers.
pub(crate) const COMPRESS_BLOSC: u32 = 0x4;

/// How node buffers are compressed on write. The active-mask compression (inactive
/// values left out, lossless) is always on: it is what makes a level set small. On a
/// sphere of 1.09 M band voxels zlib then saved 2% (5.29 → 5.18 MB) for 2.5× the
/// encoding time, since a distance field's float bits hardly deflate, so the default is
/// no further compression (what OpenVDB itself does for level sets when it has no Blosc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VdbCompression {
    /// Active values stored raw: the fastest to write and to read.
    #[default]
    None,
    /// zlib (deflate) over each node's active values: a few percent smaller.
    Zip,
}

impl VdbCompression {
    fn flags(self) -> u32 {
        match self {
            VdbCompression::None => COMPRESS_ACTIVE_MASK,
            VdbCompression::Zip => COMPRESS_ACTIVE_MASK | COMPRESS_ZIP,
        }
    }
}

/// Options of [`encode`] and [`save`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VdbOptions {
    /// The grid's name (non-empty; Blender and Houdini show it).
    pub grid_name: String,
    /// Compression of the node buffers.
    pub compression: VdbCompression,
}

impl Default for VdbOptions {
    fn default() -> Self {
        VdbOptions { grid_name: "level_set".into(), compression: VdbCompression::None }
    }
}

/// What a `.vdb` file says about the grid read.
#[derive(Clone, Debug, PartialEq)]
pub struct VdbInfo {
    /// The grid's name.
    pub grid_name: String,
    /// The grid's class as written (`level set`, or `unknown` for a grid chosen by name).
    pub grid_class: String,
    /// Voxel size (world units).
    pub voxel_size: f64,
    /// World position of voxel (0, 0, 0) (the transform's translation).
    pub origin: [f64; 3],
    /// The background value (world units): γ.
    pub background: f32,
    /// Half-width of the band in voxels: background / voxel size.
    pub half_width: f32,
    /// The grid's compression flags as a description (OpenVDB's words: `none`,
    /// `zip + active values`, `blosc + active values`, ...).
    pub compression: String,
    /// Whether the values were stored as 16-bit half floats.
    pub half_float: bool,
    /// File format version.
    pub file_version: u32,
    /// Version of the OpenVDB library that wrote the file (major, minor).
    pub library_version: (u32, u32),
    /// Active voxels in the grid's leaves.
    pub active_voxels: u64,
    /// The names, value types and classes of every grid in the file.
    pub grids: Vec<String>,
}

/// Why a `.vdb` file was refused or could not be written.
#[derive(Debug, thiserror::Error)]
pub enum VdbError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    /// Any other error, with the file it concerns.
    #[error("{path}: {error}")]
    InFile { path: String, error: Box<VdbError> },
    /// The bytes do not start with OpenVDB's magic number.
    #[error("not an OpenVDB (.vdb) file: it does not start with the VDB magic number")]
    NotVdb,
    /// A file format version this library cannot read.
    #[error(
        "written in OpenVDB file format version {0}; this library reads versions \
         {MIN_FILE_VERSION} to {FILE_VERSION} (OpenVDB 3 and later): re-save it with OpenVDB 10"
    )]
    Version(u32),
    /// The file ends before what it announces.
    #[error("truncated: the file ends inside {0}")]
    Truncated(&'static str),
    /// The bytes are not a well-formed VDB file.
    #[error("corrupt: {0}")]
    Corrupt(String),
    /// A well-formed file using a feature this reader does not support.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// No grid of the file can be read as a level set.
    #[error("{0}")]
    NoGrid(String),
    /// A NaN value in the level set.
    #[error("NaN at voxel {coord}; level-set values must be numbers")]
    NaN { coord: Coord },
    /// The grid has no active voxel inside the band.
    #[error(
        "no interface: the grid has no active voxel with |φ| < background, so the level set \
         is empty"
    )]
    NoInterface,
    /// The level set to write has no band voxel.
    #[error("the level set has no band voxel (|φ| < γ): there is no surface to write")]
    Empty,
    /// An option outside its domain.
    #[error("invalid option: {0}")]
    Option(String),
    /// The file or the grid does not fit in memory, or a grid could not be made.
    #[error(transparent)]
    Grid(#[from] GridError),
}

impl crate::error::Error for VdbError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            VdbError::Io { source, .. } => crate::error::io_kind(source),
            VdbError::InFile { error, .. } => error.kind(),
            VdbError::NotVdb | VdbError::Truncated(_) | VdbError::Corrupt(_) => CorruptFile,
            VdbError::Version(_) | VdbError::Unsupported(_) => Unsupported,
            VdbError::NoGrid(_) | VdbError::Option(_) => InvalidInput,
            VdbError::NaN { .. } | VdbError::NoInterface | VdbError::Empty => InvalidData,
            VdbError::Grid(e) => e.kind(),
        }
    }
}

impl VdbError {
    /// The error with the file's path in front.
    fn at(self, path: &Path) -> VdbError {
        match self {
            VdbError::Io { .. } | VdbError::InFile { .. } => self,
            e => VdbError::InFile { path: path.display().to_string(), error: Box::new(e) },
        }
    }
}

/// OpenVDB's description of compression flags (`compressionToString`).
fn compression_name(flags: u32) -> String {
    if flags == 0 {
        return "none".into();
    }
    let mut parts = Vec::new();
    if flags & COMPRESS_ZIP != 0 {
        parts.push("zip");
    }
    if flags & COMPRESS_BLOSC != 0 {
        parts.push("blosc");
    }
    if flags & COMPRESS_ACTIVE_MASK != 0 {
        parts.push("active values");
    }
    parts.join(" + ")
}

/// The bytes of a `.vdb` file holding `ls` as one level-set grid (see the
/// [module docs](self) for the layout). An empty level set (no band voxel) is an error.
pub fn encode<G: LevelSet + ?Sized>(ls: &G, opts: &VdbOptions) -> Result<Vec<u8>, VdbError> {
    write::encode(ls, opts)
}

/// Writes `ls` to `path` as a `.vdb` file, atomically (a temporary file renamed into
/// place: on any error `path` is left as it was).
pub fn save<G: LevelSet + ?Sized>(path: &Path, ls: &G, opts: &VdbOptions) -> Result<(), VdbError> {
    let bytes = encode(ls, opts).map_err(|e| e.at(path))?;
    crate::io::fsutil::write_atomic(path, |w| w.write_all(&bytes))
        .map_err(|source| VdbError::Io { path: path.display().to_string(), source })
}

/// Decodes a `.vdb` file's bytes: its first `float` level-set grid, as a tile grid.
pub fn decode(bytes: &[u8]) -> Result<(TileGrid, VdbInfo), VdbError> {
    read::decode(bytes, None)
}

/// Decodes the grid named `name` of a `.vdb` file's bytes (class `level set` or
/// `unknown`).
pub fn decode_grid(bytes: &[u8], name: &str) -> Result<(TileGrid, VdbInfo), VdbError> {
    read::decode(bytes, Some(name))
}

fn load_impl(path: &Path, name: Option<&str>) -> Result<(TileGrid, VdbInfo), VdbError> {
    let io = |source| VdbError::Io { path: path.display().to_string(), source };
    let len = std::fs::metadata(path).map_err(io)?.len();
    // The bytes, the nodes' values (at most 16 times the bytes that describe them, see
    // `read`) and the tiles built from them.
    crate::memory::check(24.0 * len as f64, "reading the .vdb file")
        .map_err(|e| VdbError::from(e).at(path))?;
    let bytes = std::fs::read(path).map_err(io)?;
    read::decode(&bytes, name).map_err(|e| e.at(path))
}

/// Reads the first `float` level-set grid of a `.vdb` file into a tile grid; errors name
/// the file.
pub fn load(path: &Path) -> Result<(TileGrid, VdbInfo), VdbError> {
    load_impl(path, None)
}

/// Reads the grid named `name` of a `.vdb` file (class `level set` or `unknown`).
pub fn load_grid(path: &Path, name: &str) -> Result<(TileGrid, VdbInfo), VdbError> {
    load_impl(path, Some(name))
}

/// The spec of a grid read from a file: voxel size, origin and half-width = background /
/// voxel size, nudged by a few ulps so that half-width × voxel size gives the background
/// back exactly where an `f32` allows it (files this module writes read back with their
/// own spec).
/// A vector grid (`Vec3s`, e.g. a velocity field) read by [`load_vector_grid`]: its three
/// components as dense fields over the box of its active values, placed in the world by
/// the grid's transform (voxel (i, j, k) at `(i, j, k) · voxel_size + origin`).
#[derive(Clone, Debug)]
pub struct VdbVectorGrid {
    /// `[u_x, u_y, u_z]`, each with the box's first voxel as its origin.
    pub components: [crate::storage::dense::DenseField; 3],
    pub voxel_size: f64,
    pub origin: [f64; 3],
    pub name: String,
}

impl VdbVectorGrid {
    /// The lattice of the components in the world (the half-width is not used).
    pub fn spec(&self) -> Result<GridSpec, GridError> {
        GridSpec::new(self.voxel_size as f32, self.origin, 3.0)
    }
}

/// Decodes a vector grid (`Tree_vec3s_5_4_3`, full or half floats) of a `.vdb` file's
/// bytes: the one named, or the first.
pub fn decode_vector_grid(bytes: &[u8], name: Option<&str>) -> Result<VdbVectorGrid, VdbError> {
    read::decode_vector(bytes, name)
}

/// Reads a vector grid of a `.vdb` file (the one named, or the first `Vec3s` grid) into
/// dense components; the same checks as [`load`] (hostile files, NaN, memory before the
/// dense box is allocated); errors name the file.
pub fn load_vector_grid(path: &Path, name: Option<&str>) -> Result<VdbVectorGrid, VdbError> {
    let io = |source| VdbError::Io { path: path.display().to_string(), source };
    let len = std::fs::metadata(path).map_err(io)?.len();
    crate::memory::check(24.0 * len as f64, "reading the .vdb file")
        .map_err(|e| VdbError::from(e).at(path))?;
    let bytes = std::fs::read(path).map_err(io)?;
    read::decode_vector(&bytes, name).map_err(|e| e.at(path))
}

fn spec_from(voxel_size: f32, origin: [f64; 3], background: f32) -> Result<GridSpec, VdbError> {
    let hw = background / voxel_size;
    let exact = (1..=4u32)
        .flat_map(|k| [hw.to_bits().wrapping_add(k), hw.to_bits().wrapping_sub(k)])
        .map(f32::from_bits)
        .chain(std::iter::once(hw))
        .filter(|c| c.is_finite() && *c * voxel_size == background)
        .min_by(|a, b| (a - hw).abs().total_cmp(&(b - hw).abs()));
    let best = exact.unwrap_or(hw);
    if best.is_nan() || best <= 1.0 {
        return Err(VdbError::Unsupported(format!(
            "the background {background} is not more than one voxel ({voxel_size}): the band \
             half-width must exceed 1 voxel (rebuild the level set with a wider band, e.g. \
             OpenVDB's halfWidth = 3)"
        )));
    }
    GridSpec::new(voxel_size, origin, best)
        .map_err(|e| VdbError::Unsupported(format!("grid placement: {e}")))
}
