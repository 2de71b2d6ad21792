//! Scalar images on a regular lattice: the input of segmentation (`crate::segment`), and
//! their files.
//!
//! # Layout and geometry
//! An [`Image`] holds `nx · ny · nz` intensities, **x fastest** (`index = x + nx (y + ny
//! z)`, the memory order of a C-ordered NumPy array of shape `(nz, ny, nx)`), kept in
//! `f32` whatever the file's voxel type. Voxel `(i, j, k)` has its centre at the
//! *lattice position* `(i sx, j sy, k sz)` with the spacing `(sx, sy, sz)` in world units
//! (millimetres for a scan); the level sets of a segmentation live in this frame. The
//! image's placement in the scanner's world (origin and axis directions, for a NIfTI file
//! its `sform`/`qform`) is [`Image::to_world`]: meshes are written through it. A 2D
//! image is a volume with `nz = 1`.
//!
//! # Files
//! [`load`] reads an image, [`save_mask`] writes a segmentation (0/1 per voxel) and
//! [`save_f32`] a float volume (a level set, a feature image); the format is chosen by the
//! file name's extension (case-insensitive), [`FileFormat::from_path`]:
//!
//! | extension | read | written |
//! |---|---|---|
//! | `.nii`, `.nii.gz` | NIfTI-1, one file; voxel types `uint8`, `int8`, `uint16`, `int16`, `uint32`, `int32`, `uint64`, `int64`, `float32`, `float64`, either byte order | masks as `uint8`, floats as `float32`, little-endian |
//! | `.npy` | 2-D `(ny, nx)` or 3-D `(nz, ny, nx)` arrays of `bool`, `u1`/`i1`, `u2`/`i2`, `u4`/`i4`, `u8`/`i8`, `f4`, `f8`, either byte order, C or Fortran order | masks as `\|u1`, floats as `<f4`, C order, the input's 2-D or 3-D shape |
//! | `.png` | greyscale, 1 to 16 bits, as one slice; row 0 is y = 0 | masks only, 8-bit greyscale 0/255, images with `nz = 1` |
//!
//! Every input gets one verdict from [`load`], with one message per kind of bad input
//! ([`ImageError`], naming the file), before anything large is allocated: the sizes a
//! header announces are checked against the file's size (uncompressed files) and against
//! the memory the machine can give ([`crate::memory`]), so a hostile header announcing
//! 2⁴⁰ voxels is refused at once. Every intensity must be finite ([`ImageError::NonFinite`]
//! names the first offending voxel, x fastest). Writes are atomic
//! ([`crate::fsutil::write_atomic`]): a failed write leaves an existing file as it was.
//!
//! ## NIfTI
//! * Axes: NIfTI's voxel indices `(i, j, k)` are our `(x, y, z)`; `i` is fastest in the
//!   file, as x is in [`Image::data`]. Intensities are `scl_slope · v + scl_inter` when
//!   `scl_slope` is a non-zero finite number (the standard: `scl_slope = 0` means no
//!   scaling), computed in `f64`, rounded once to `f32`. Integers beyond 2²⁴ lose
//!   precision in `f32`.
//! * Dimensions: `dim[0]` from 1 to 7, every used `dim[i] ≥ 1`; 1-D and 2-D images are
//!   volumes with `ny = nz = 1` or `nz = 1`. Dimensions 4 to 7 must all be 1 (a 4-D file
//!   with one volume is read); a time series or a vector image is refused
//!   ([`ImageError::Unsupported4D`]).
//! * Spacing: `|pixdim[1..=3]|` (a negative `pixdim` is read by its magnitude, as nibabel
//!   does); zero or non-finite values on a used axis are refused
//!   ([`ImageError::BadSpacing`]); an unused axis (z of a 2-D image) with no valid value
//!   gets 1.
//! * Placement, as the standard prescribes: the `sform` when `sform_code > 0`, else the
//!   `qform` (quaternion `b, c, d`, offsets, `qfac = pixdim[0]`, spacing
//!   `|pixdim[1..=3]|`) when `qform_code > 0`, else none (world = lattice position). With
//!   `A` the 3×4 voxel-index → world matrix so obtained (finite and invertible, else
//!   [`ImageError::BadTransform`]), `to_world = A · diag(1/sx, 1/sy, 1/sz, 1)`: it maps
//!   lattice positions, so that `image.world([i sx, j sy, k sz])` is `A · (i, j, k, 1)`
//!   whatever the spacing.
//! * The header's `float32` values are read as the `f64` of their shortest decimal form
//!   (`0.7f32` is 0.7, not 0.699999988…), so that spacings written from `f64` read back
//!   as they were, to `float32` precision.
//! * Not read: extensions (skipped), intent, time units, slice timing, display range; they
//!   are not needed for segmentation. `.hdr`/`.img` pairs and NIfTI-2 are refused with
//!   their own messages. The header's `bitpix` is not trusted (the datatype decides).
//! * Bytes after the voxel data are ignored (as nibabel does); a `.nii.gz` is read to its
//!   end so that gzip's checksum is verified.
//!
//! ## The spacing argument
//! `load(path, Some(spacing))` replaces the file's spacing (NIfTI's `pixdim`, and the
//! default `(1, 1, 1)` of `.npy` and PNG); it is checked as above and allowed for every
//! format. For a NIfTI file placed by its `sform` or `qform` the placement is kept: voxel
//! `(i, j, k)` still lands at `A · (i, j, k, 1)` in the world, only the lattice (the frame
//! of distances and curvatures) changes; an unplaced image stays at world = lattice
//! position. It rescues a file with a broken `pixdim` unless its placement is a `qform`
//! (which is built from `pixdim`).
//!
//! ## Writing back
//! [`LoadedImage`] keeps what writing in the input's format needs ([`Source`]): for a
//! NIfTI input its whole header, so that [`save_mask`] and [`save_f32`] to `.nii`/`.nii.gz`
//! write it again — same `dim`, `pixdim` (the file's, whatever the spacing argument),
//! `sform`, `qform` and their codes, `xyzt_units`, `descrip` — with the datatype changed
//! (`uint8` for masks, with `cal_min = 0`, `cal_max = 1`; `float32` for floats), no
//! scaling (`scl_slope = 1`, `scl_inter = 0`), no intent, no extensions, little-endian,
//! data at byte 352. Images from `.npy`, PNG or memory get a header of their own: their
//! spacing in `pixdim`, `A = to_world · diag(sx, sy, sz, 1)` as the `sform` (code 2,
//! aligned), and as the `qform` too (code 2) when `to_world` is a rotation (possibly
//! improper) plus a translation, spatial units unknown. A `.npy` output has the input's
//! 2-D or 3-D shape (2-D for PNG inputs and NIfTI inputs with `dim[0] ≤ 2`). An image
//! whose [`Image::dims`] no longer match its NIfTI header (cropped after loading) is not
//! written with that header ([`ImageError::CannotWrite`]): make it a
//! [`LoadedImage::from_image`] first.
//!
//! ## World coordinates of NIfTI
//! NIfTI's world frame (`sform`/`qform` codes 1 to 4) is **RAS+**: x grows to the
//! subject's Right, y Anterior, z Superior, in millimetres when `xyzt_units` says so.
//! DICOM and ITK use LPS+: x and y have the opposite sign. Nothing here converts.
//!
//! ## `.npy`
//! `arr[z, y, x]` (or `arr[y, x]`) is voxel `(x, y, z)`. Fortran-ordered files are read
//! with a scattering copy into x-fastest order. The spacing is the argument's, `(1, 1, 1)`
//! by default; the placement is the identity. Bytes after the data are an error, as in
//! [`crate::npy`]. The header is parsed here by a strict parser (nothing is allocated
//! from what a hostile header says).
//!
//! ## PNG
//! One slice (`nz = 1`), x along a row, row 0 at y = 0 (the top row of the picture);
//! spacing from the argument, `(1, 1, 1)` by default; identity placement. Greyscale and
//! grey + alpha images are read, 8 and 16 bits as they are, 1, 2 and 4 bits scaled to
//! 0..255 (PNG's display semantics); alpha is ignored. Colour images (RGB, RGBA,
//! palette) are read only when every pixel is grey (R = G = B), which is how many tools
//! save greyscale pictures; any coloured pixel is refused ([`ImageError::NotGreyscale`]),
//! because no choice of luminance weights is right for every image: convert it first.
//!
//! ```
//! use sparse_levelset::image::{self, Image, LoadedImage, IDENTITY};
//!
//! let dir = std::env::temp_dir().join(format!("image-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! // A 4 × 3 × 2 image with voxels of 0.5 × 0.5 × 2 mm.
//! let data: Vec<f32> = (0..24).map(|i| i as f32).collect();
//! let im = Image { dims: [4, 3, 2], spacing: [0.5, 0.5, 2.0], data, to_world: IDENTITY };
//! let like = LoadedImage::from_image(im);
//! image::save_f32(&dir.join("a.nii.gz"), &like.image.data, &like).unwrap();
//! let back = image::load(&dir.join("a.nii.gz"), None).unwrap();
//! assert_eq!(back.image.dims, [4, 3, 2]);
//! assert_eq!(back.image.spacing, [0.5, 0.5, 2.0]);
//! assert_eq!(back.image.data, like.image.data);
//! // A mask written back with the input's header, and as .npy of the same shape.
//! let mask: Vec<u8> = back.image.data.iter().map(|&v| (v > 11.5) as u8).collect();
//! image::save_mask(&dir.join("mask.nii"), &mask, &back).unwrap();
//! image::save_mask(&dir.join("mask.npy"), &mask, &back).unwrap();
//! assert_eq!(image::load(&dir.join("mask.npy"), None).unwrap().image.data[12], 1.0);
//! // A 3-D image cannot be a PNG.
//! assert!(image::save_mask(&dir.join("mask.png"), &mask, &back).is_err());
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

mod nifti;
mod npy;
mod png;
mod voxels;

use rayon::prelude::*;
use std::io;
use std::path::{Path, PathBuf};

/// A scalar image: intensities, spacing and placement in the world.
///
/// # Invariants
/// * every entry of `dims` is ≥ 1 and `data.len() == dims[0] · dims[1] · dims[2]`;
/// * every spacing is finite and > 0;
/// * every intensity is finite.
#[derive(Clone, Debug)]
pub struct Image {
    /// `[nx, ny, nz]`.
    pub dims: [usize; 3],
    /// World units per voxel along x, y, z.
    pub spacing: [f64; 3],
    /// Intensities, x fastest.
    pub data: Vec<f32>,
    /// Lattice position → world: `world = M · (p, 1)` with `M` a 3×4 matrix (rows x, y,
    /// z). The identity for images without a placement (`.npy`, PNG).
    pub to_world: [[f64; 4]; 3],
}

impl Image {
    /// The index of voxel `(x, y, z)` in [`Image::data`].
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the image has no voxel (never, by the invariants).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// A 2D image (one slice).
    pub fn is_2d(&self) -> bool {
        self.dims[2] == 1
    }

    /// Applies [`Image::to_world`] to a lattice position.
    pub fn world(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.to_world;
        std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
    }
}

/// The identity placement: world = lattice position.
pub const IDENTITY: [[f64; 4]; 3] =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];

/// The extensions [`load`] and the writers know, for messages.
pub const SUPPORTED_EXTENSIONS: &str = ".nii, .nii.gz, .npy, .png";

/// Why an image cannot be read or written; every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The operating system refused (missing file, permissions, disk full, ...).
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The file name's extension is not one of [`SUPPORTED_EXTENSIONS`].
    #[error(
        "{}: unknown image format: the file name must end in one of {SUPPORTED_EXTENSIONS} \
         (case does not matter)",
        .path.display()
    )]
    UnsupportedFormat { path: PathBuf },
    /// The file is not what its extension says, or its header contradicts itself.
    #[error("{}: not a valid {format} file: {reason}", .path.display())]
    Corrupt { path: PathBuf, format: &'static str, reason: String },
    /// The file ends before the data its header announces.
    #[error("{}: truncated file: {detail}", .path.display())]
    Truncated { path: PathBuf, detail: String },
    /// The image needs more memory than the machine can give (or than 64 bits count),
    /// refused before anything is allocated.
    #[error(
        "{}: the image is too large: {what} need about {} but only about {} of memory may \
         be used",
        .path.display(), crate::memory::gib(*.needed), crate::memory::gib(*.limit)
    )]
    TooLarge { path: PathBuf, what: String, needed: u64, limit: u64 },
    /// A voxel type that is not read (complex, RGB, float16, structured, ...).
    #[error("{}: unsupported voxel type {found}; supported: {supported}", .path.display())]
    UnsupportedVoxelType { path: PathBuf, found: String, supported: &'static str },
    /// Dimensions that do not describe a volume: a zero or negative size, an array that
    /// is not 2-D or 3-D, a size beyond the `i32` voxel coordinates.
    #[error("{}: bad dimensions: {reason}", .path.display())]
    BadDimensions { path: PathBuf, reason: String },
    /// A NIfTI file holding several volumes (a time series, vectors): `dims` are
    /// `dim[1..=dim[0]]`, `volumes` the product of `dim[4..]`.
    #[error(
        "{}: the image has dimensions {dims:?}, i.e. {volumes} volumes of {}×{}×{} voxels; \
         only one volume can be segmented (dimensions 4 to 7 must be 1): extract one first, \
         e.g. with `fslroi in out 0 1`",
        .path.display(), .dims[0], .dims[1], .dims[2]
    )]
    Unsupported4D { path: PathBuf, dims: Vec<i64>, volumes: u64 },
    /// A feature of the format that is not read (NIfTI-2, `.hdr`/`.img` pairs, ...).
    #[error("{}: {what} not supported", .path.display())]
    Unsupported { path: PathBuf, what: String },
    /// A PNG pixel with colour: only greyscale pictures are read.
    #[error(
        "{}: pixel (x, y) = ({x}, {y}) has colour (r, g, b) = ({}, {}, {}); only greyscale \
         PNGs are read (an RGB picture is accepted when R = G = B everywhere): convert it \
         to greyscale first",
        .path.display(), .rgb[0], .rgb[1], .rgb[2]
    )]
    NotGreyscale { path: PathBuf, x: usize, y: usize, rgb: [u16; 3] },
    /// A NaN or infinite intensity (after NIfTI's scaling; a value beyond the `f32` range
    /// also reads as infinite); `voxel` is `(x, y, z)`, the first in x-fastest order.
    #[error(
        "{}: voxel (x, y, z) = ({}, {}, {}) is {value}; every intensity must be a finite \
         number",
        .path.display(), .voxel[0], .voxel[1], .voxel[2]
    )]
    NonFinite { path: PathBuf, voxel: [usize; 3], value: f32 },
    /// A spacing that is zero, negative or not finite; `from` says where it came from.
    #[error(
        "{}: bad spacing {value} along {axis} ({from}): a spacing must be finite and > 0",
        .path.display()
    )]
    BadSpacing { path: PathBuf, axis: char, value: f64, from: String },
    /// A NIfTI placement (`which`: "sform" or "qform") that is not finite or invertible.
    #[error("{}: bad {which}: {reason}", .path.display())]
    BadTransform { path: PathBuf, which: &'static str, reason: String },
    /// An output the format cannot hold (a float or 3-D image as PNG).
    #[error("{}: cannot write {what}: {reason}", .path.display())]
    CannotWrite { path: PathBuf, what: &'static str, reason: String },
    /// Data of the wrong length for the image they are written like.
    #[error(
        "{}: the {what} to write holds {found} values but the image has {expected} voxels",
        .path.display()
    )]
    WrongLength { path: PathBuf, what: &'static str, expected: usize, found: usize },
    /// A mask value other than 0 or 1; `voxel` is `(x, y, z)`.
    #[error(
        "{}: mask value {value} at voxel (x, y, z) = ({}, {}, {}): a mask holds 0 or 1",
        .path.display(), .voxel[0], .voxel[1], .voxel[2]
    )]
    BadMask { path: PathBuf, voxel: [usize; 3], value: u8 },
}

/// A file format, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    /// NIfTI-1 in one file: `.nii`, or `.nii.gz` when `compressed`.
    Nifti { compressed: bool },
    /// NumPy `.npy`.
    Npy,
    /// PNG.
    Png,
}

impl FileFormat {
    /// The format a file name's extension names (case-insensitive), else
    /// [`ImageError::UnsupportedFormat`].
    pub fn from_path(path: &Path) -> Result<FileFormat, ImageError> {
        let name = path.file_name().map(|n| n.to_string_lossy().to_lowercase());
        match name.as_deref() {
            Some(n) if n.ends_with(".nii.gz") && n.len() > 7 => {
                Ok(FileFormat::Nifti { compressed: true })
            }
            Some(n) if n.ends_with(".nii") && n.len() > 4 => {
                Ok(FileFormat::Nifti { compressed: false })
            }
            Some(n) if n.ends_with(".npy") && n.len() > 4 => Ok(FileFormat::Npy),
            Some(n) if n.ends_with(".png") && n.len() > 4 => Ok(FileFormat::Png),
            _ => Err(ImageError::UnsupportedFormat { path: path.to_path_buf() }),
        }
    }
}

/// An image read by [`load`] (or made in memory, [`LoadedImage::from_image`]) with what
/// writing results in its format needs.
#[derive(Clone, Debug)]
pub struct LoadedImage {
    /// The intensities, spacing and placement.
    pub image: Image,
    /// Where the image came from.
    pub source: Source,
}

impl LoadedImage {
    /// An image made in memory ([`Source::Memory`]): written as a 3-D volume, with a
    /// NIfTI header of its own.
    pub fn from_image(image: Image) -> LoadedImage {
        LoadedImage { image, source: Source::Memory }
    }

    /// Whether the input was two-dimensional: a PNG, a 2-D `.npy`, a NIfTI file with
    /// `dim[0] ≤ 2`. Outputs keep it (a `.npy` of shape `(ny, nx)`, a NIfTI `dim[0] = 2`).
    pub fn is_2d_source(&self) -> bool {
        match &self.source {
            Source::Nifti(n) => n.header.dim[0] <= 2,
            Source::Npy { ndim, .. } => *ndim == 2,
            Source::Png { .. } => true,
            Source::Memory => false,
        }
    }

    /// Number of voxels by [`Image::dims`] (not by the length of [`Image::data`], which
    /// a caller may have moved out).
    fn voxel_count(&self) -> usize {
        self.image.dims.iter().product()
    }
}

/// Where a [`LoadedImage`] came from: what writing back in its format needs.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum Source {
    /// A NIfTI-1 file; its header is kept.
    Nifti(NiftiSource),
    /// A `.npy` file: `ndim` is 2 (`(ny, nx)`) or 3 (`(nz, ny, nx)`); `dtype` as written
    /// in its header (`'<i2'`).
    Npy { ndim: usize, dtype: String, fortran_order: bool },
    /// A PNG file of the given bit depth (1 to 16).
    Png { bit_depth: u8 },
    /// Made in memory.
    Memory,
}

/// What is kept of a NIfTI input: its header (without extensions).
#[derive(Clone, Debug)]
pub struct NiftiSource {
    header: Box<::nifti::NiftiHeader>,
    compressed: bool,
}

impl NiftiSource {
    /// Whether the file was a `.nii.gz`.
    pub fn compressed(&self) -> bool {
        self.compressed
    }

    /// The header's `datatype` code (2 = `uint8`, 4 = `int16`, 16 = `float32`, ...).
    pub fn datatype(&self) -> i16 {
        self.header.datatype
    }

    /// The header's `sform_code` (> 0: the `sform` places the image).
    pub fn sform_code(&self) -> i16 {
        self.header.sform_code
    }

    /// The header's `qform_code` (> 0: the `qform` places the image, unless the `sform`
    /// does).
    pub fn qform_code(&self) -> i16 {
        self.header.qform_code
    }

    /// The header's `dim` (`dim[0]` dimensions, then the sizes).
    pub fn dim(&self) -> [i16; 8] {
        self.header.dim.map(|d| d as i16)
    }
}

/// Reads an image; the format is chosen by the extension ([`FileFormat::from_path`]).
/// `spacing`, when given, replaces the file's spacing (see the module docs for what it
/// means for a NIfTI file's placement); it must be finite and > 0.
///
/// Every problem is an [`ImageError`] naming the file, found before any allocation the
/// file's size does not justify.
pub fn load(path: &Path, spacing: Option<[f64; 3]>) -> Result<LoadedImage, ImageError> {
    let format = FileFormat::from_path(path)?;
    if let Some(s) = spacing {
        check_spacing(path, s, "the spacing argument")?;
    }
    let loaded = match format {
        FileFormat::Nifti { compressed } => nifti::read(path, spacing, compressed)?,
        FileFormat::Npy => npy::read(path, spacing)?,
        FileFormat::Png => png::read(path, spacing)?,
    };
    debug_assert_eq!(loaded.image.data.len(), loaded.voxel_count());
    Ok(loaded)
}

/// What is written: a mask ([`save_mask`]) or a float volume ([`save_f32`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// 0/1 per voxel.
    Mask,
    /// `f32` per voxel.
    Float,
}

/// Checks, before any work, that [`save_mask`] (`what = Output::Mask`) or [`save_f32`]
/// can write `path` like `like`: a known extension, a format that can hold the output (no
/// floats and no 3-D volumes as PNG) and a writable location
/// ([`crate::fsutil::check_writable`]; nothing is left behind). Returns the format.
pub fn check_output(
    path: &Path,
    like: &LoadedImage,
    what: Output,
) -> Result<FileFormat, ImageError> {
    let format = output_format(path, like, what)?;
    crate::fsutil::check_writable(path)
        .map_err(|source| ImageError::Io { path: path.to_path_buf(), source })?;
    Ok(format)
}

/// The format of an output, checked against what it holds.
fn output_format(path: &Path, like: &LoadedImage, what: Output) -> Result<FileFormat, ImageError> {
    let format = FileFormat::from_path(path)?;
    if format == FileFormat::Png {
        let cannot = |what, reason: String| ImageError::CannotWrite {
            path: path.to_path_buf(),
            what,
            reason,
        };
        if what == Output::Float {
            return Err(cannot(
                "a float volume as PNG",
                "write it as .nii, .nii.gz or .npy".to_string(),
            ));
        }
        let [nx, ny, nz] = like.image.dims;
        if nz != 1 {
            return Err(cannot(
                "a 3-D mask as PNG",
                format!(
                    "the image has {nz} slices ({nx}×{ny}×{nz}) and a PNG holds one; write \
                     it as .nii, .nii.gz or .npy"
                ),
            ));
        }
        if nx > i32::MAX as usize || ny > i32::MAX as usize {
            return Err(cannot(
                "a mask as PNG",
                format!("{nx}×{ny} pixels exceed PNG's 2³¹ − 1 per side"),
            ));
        }
    }
    Ok(format)
}

/// Writes a segmentation mask (`mask[i]` is 0 or 1 for voxel `i`, x fastest, as in
/// [`Image::data`]) in the format of `path`'s extension, like the image `like` (its
/// shape, spacing, placement, and for a NIfTI input its header): `.nii`/`.nii.gz` as
/// `uint8`, `.npy` as `|u1` of the input's 2-D or 3-D shape, `.png` as 8-bit greyscale
/// 0/255 (images with `nz = 1` only). See the module docs for the NIfTI header written.
///
/// The write is atomic ([`crate::fsutil::write_atomic`]): on error an existing `path` is
/// left as it was and nothing else remains.
pub fn save_mask(path: &Path, mask: &[u8], like: &LoadedImage) -> Result<(), ImageError> {
    let format = output_format(path, like, Output::Mask)?;
    check_length(path, "mask", mask.len(), like)?;
    if let Some(i) = mask.par_iter().position_first(|&v| v > 1) {
        return Err(ImageError::BadMask {
            path: path.to_path_buf(),
            voxel: voxel_of(i, like.image.dims),
            value: mask[i],
        });
    }
    let data = Payload::Mask(mask);
    match format {
        FileFormat::Nifti { compressed } => nifti::write(path, like, compressed, data),
        FileFormat::Npy => npy::write(path, like, data),
        FileFormat::Png => png::write_mask(path, like, mask),
    }
}

/// Writes a float volume (`data[i]` for voxel `i`, x fastest) like the image `like`, in
/// the format of `path`'s extension: `.nii`/`.nii.gz` as `float32`, `.npy` as `<f4` of the
/// input's 2-D or 3-D shape. Every value must be finite ([`ImageError::NonFinite`]), so
/// that [`load`] reads back what was written. Atomic, as [`save_mask`].
pub fn save_f32(path: &Path, data: &[f32], like: &LoadedImage) -> Result<(), ImageError> {
    let format = output_format(path, like, Output::Float)?;
    check_length(path, "float volume", data.len(), like)?;
    check_finite(path, like.image.dims, data)?;
    let data = Payload::Float(data);
    match format {
        FileFormat::Nifti { compressed } => nifti::write(path, like, compressed, data),
        FileFormat::Npy => npy::write(path, like, data),
        FileFormat::Png => unreachable!("refused by output_format"),
    }
}

/// The voxels of an output.
#[derive(Clone, Copy)]
enum Payload<'a> {
    Mask(&'a [u8]),
    Float(&'a [f32]),
}

impl Payload<'_> {
    /// Writes the voxels: mask bytes as they are, floats little-endian in chunks.
    fn write_to(&self, w: &mut dyn std::io::Write) -> std::io::Result<()> {
        match self {
            Payload::Mask(m) => w.write_all(m),
            Payload::Float(f) => {
                let mut buf = Vec::with_capacity(voxels::CHUNK);
                for chunk in f.chunks(voxels::CHUNK / 4) {
                    buf.clear();
                    buf.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
                    w.write_all(&buf)?;
                }
                Ok(())
            }
        }
    }
}

fn check_length(
    path: &Path,
    what: &'static str,
    found: usize,
    like: &LoadedImage,
) -> Result<(), ImageError> {
    let expected = like.voxel_count();
    if found == expected {
        Ok(())
    } else {
        Err(ImageError::WrongLength { path: path.to_path_buf(), what, expected, found })
    }
}

/// `(x, y, z)` of index `i` (x fastest).
fn voxel_of(i: usize, dims: [usize; 3]) -> [usize; 3] {
    let [nx, ny, _] = dims;
    [i % nx, (i / nx) % ny, i / (nx * ny)]
}

/// Refuses the first non-finite value (x-fastest order).
fn check_finite(path: &Path, dims: [usize; 3], data: &[f32]) -> Result<(), ImageError> {
    match data.par_iter().position_first(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(ImageError::NonFinite {
            path: path.to_path_buf(),
            voxel: voxel_of(i, dims),
            value: data[i],
        }),
    }
}

/// Refuses a spacing that is not finite and > 0; `from` names its origin.
fn check_spacing(path: &Path, s: [f64; 3], from: &str) -> Result<(), ImageError> {
    match (0..3).find(|&a| !(s[a].is_finite() && s[a] > 0.0)) {
        None => Ok(()),
        Some(a) => Err(ImageError::BadSpacing {
            path: path.to_path_buf(),
            axis: ['x', 'y', 'z'][a],
            value: s[a],
            from: from.to_string(),
        }),
    }
}

/// Refuses `needed` bytes beyond [`crate::memory::limit`] (or not countable: `None`).
fn check_memory(path: &Path, needed: Option<u64>, what: &str) -> Result<(), ImageError> {
    let bytes = needed.map_or(f64::INFINITY, |b| b as f64);
    crate::memory::check(bytes, what).map_err(|e| match e {
        crate::grid::GridError::OutOfMemory { what, needed, limit } => {
            ImageError::TooLarge { path: path.to_path_buf(), what, needed, limit }
        }
        other => ImageError::TooLarge {
            path: path.to_path_buf(),
            what: other.to_string(),
            needed: u64::MAX,
            limit: crate::memory::limit(),
        },
    })
}

/// Refuses dimensions that are 0 or beyond the `i32` voxel coordinates; `shape` describes
/// them in the file's terms for the message.
fn check_dims(path: &Path, dims: [u64; 3], shape: &str) -> Result<[usize; 3], ImageError> {
    let bad = |reason: String| ImageError::BadDimensions { path: path.to_path_buf(), reason };
    if dims.contains(&0) {
        return Err(bad(format!("{shape} has an empty dimension: every size must be ≥ 1")));
    }
    if let Some(a) = (0..3).find(|&a| dims[a] > i32::MAX as u64) {
        return Err(bad(format!(
            "{shape}: {} voxels along {} exceed the i32 voxel coordinates",
            dims[a],
            ['x', 'y', 'z'][a]
        )));
    }
    Ok(dims.map(|d| d as usize))
}

/// `to_world = A · diag(1/s)`: turns a voxel-index → world matrix into the lattice
/// position → world matrix of [`Image::to_world`].
fn lattice_to_world(a: [[f64; 4]; 3], s: [f64; 3]) -> [[f64; 4]; 3] {
    a.map(|row| [row[0] / s[0], row[1] / s[1], row[2] / s[2], row[3]])
}

/// `A = to_world · diag(s)`: the voxel-index → world matrix of an image.
fn index_to_world(to_world: [[f64; 4]; 3], s: [f64; 3]) -> [[f64; 4]; 3] {
    to_world.map(|row| [row[0] * s[0], row[1] * s[1], row[2] * s[2], row[3]])
}
