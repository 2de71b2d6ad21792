//! Scalar images on a regular lattice: the input of segmentation (`crate::segment`), and
//! their files.
//!
//! # Layout and geometry
//! An [`Image`] holds `nx · ny · nz` intensities, **x fastest** (`index = x + nx (y + ny
//! z)`, the memory order of a C-ordered NumPy array of shape `(nz, ny, nx)`), kept in
//! `f32` whatever the file's voxel type. Voxel `(i, j, k)` has its centre at the
//! *lattice position* `(i sx, j sy, k sz)` with the spacing `(sx, sy, sz)` in world units
//! (millimetres for a scan); the level sets of a segmentation live in this frame. The
//! image's placement in the scanner's world (origin and axis directions: for a NIfTI file
//! its `sform`/`qform`, for a MetaImage its `Offset` and `TransformMatrix`, for a NRRD its
//! `space origin` and `space directions`) is [`Image::to_world`], in the file's own world
//! frame (see "World coordinates"): meshes are written through it. A 2D image is a volume
//! with `nz = 1`.
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
//! | `.mha`, `.mhd` | MetaImage (ITK), `NDims` 2 or 3, one channel; `ElementType` `MET_UCHAR`, `MET_CHAR`, `MET_USHORT`, `MET_SHORT`, `MET_UINT`, `MET_INT`, `MET_ULONG`, `MET_LONG`, `MET_ULONG_LONG`, `MET_LONG_LONG`, `MET_FLOAT`, `MET_DOUBLE`, either byte order; voxels after the header (`LOCAL`) or in the data file it names, raw or zlib-compressed; world frame LPS | masks as `MET_UCHAR`, floats as `MET_FLOAT`, little-endian, compressed when the input was; `.mha` in one file, `.mhd` with `NAME.raw` (`NAME.zraw` compressed) beside it |
//! | `.nrrd`, `.nhdr` | NRRD (`NRRD0001` to `NRRD0005`), 2 or 3 spatial axes after at most one non-spatial axis of size 1; every integer type, `float`, `double` under any of their names, either byte order; encodings `raw` and `gzip`; voxels after the header or in its `data file`; world frame the header's `space` | masks as `uint8`, floats as `float` (little-endian), gzip when the input was; `.nrrd` in one file, `.nhdr` with `NAME.raw` (`NAME.raw.gz`) beside it |
//!
//! Every input gets one verdict from [`load`], with one message per kind of bad input
//! ([`ImageError`], naming the file), before anything large is allocated: the sizes a
//! header announces are checked against the file's size (uncompressed files) and against
//! the memory the machine can give ([`crate::memory`]), so a hostile header announcing
//! 2⁴⁰ voxels is refused at once. Every intensity must be finite ([`ImageError::NonFinite`]
//! names the first offending voxel, x fastest). Writes are atomic
//! ([`crate::io::fsutil::write_atomic`]): a failed write leaves an existing file as it was.
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
//! ## MetaImage
//! * The header: `Key = Value` lines (MetaIO's keys, case as MetaIO writes them), each key
//!   at most once, ending with `ElementDataFile`; at most 64 KiB. Required: `NDims` (2 or
//!   3), `DimSize`, `ElementType`, `ElementDataFile`. `ObjectType`, when given, is `Image`;
//!   `ElementNumberOfChannels`, when given, is 1 (vector and colour images are refused);
//!   `BinaryData = False` (voxels as text), `FileFormatVersion` other than 0, and lists of
//!   data files (`LIST`, `%d` patterns) are refused with their own messages. Unknown keys
//!   (`AnatomicalOrientation`, `CenterOfRotation`, `Modality`, ...) are skipped.
//! * Byte order: `BinaryDataByteOrderMSB` or its synonym `ElementByteOrderMSB` (they must
//!   agree when both are given), little-endian when neither is. `MET_LONG` and
//!   `MET_ULONG` are 4 bytes, as in MetaIO. `ElementToIntensityFunction*` are not applied
//!   (ITK does not either).
//! * Geometry: `ElementSpacing` (else `ElementSize`, else 1); `Offset` (or its synonyms
//!   `Position`, `Origin`; they must agree when several are given); `TransformMatrix` (or
//!   `Rotation`, `Orientation`), which lists the direction of axis x, then of y, then of
//!   z. With `D` the directions as columns and `s` the spacing, `A = [D · diag(s) |
//!   Offset]` and `to_world = [D | Offset]` exactly (a spacing argument `s'` makes it
//!   `D · diag(s / s')`). A 2-D image is embedded with z along (0, 0, 1).
//! * Data: after the header line `ElementDataFile = LOCAL`, else in the named file
//!   (relative to the header's directory, or absolute; it must exist,
//!   [`ImageError::DataFile`]); `HeaderSize = k` starts the voxels at byte k of that file
//!   (of the `.mha` for `LOCAL`, as MetaIO does), `-1` at its end. `CompressedData = True`:
//!   a zlib stream (gzip is recognised too), checked against `CompressedDataSize` when
//!   given, read to its end so that its checksum is verified. Bytes after the voxels are
//!   ignored.
//!
//! ## NRRD
//! * The header: the magic `NRRD0001` to `NRRD0005`, then `field: description` lines
//!   (`key:=value` pairs and `#` comments skipped), ended by a blank line (or, in a header
//!   naming a `data file`, by the end of the file); at most 64 KiB. Field names are read
//!   without case and spaces (`data file`, `datafile`); each at most once; fields not
//!   needed (`content`, `units`, `axis mins`, `centerings`, `measurement frame`, ...) are
//!   skipped. Required: `type`, `dimension`, `sizes`, `encoding`, and `endian` for types
//!   wider than a byte. Other encodings (`ascii`, `hex`, `bzip2`, ...), `block` data and
//!   lists of data files are refused with their own messages.
//! * Axes: 2 or 3 spatial axes (x fastest, as the file stores them), possibly after one
//!   leading non-spatial axis of size 1 (its space direction `none` or its kind not
//!   `domain`/`space`, or any leading axis of a 4-D array); a non-spatial axis of more
//!   than one sample (a vector, colour or time series image), or one elsewhere, is refused.
//! * Geometry: with `space` (`left-posterior-superior`/`LPS`, `right-anterior-superior`/
//!   `RAS`, `left-anterior-superior`/`LAS`, `scanner-xyz`, `3D-right-handed`,
//!   `3D-left-handed`; spaces with time are refused) or `space dimension` (2 or 3),
//!   `space directions` `d_i` and `space origin` `o` give `A = [d_0 d_1 d_2 | o]`, the
//!   spacing `|d_i|` (NRRD has no other), `to_world = A · diag(1/s)`; a 2-D image in 3-D
//!   space gets the unit normal of its plane as its z axis. Without a space, `spacings`
//!   (`nan` is 1, as ITK reads it) and the identity placement; `axis mins` are not read.
//!   `spacings` with `space directions` on the same axis, vectors of the wrong length,
//!   parallel or zero directions are refused.
//! * Data: after the header, else in the `data file` (relative to the header's
//!   directory, or absolute; it must exist); `line skip` lines then `byte skip` bytes
//!   skipped (for gzip, the bytes of the decompressed stream), `byte skip: -1` for data at
//!   the end of a raw file; gzip read to its end. Bytes after the voxels are ignored.
//!
//! ## The spacing argument
//! `load(path, Some(spacing))` replaces the file's spacing (NIfTI's `pixdim`,
//! MetaImage's `ElementSpacing`, NRRD's lengths of `space directions` or `spacings`, and
//! the default `(1, 1, 1)` of `.npy` and PNG); it is checked as above and allowed for
//! every format. For a placed image (NIfTI by its `sform` or `qform`, MetaImage, NRRD) the
//! placement is kept: voxel `(i, j, k)` still lands at `A · (i, j, k, 1)` in the world,
//! only the lattice (the frame of distances and curvatures) changes; an unplaced image
//! stays at world = lattice position. It rescues a NIfTI file with a broken `pixdim`
//! unless its placement is a `qform` (which is built from `pixdim`); the placements of
//! MetaImage and NRRD are built from their spacings, which must be valid.
//!
//! ## Writing back
//! [`LoadedImage`] keeps what writing in the input's format needs ([`Source`]): for a
//! NIfTI input its whole header, so that [`save_mask`] and [`save_f32`] to `.nii`/`.nii.gz`
//! write it again — same `dim`, `pixdim` (the file's, whatever the spacing argument),
//! `sform`, `qform` and their codes, `xyzt_units`, `descrip` — with the datatype changed
//! (`uint8` for masks, with `cal_min = 0`, `cal_max = 1`; `float32` for floats), no
//! scaling (`scl_slope = 1`, `scl_inter = 0`), no intent, no extensions, little-endian,
//! data at byte 352. Images from other formats or memory get a header of their own: their
//! spacing in `pixdim`, `A = to_world · diag(sx, sy, sz, 1)` (in RAS for an LPS or LAS
//! input, see "World coordinates") as the `sform` (code 2, aligned), and as the `qform`
//! too (code 2) when `to_world` is a rotation (possibly improper) plus a translation,
//! spatial units unknown. A `.npy` output has the input's 2-D or 3-D shape (2-D for 2-D
//! inputs, [`LoadedImage::is_2d_source`]). An image whose [`Image::dims`] no longer match
//! its input's header (cropped after loading) is not written with that header (NIfTI,
//! MetaImage, NRRD; [`ImageError::CannotWrite`]): make it a [`LoadedImage::from_image`]
//! first.
//!
//! A MetaImage or NRRD input keeps its geometry as its header wrote it ([`MetaSource`],
//! [`NrrdSource`]): an output in the same format (either of its two extensions) repeats
//! it number for number — `NDims`, `DimSize`, `ElementSpacing`, `TransformMatrix`,
//! `Offset`; or the spatial `sizes`, `space`, `space directions`, `space origin` (or
//! `spacings`) — so that it reads back with the input's dims, spacing and `to_world` bit
//! for bit (a leading non-spatial axis of size 1 is not written). Numbers are written in
//! their shortest form that reads back exactly. Other inputs get the image's spacing, the
//! columns of `to_world` as directions and its origin: in a MetaImage converted to LPS,
//! in a NRRD with the frame's `space` (none for `.npy`, PNG and memory images, and for
//! 2-D images, written in `space dimension: 2` as ITK writes them). NRRD has no spacing
//! apart from its directions: an image whose `to_world` columns are not unit vectors (a
//! shear, a NIfTI `sform` scaled unlike `pixdim`) reads back with its voxels in the same
//! place but the lattice spacing `|A column|`. A 2-D input (see
//! [`LoadedImage::is_2d_source`]) lying in the plane z = 0 is written with two axes. The
//! data file of a detached header is written first, then the header, each atomically; a
//! compressed `.mha` says its `CompressedDataSize` (ITK needs it).
//!
//! ## World coordinates
//! [`Image::to_world`] maps into the input file's own world frame,
//! [`LoadedImage::world_frame`]; nothing converts on reading:
//! * NIfTI's world frame (`sform`/`qform` codes 1 to 4) is **RAS+**: x grows to the
//!   subject's Right, y Anterior, z Superior, in millimetres when `xyzt_units` says so.
//! * MetaImage's is ITK's (and DICOM's) **LPS+**: x and y have the opposite sign; NRRD's
//!   is its `space` (LPS, RAS or LAS; no anatomical frame for `scanner-xyz`,
//!   `3D-right-handed`, `3D-left-handed`, a bare `space dimension`, or no space).
//!
//! Meshes written through `to_world` are therefore in LPS for MetaImage inputs, as ITK
//! and 3D Slicer's LPS model files expect. Writing in another format converts between
//! anatomical frames (exactly, by negating rows of the placement,
//! [`WorldFrame::convert`]), so that a mask lands where its input was: a MetaImage input
//! written as NIfTI gets an RAS `sform` (x and y negated), a NIfTI input written as
//! MetaImage an LPS `TransformMatrix` and `Offset`. An image without an anatomical frame
//! is written with its placement as it is.
//!
//! ## `.npy`
//! `arr[z, y, x]` (or `arr[y, x]`) is voxel `(x, y, z)`. Fortran-ordered files are read
//! with a scattering copy into x-fastest order. The spacing is the argument's, `(1, 1, 1)`
//! by default; the placement is the identity. Bytes after the data are an error, as in
//! [`crate::io::npy`]. The header is parsed here by a strict parser (nothing is allocated
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
//! use sparse_levelset::io::image::{self, Image, LoadedImage, IDENTITY};
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

mod meta;
mod nifti;
mod npy;
mod nrrd;
mod png;
mod textheader;
mod voxels;

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
pub const SUPPORTED_EXTENSIONS: &str = ".nii, .nii.gz, .npy, .png, .mha, .mhd, .nrrd, .nhdr";

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
    /// The data file a MetaImage or NRRD header names (`ElementDataFile`, `data file`)
    /// cannot be read; `data` is its path (relative names are taken from the header's
    /// directory).
    #[error("{}: cannot read the data file {} it names: {source}", .path.display(), .data.display())]
    DataFile {
        path: PathBuf,
        data: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The file ends before the data its header announces.
    #[error("{}: truncated file: {detail}", .path.display())]
    Truncated { path: PathBuf, detail: String },
    /// The image needs more memory than the machine can give (or than 64 bits count),
    /// refused before anything is allocated.
    #[error(
        "{}: the image is too large: {what} need about {} but only about {} of memory may \
         be used",
        .path.display(), crate::grid::gib(*.needed), crate::grid::gib(*.limit)
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
    /// A placement that is not finite or invertible; `which` names it: NIfTI's "sform" or
    /// "qform", MetaImage's "TransformMatrix" or "Offset", NRRD's "space directions" or
    /// "space origin".
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

impl crate::error::Error for ImageError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            ImageError::Io { source, .. } | ImageError::DataFile { source, .. } => {
                crate::error::io_kind(source)
            }
            ImageError::UnsupportedFormat { .. } => UnknownFormat,
            ImageError::UnsupportedVoxelType { .. }
            | ImageError::Unsupported4D { .. }
            | ImageError::Unsupported { .. }
            | ImageError::NotGreyscale { .. } => Unsupported,
            ImageError::Corrupt { .. }
            | ImageError::Truncated { .. }
            | ImageError::BadDimensions { .. }
            | ImageError::BadSpacing { .. }
            | ImageError::BadTransform { .. } => CorruptFile,
            ImageError::TooLarge { .. } => OutOfMemory,
            ImageError::NonFinite { .. } | ImageError::BadMask { .. } => InvalidData,
            ImageError::CannotWrite { .. } | ImageError::WrongLength { .. } => InvalidInput,
        }
    }
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
    /// MetaImage: `.mha` (one file), or `.mhd` when `detached` (a header naming a data
    /// file).
    MetaImage { detached: bool },
    /// NRRD: `.nrrd` (one file), or `.nhdr` when `detached` (a header naming a data file).
    Nrrd { detached: bool },
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
            Some(n) if n.ends_with(".mha") && n.len() > 4 => {
                Ok(FileFormat::MetaImage { detached: false })
            }
            Some(n) if n.ends_with(".mhd") && n.len() > 4 => {
                Ok(FileFormat::MetaImage { detached: true })
            }
            Some(n) if n.ends_with(".nrrd") && n.len() > 5 => {
                Ok(FileFormat::Nrrd { detached: false })
            }
            Some(n) if n.ends_with(".nhdr") && n.len() > 5 => {
                Ok(FileFormat::Nrrd { detached: true })
            }
            _ => Err(ImageError::UnsupportedFormat { path: path.to_path_buf() }),
        }
    }

    /// The extension that names the format (lower case, with its dot).
    pub fn extension(self) -> &'static str {
        match self {
            FileFormat::Nifti { compressed: true } => ".nii.gz",
            FileFormat::Nifti { compressed: false } => ".nii",
            FileFormat::Npy => ".npy",
            FileFormat::Png => ".png",
            FileFormat::MetaImage { detached: false } => ".mha",
            FileFormat::MetaImage { detached: true } => ".mhd",
            FileFormat::Nrrd { detached: false } => ".nrrd",
            FileFormat::Nrrd { detached: true } => ".nhdr",
        }
    }
}

/// An image file name split into its stem and its extension as written (`.nii.gz` is one
/// extension), or `None` when the extension names no image format. Detached data files
/// (`.raw`, `.zraw`, `.raw.gz`) are not images: their headers are.
///
/// ```
/// use sparse_levelset::io::image::split_file_name;
///
/// assert_eq!(split_file_name("Brain.NII.GZ"), Some(("Brain", ".NII.GZ")));
/// assert_eq!(split_file_name("scan.raw"), None);
/// ```
pub fn split_file_name(name: &str) -> Option<(&str, &str)> {
    let format = FileFormat::from_path(Path::new(name)).ok()?;
    let stem = name.len().checked_sub(format.extension().len())?;
    Some((&name[..stem], &name[stem..]))
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
    /// `dim[0] ≤ 2`, a MetaImage with `NDims = 2`, a NRRD with two spatial axes. Outputs
    /// keep it (a `.npy` of shape `(ny, nx)`, a NIfTI `dim[0] = 2`, ...).
    pub fn is_2d_source(&self) -> bool {
        match &self.source {
            Source::Nifti(n) => n.header.dim[0] <= 2,
            Source::Npy { ndim, .. } => *ndim == 2,
            Source::Png { .. } => true,
            Source::MetaImage(m) => m.ndim == 2,
            Source::Nrrd(n) => n.ndim == 2,
            Source::Memory => false,
        }
    }

    /// The world frame of [`Image::to_world`]: the input file's own (see the module docs,
    /// "World coordinates").
    pub fn world_frame(&self) -> WorldFrame {
        match &self.source {
            Source::Nifti(n) if n.header.sform_code > 0 || n.header.qform_code > 0 => {
                WorldFrame::Ras
            }
            Source::MetaImage(_) => WorldFrame::Lps,
            Source::Nrrd(n) => n.frame,
            _ => WorldFrame::Unspecified,
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
    /// A MetaImage file (`.mha`, `.mhd`); its geometry is kept.
    MetaImage(MetaSource),
    /// A NRRD file (`.nrrd`, `.nhdr`); its geometry is kept.
    Nrrd(NrrdSource),
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

/// What is kept of a MetaImage input: its geometry as written in its header, so that
/// outputs in MetaImage repeat it exactly.
#[derive(Clone, Debug)]
pub struct MetaSource {
    /// `NDims`: 2 or 3.
    ndim: usize,
    /// `DimSize`, with nz = 1 for `NDims = 2`.
    dims: [usize; 3],
    /// `ElementSpacing` (or `ElementSize`), 1 for z when `NDims = 2`.
    spacing: [f64; 3],
    /// `TransformMatrix`: `axes[i]` is the direction of voxel axis i (embedded in 3-D).
    axes: [[f64; 3]; 3],
    /// `Offset`.
    origin: [f64; 3],
    compressed: bool,
    element_type: &'static str,
}

impl MetaSource {
    /// Whether the voxels were compressed (`CompressedData = True`); outputs in MetaImage
    /// are compressed alike.
    pub fn compressed(&self) -> bool {
        self.compressed
    }

    /// The `ElementType` (`MET_SHORT`, ...).
    pub fn element_type(&self) -> &'static str {
        self.element_type
    }

    /// `NDims`: 2 or 3.
    pub fn ndim(&self) -> usize {
        self.ndim
    }
}

/// What is kept of a NRRD input: its geometry as written in its header (for its spatial
/// axes), so that outputs in NRRD repeat it exactly.
#[derive(Clone, Debug)]
pub struct NrrdSource {
    /// Spatial axes: 2 or 3.
    ndim: usize,
    /// `sizes` of the spatial axes, with nz = 1 for two.
    dims: [usize; 3],
    /// `space` (its full name) or `space dimension`, if any.
    space: Option<&'static str>,
    space_dim: usize,
    /// `space directions` of the spatial axes (`space_dim` components each).
    directions: Option<[[f64; 3]; 3]>,
    /// `space origin`.
    origin: Option<[f64; 3]>,
    /// `spacings` of the spatial axes, as written (NaN for `nan`).
    spacings: Option<[f64; 3]>,
    gzip: bool,
    type_name: &'static str,
    frame: WorldFrame,
}

impl NrrdSource {
    /// Whether the voxels were gzip-compressed; outputs in NRRD are compressed alike.
    pub fn gzip(&self) -> bool {
        self.gzip
    }

    /// The `type` (its standard name: `int16`, `float`, ...).
    pub fn type_name(&self) -> &'static str {
        self.type_name
    }

    /// The `space` (`left-posterior-superior`, ...), if the header names one.
    pub fn space(&self) -> Option<&'static str> {
        self.space
    }
}

/// The world frame of an image's [`Image::to_world`]: each file's own, not converted on
/// reading (see the module docs, "World coordinates").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum WorldFrame {
    /// x to the subject's Right, y Anterior, z Superior (NIfTI placed by a sform or
    /// qform; NRRD with space `right-anterior-superior`).
    Ras,
    /// x Left, y Anterior, z Superior (NRRD with space `left-anterior-superior`).
    Las,
    /// x Left, y Posterior, z Superior: DICOM's and ITK's (MetaImage; NRRD with space
    /// `left-posterior-superior`).
    Lps,
    /// No anatomical frame: `.npy`, PNG, images made in memory, NIfTI without a sform or
    /// qform, NRRD without a space or with a space such as `scanner-xyz` or
    /// `3D-right-handed`.
    Unspecified,
}

impl WorldFrame {
    /// The sign of each world axis relative to RAS, for an anatomical frame.
    fn signs(self) -> Option<[f64; 3]> {
        match self {
            WorldFrame::Ras => Some([1.0, 1.0, 1.0]),
            WorldFrame::Las => Some([-1.0, 1.0, 1.0]),
            WorldFrame::Lps => Some([-1.0, -1.0, 1.0]),
            WorldFrame::Unspecified => None,
        }
    }

    /// A placement (such as [`Image::to_world`]) in this frame, expressed in `to`: the
    /// rows of the world axes on which the two frames point opposite ways are negated
    /// (exactly); unchanged when either frame is [`WorldFrame::Unspecified`].
    ///
    /// ```
    /// use sparse_levelset::io::image::{WorldFrame, IDENTITY};
    /// let ras = WorldFrame::Lps.convert(IDENTITY, WorldFrame::Ras);
    /// assert_eq!(ras[0], [-1.0, 0.0, 0.0, 0.0]);
    /// assert_eq!(ras[2], [0.0, 0.0, 1.0, 0.0]);
    /// ```
    pub fn convert(self, m: [[f64; 4]; 3], to: WorldFrame) -> [[f64; 4]; 3] {
        match (self.signs(), to.signs()) {
            (Some(a), Some(b)) => {
                std::array::from_fn(|r| if a[r] == b[r] { m[r] } else { m[r].map(|v| -v) })
            }
            _ => m,
        }
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
        FileFormat::MetaImage { .. } => meta::read(path, spacing)?,
        FileFormat::Nrrd { .. } => nrrd::read(path, spacing)?,
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
/// ([`crate::io::fsutil::check_writable`]; nothing is left behind). Returns the format.
pub fn check_output(
    path: &Path,
    like: &LoadedImage,
    what: Output,
) -> Result<FileFormat, ImageError> {
    let format = output_format(path, like, what)?;
    crate::io::fsutil::check_writable(path)
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
                "write it as .nii, .nii.gz, .npy, .mha, .mhd, .nrrd or .nhdr".to_string(),
            ));
        }
        let [nx, ny, nz] = like.image.dims;
        if nz != 1 {
            return Err(cannot(
                "a 3-D mask as PNG",
                format!(
                    "the image has {nz} slices ({nx}×{ny}×{nz}) and a PNG holds one; write \
                     it as .nii, .nii.gz, .npy, .mha, .mhd, .nrrd or .nhdr"
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
/// The write is atomic ([`crate::io::fsutil::write_atomic`]): on error an existing `path` is
/// left as it was and nothing else remains.
pub fn save_mask(path: &Path, mask: &[u8], like: &LoadedImage) -> Result<(), ImageError> {
    let format = output_format(path, like, Output::Mask)?;
    check_length(path, "mask", mask.len(), like)?;
    if let Some(i) = crate::storage::dense::first_position(mask, |&v| v > 1) {
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
        FileFormat::MetaImage { detached } => meta::write(path, like, detached, data),
        FileFormat::Nrrd { detached } => nrrd::write(path, like, detached, data),
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
        FileFormat::MetaImage { detached } => meta::write(path, like, detached, data),
        FileFormat::Nrrd { detached } => nrrd::write(path, like, detached, data),
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
    match crate::storage::dense::first_position(data, |v| !v.is_finite()) {
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
