//! Every file format in one place, on one bounds-checked byte reader (`bytes`) and one
//! atomic writer ([`fsutil`]): dense `.npy` level sets ([`npy`]), the sparse `.sls` format
//! ([`sls`]), OpenVDB ([`vdb`]), images (NIfTI, PNG, MetaImage, NRRD, `.npy`: [`image`]),
//! and the checks every loaded level set passes ([`input`]).

pub(crate) mod bytes;
pub mod fsutil;
pub mod image;
pub mod input;
pub mod mesh;
pub mod npy;
pub mod sls;
pub mod vdb;

use crate::coord::Coord;
use crate::grid::{GridSpec, MemoryReport};
use crate::storage::convert::{tiles_from_dense, ExportError};
use crate::storage::hrle::HrleGrid;
use crate::storage::levelset::{Accessor, LevelSet};
use crate::storage::tiles::TileGrid;
use input::{Expect, InputError};
use std::path::Path;

/// The level-set file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelSetFormat {
    /// A dense float32 `.npy` array `[z, y, x]` (φ < 0 inside, world units), on a grid the
    /// caller names.
    Npy,
    /// The sparse `.sls` format (an H-RLE band with its own grid).
    Sls,
    /// An OpenVDB `.vdb` level set (with its own grid).
    Vdb,
}

impl LevelSetFormat {
    /// The extensions of level-set files, for messages.
    pub const EXTENSIONS: &'static str = ".npy, .sls, .vdb";

    /// The format a path's extension names (`.npy`, `.sls`, `.vdb`, any case).
    pub fn from_path(path: &Path) -> Option<LevelSetFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "npy" => Some(LevelSetFormat::Npy),
            "sls" => Some(LevelSetFormat::Sls),
            "vdb" => Some(LevelSetFormat::Vdb),
            _ => None,
        }
    }
}

/// A level set in whichever storage its file gave: the tiles of a `.npy` or `.vdb` file, the
/// H-RLE band of a `.sls` file. It is a [`LevelSet`] itself, so every tool takes it.
#[derive(Clone, Debug)]
pub enum AnyLevelSet {
    /// A Sorted Tile List.
    Tiles(TileGrid),
    /// An H-RLE band (with its domain and fields, as a `.sls` file holds them).
    Hrle(HrleGrid),
}

/// What [`load_level_set`] read: the level set and what the file said about it.
#[derive(Clone, Debug)]
pub struct LoadedLevelSet {
    /// The level set.
    pub level_set: AnyLevelSet,
    /// The file's format.
    pub format: LevelSetFormat,
    /// The header of a `.sls` file.
    pub sls_header: Option<sls::Header>,
    /// The grid description of a `.vdb` file.
    pub vdb_info: Option<vdb::VdbInfo>,
    /// A `.npy` file's array, `[nx, ny, nz]` voxels from voxel (0, 0, 0).
    pub npy_dims: Option<[usize; 3]>,
}

/// Loads a level set from a `.npy`, `.sls` or `.vdb` file, chosen by the extension, through
/// the checks of [`input`] (the same verdict and message from every tool). A `.npy` field
/// is read on `expect.spec` and becomes tiles; `.sls` and `.vdb` files carry their own grid.
pub fn load_level_set(path: &Path, expect: &Expect) -> Result<LoadedLevelSet, InputError> {
    let format = LevelSetFormat::from_path(path)
        .ok_or_else(|| InputError::UnknownFormat { input: path.display().to_string() })?;
    let loaded = |level_set, sls_header, vdb_info, npy_dims| LoadedLevelSet {
        level_set,
        format,
        sls_header,
        vdb_info,
        npy_dims,
    };
    Ok(match format {
        LevelSetFormat::Npy => {
            let field = input::load_npy(path, expect)?;
            let tiles = tiles_from_dense(&field, expect.spec).map_err(|error| {
                InputError::OutOfMemory { input: path.display().to_string(), error }
            })?;
            loaded(AnyLevelSet::Tiles(tiles), None, None, Some(field.dims()))
        }
        LevelSetFormat::Sls => {
            let (grid, header) = input::load_sls(path, expect)?;
            loaded(AnyLevelSet::Hrle(grid), Some(header), None, None)
        }
        LevelSetFormat::Vdb => {
            let (tiles, info) = input::load_vdb(path, expect)?;
            loaded(AnyLevelSet::Tiles(tiles), None, Some(info), None)
        }
    })
}

/// A vector field read by [`load_vector_field`]: its components `[u_x, u_y, u_z]` on their
/// dense grid, and the lattice that places that grid in the world.
#[derive(Clone, Debug)]
pub struct LoadedVectorField {
    pub components: [crate::storage::dense::DenseField; 3],
    pub spec: GridSpec,
}

/// Why [`load_vector_field`] read nothing.
#[derive(Debug, thiserror::Error)]
pub enum VectorFieldError {
    /// The file's extension names no vector-field format.
    #[error(
        "{}: unknown vector-field file type; use .npy (float32, shape (nz, ny, nx, 3)) or .vdb \
         (a Vec3s grid)",
        .path.display()
    )]
    UnknownFormat { path: std::path::PathBuf },
    #[error(transparent)]
    Npy(#[from] npy::NpyError),
    #[error(transparent)]
    Vdb(#[from] vdb::VdbError),
    /// The field cannot be placed where it was asked to be.
    #[error("{}: {error}", .path.display())]
    Placement { path: std::path::PathBuf, error: crate::grid::GridError },
}

impl crate::error::Error for VectorFieldError {
    fn kind(&self) -> crate::error::ErrorKind {
        match self {
            VectorFieldError::UnknownFormat { .. } => crate::error::ErrorKind::UnknownFormat,
            VectorFieldError::Npy(e) => e.kind(),
            VectorFieldError::Vdb(e) => e.kind(),
            VectorFieldError::Placement { error, .. } => error.kind(),
        }
    }
}

/// Reads a vector field (a velocity, say), chosen by the extension: a float32 `.npy` of
/// shape `(nz, ny, nx, 3)` on the lattice `npy_lattice` with element `[0, 0, 0]` at voxel
/// `npy_origin`, or the first `Vec3s` grid of a `.vdb` file, placed by its own transform.
pub fn load_vector_field(
    path: &Path,
    npy_lattice: &GridSpec,
    npy_origin: Coord,
) -> Result<LoadedVectorField, VectorFieldError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let placement = |error| VectorFieldError::Placement { path: path.to_path_buf(), error };
    match ext.as_deref() {
        Some("npy") => {
            let [x, y, z] = npy::read_npy_vector(path)?;
            let at = |f: crate::storage::dense::DenseField| f.with_origin(npy_origin);
            Ok(LoadedVectorField {
                components: [
                    at(x).map_err(placement)?,
                    at(y).map_err(placement)?,
                    at(z).map_err(placement)?,
                ],
                spec: *npy_lattice,
            })
        }
        Some("vdb") => {
            let g = vdb::load_vector_grid(path, None)?;
            let spec = g.spec().map_err(placement)?;
            Ok(LoadedVectorField { components: g.components, spec })
        }
        _ => Err(VectorFieldError::UnknownFormat { path: path.to_path_buf() }),
    }
}

/// How [`save_level_set`] writes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SaveOptions {
    /// Voxels of margin around the band's box in a dense `.npy`.
    pub margin: u32,
    /// The grid's name and compression in a `.vdb`.
    pub vdb: vdb::VdbOptions,
}

/// Why [`save_level_set`] wrote nothing.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    /// The file's extension names no level-set format.
    #[error("{}: unknown level-set file type; use {}", .path.display(), LevelSetFormat::EXTENSIONS)]
    UnknownFormat {
        /// The path asked for.
        path: std::path::PathBuf,
    },
    /// Writing the `.sls` file failed.
    #[error(transparent)]
    Sls(#[from] sls::SlsError),
    /// Writing the `.vdb` file failed.
    #[error(transparent)]
    Vdb(#[from] vdb::VdbError),
    /// Writing the dense `.npy` file failed.
    #[error("{}", npy_message(.path, .source))]
    Npy {
        /// The path asked for.
        path: std::path::PathBuf,
        /// What failed.
        source: ExportError,
    },
}

/// The message of a failed `.npy` export, naming the path once (a file error names it).
fn npy_message(path: &Path, e: &ExportError) -> String {
    match e {
        ExportError::Npy(e) => e.to_string(),
        e => format!("{}: {e}", path.display()),
    }
}

impl crate::error::Error for SaveError {
    fn kind(&self) -> crate::error::ErrorKind {
        match self {
            SaveError::UnknownFormat { .. } => crate::error::ErrorKind::UnknownFormat,
            SaveError::Sls(e) => e.kind(),
            SaveError::Vdb(e) => e.kind(),
            SaveError::Npy { source, .. } => source.kind(),
        }
    }
}

/// Writes any level set to `path` as `.sls`, `.vdb` or a dense `.npy` (the band's box grown
/// by `opts.margin` voxels), chosen by the extension; atomically (the file appears
/// complete or not at all). Returns the voxel of the `.npy` array's element `[0, 0, 0]`.
pub fn save_level_set<L: LevelSet + ?Sized>(
    path: &Path,
    ls: &L,
    opts: &SaveOptions,
) -> Result<Option<Coord>, SaveError> {
    match LevelSetFormat::from_path(path) {
        Some(LevelSetFormat::Sls) => sls::save(path, ls).map(|_| None).map_err(SaveError::from),
        Some(LevelSetFormat::Vdb) => {
            vdb::save(path, ls, &opts.vdb).map(|_| None).map_err(SaveError::from)
        }
        Some(LevelSetFormat::Npy) => crate::storage::convert::export_npy(ls, path, opts.margin)
            .map(Some)
            .map_err(|source| SaveError::Npy { path: path.to_path_buf(), source }),
        None => Err(SaveError::UnknownFormat { path: path.to_path_buf() }),
    }
}

/// The reader of either storage.
enum AnyAccessor<T, H> {
    Tiles(T),
    Hrle(H),
}

impl<T: Accessor, H: Accessor> Accessor for AnyAccessor<T, H> {
    fn value(&mut self, voxel: Coord) -> f32 {
        match self {
            AnyAccessor::Tiles(a) => a.value(voxel),
            AnyAccessor::Hrle(a) => a.value(voxel),
        }
    }
}

impl LevelSet for AnyLevelSet {
    fn spec(&self) -> GridSpec {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::spec(g),
            AnyLevelSet::Hrle(g) => LevelSet::spec(g),
        }
    }
    fn value(&self, voxel: Coord) -> f32 {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::value(g, voxel),
            AnyLevelSet::Hrle(g) => LevelSet::value(g, voxel),
        }
    }
    fn accessor(&self) -> impl Accessor + '_ {
        match self {
            AnyLevelSet::Tiles(g) => AnyAccessor::Tiles(LevelSet::accessor(g)),
            AnyLevelSet::Hrle(g) => AnyAccessor::Hrle(LevelSet::accessor(g)),
        }
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::for_each_band_voxel(g, f),
            AnyLevelSet::Hrle(g) => LevelSet::for_each_band_voxel(g, f),
        }
    }
    fn band_voxels(&self) -> usize {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::band_voxels(g),
            AnyLevelSet::Hrle(g) => LevelSet::band_voxels(g),
        }
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::bounding_box(g),
            AnyLevelSet::Hrle(g) => LevelSet::bounding_box(g),
        }
    }
    fn memory(&self) -> MemoryReport {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::memory(g),
            AnyLevelSet::Hrle(g) => LevelSet::memory(g),
        }
    }
    fn storage(&self) -> Option<&dyn std::any::Any> {
        match self {
            AnyLevelSet::Tiles(g) => LevelSet::storage(g),
            AnyLevelSet::Hrle(g) => LevelSet::storage(g),
        }
    }
}
