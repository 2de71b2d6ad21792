//! NIfTI-1 single files (`.nii`, `.nii.gz`): the header is parsed by the `nifti` crate
//! (both byte orders); everything it announces is checked here before the voxels are
//! read, and the voxels are decoded here in chunks (see [`super::voxels`]), so that
//! reading holds the `f32` intensities and one chunk, never a raw copy of the file.
//! Writing serializes the 348-byte header itself (the crate's writer needs `ndarray` and
//! writes in place; ours goes through [`crate::io::fsutil::write_atomic`]).

use super::voxels::{self, Rescale, Scalar};
use super::{
    check_dims, check_finite, check_memory, check_spacing, index_to_world, lattice_to_world, Image,
    ImageError, LoadedImage, NiftiSource, Payload, Source, WorldFrame, IDENTITY,
};
use ::nifti::{Endianness, NiftiHeader};
use flate2::bufread::MultiGzDecoder;
use flate2::write::GzEncoder;
use std::fs::File;
use std::io::{self, BufReader, Read, Write};
use std::path::Path;

/// Bytes of a NIfTI-1 header.
const HEADER_LEN: usize = 348;
/// Where the voxels of the files written here start: the header and the 4 bytes of the
/// extension flag (no extensions).
const DATA_OFFSET: usize = 352;
const FORMAT: &str = "NIfTI-1";
/// The voxel types [`read`] decodes, for messages.
const SUPPORTED: &str = "uint8 (2), int8 (256), uint16 (512), int16 (4), uint32 (768), \
                         int32 (8), uint64 (1280), int64 (1024), float32 (16), float64 (64)";

/// NIfTI `datatype` codes.
mod dt {
    pub const UINT8: i16 = 2;
    pub const FLOAT32: i16 = 16;
}

/// `NIFTI_XFORM_ALIGNED_ANAT`: the code of the placements written for images without a
/// NIfTI header of their own.
const XFORM_ALIGNED: i16 = 2;

fn scalar_of(datatype: i16) -> Result<Scalar, String> {
    Ok(match datatype {
        2 => Scalar::U8,
        4 => Scalar::I16,
        8 => Scalar::I32,
        16 => Scalar::F32,
        64 => Scalar::F64,
        256 => Scalar::I8,
        512 => Scalar::U16,
        768 => Scalar::U32,
        1024 => Scalar::I64,
        1280 => Scalar::U64,
        other => {
            let name = match other {
                0 => "unknown",
                1 => "binary (1 bit)",
                32 => "complex64",
                128 => "RGB24",
                1536 => "float128",
                1792 => "complex128",
                2048 => "complex256",
                2304 => "RGBA32",
                _ => "not a NIfTI datatype",
            };
            return Err(format!("{name} (datatype {other})"));
        }
    })
}

/// Reads a `.nii` (or, when `compressed`, `.nii.gz`) file; see the module docs of
/// [`super`] for what is read and checked.
pub(super) fn read(
    path: &Path,
    spacing: Option<[f64; 3]>,
    compressed: bool,
) -> Result<LoadedImage, ImageError> {
    let io_err = |source| ImageError::Io { path: path.to_path_buf(), source };
    let file = File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_dir() {
        return Err(io_err(io::Error::new(io::ErrorKind::IsADirectory, "it is a directory")));
    }
    let buffered = BufReader::with_capacity(1 << 16, file);
    if compressed {
        // Multi-member streams (concatenated gzip files, as `pigz` or `bgzip` may write)
        // are one file.
        read_stream(&mut MultiGzDecoder::new(buffered), path, spacing, None, true)
    } else {
        let len = meta.is_file().then_some(meta.len());
        let mut plain = buffered;
        read_stream(&mut plain, path, spacing, len, false)
    }
}

/// Maps a read failure ([`voxels::stream_error`]; the codec of a `.nii.gz` is gzip).
fn stream_error(path: &Path, compressed: bool, e: io::Error) -> ImageError {
    voxels::stream_error(path, compressed.then_some("gzip"), e)
}

fn read_stream(
    r: &mut impl Read,
    path: &Path,
    spacing_arg: Option<[f64; 3]>,
    file_len: Option<u64>,
    compressed: bool,
) -> Result<LoadedImage, ImageError> {
    let p = || path.to_path_buf();
    let stream_err = |e| stream_error(path, compressed, e);
    let corrupt = |reason: String| ImageError::Corrupt { path: p(), format: FORMAT, reason };

    // The header: its size field says the version and the byte order.
    let mut head = [0u8; HEADER_LEN];
    let got = voxels::read_full(r, &mut head).map_err(stream_err)?;
    if got < 4 {
        return Err(corrupt(format!("the file holds {got} bytes, too few for a header")));
    }
    let size_field = |b: [u8; 4]| [i32::from_le_bytes(b), i32::from_be_bytes(b)];
    let sizes = size_field(head[..4].try_into().expect("4 bytes"));
    if sizes.contains(&540) {
        return Err(ImageError::Unsupported {
            path: p(),
            what: "NIfTI-2 (sizeof_hdr = 540) is".to_string(),
        });
    }
    if !sizes.contains(&(HEADER_LEN as i32)) {
        return Err(corrupt(format!(
            "the header size field is {} (little-endian) / {} (big-endian), not 348",
            sizes[0], sizes[1]
        )));
    }
    if got < HEADER_LEN {
        return Err(ImageError::Truncated {
            path: p(),
            detail: format!("the file ends inside the 348-byte header, after {got} bytes"),
        });
    }
    let header = match NiftiHeader::from_reader(&head[..]) {
        Ok(h) => h,
        Err(::nifti::NiftiError::InvalidFormat) => {
            return Err(corrupt(format!(
                "the magic bytes at offset 344 are {:?}, not \"n+1\\0\"",
                String::from_utf8_lossy(&head[344..348])
            )))
        }
        Err(e) => return Err(corrupt(e.to_string())),
    };
    if &header.magic == b"ni1\0" {
        return Err(ImageError::Unsupported {
            path: p(),
            what: "a header-only NIfTI-1 file (magic \"ni1\", the voxels in a separate .img \
                   file) is"
                .to_string(),
        });
    }
    // The crate takes the byte order from dim[0]; a size field that disagrees means dim[0]
    // is out of range in both orders.
    if header.sizeof_hdr != HEADER_LEN as i32 {
        return Err(ImageError::BadDimensions {
            path: p(),
            reason: "dim[0] is not in 1..=7 in the byte order of the header size".to_string(),
        });
    }

    // Dimensions (stored as signed shorts).
    let dim = header.dim.map(|d| d as i16 as i64);
    let nd = dim[0];
    if !(1..=7).contains(&nd) {
        return Err(ImageError::BadDimensions {
            path: p(),
            reason: format!("dim[0] = {nd}: the number of dimensions must be 1 to 7"),
        });
    }
    let nd = nd as usize;
    if let Some(i) = (1..=nd).find(|&i| dim[i] < 1) {
        return Err(ImageError::BadDimensions {
            path: p(),
            reason: format!("dim[{i}] = {}: every size must be ≥ 1", dim[i]),
        });
    }
    let size = |i: usize| if i <= nd { dim[i] as u64 } else { 1 };
    if nd > 3 {
        let volumes: u64 = (4..=nd).map(size).product();
        if volumes > 1 {
            return Err(ImageError::Unsupported4D {
                path: p(),
                dims: dim[1..=nd].to_vec(),
                volumes,
            });
        }
    }
    let dims = check_dims(path, [size(1), size(2), size(3)], "the image")?;
    let n = dims[0] * dims[1] * dims[2]; // < 2^45: each size < 2^15

    let kind = scalar_of(header.datatype).map_err(|found| ImageError::UnsupportedVoxelType {
        path: p(),
        found,
        supported: SUPPORTED,
    })?;
    let offset = header.vox_offset;
    if !(offset.is_finite() && offset >= DATA_OFFSET as f32 && offset.fract() == 0.0) {
        return Err(corrupt(format!(
            "vox_offset = {offset}: the voxels of a .nii file start at a whole byte offset ≥ 352"
        )));
    }
    let offset = offset as u64;
    let bytes = n as u64 * kind.size() as u64;
    if let Some(len) = file_len {
        let found = len.saturating_sub(offset);
        if found < bytes {
            return Err(ImageError::Truncated {
                path: p(),
                detail: format!(
                    "the header announces {bytes} bytes of voxel data ({}×{}×{} {kind:?}) from \
                     byte {offset}, the file holds {found}",
                    dims[0], dims[1], dims[2]
                ),
            });
        }
    }
    check_memory(
        path,
        Some(n as u64 * 4 + 3 * voxels::CHUNK as u64),
        &format!("its {}×{}×{} intensities", dims[0], dims[1], dims[2]),
    )?;

    // Spacing and placement.
    let used = nd.min(3);
    let pixdim_spacing = || -> Result<[f64; 3], ImageError> {
        let mut s = [1.0; 3];
        for (a, s) in s.iter_mut().enumerate() {
            let v = dec(header.pixdim[a + 1]).abs();
            if v.is_finite() && v > 0.0 {
                *s = v;
            } else if a < used {
                return Err(ImageError::BadSpacing {
                    path: p(),
                    axis: ['x', 'y', 'z'][a],
                    value: header.pixdim[a + 1] as f64,
                    from: format!("pixdim[{}] of the header", a + 1),
                });
            }
        }
        Ok(s)
    };
    let spacing = match spacing_arg {
        Some(s) => s,
        None => pixdim_spacing()?,
    };
    let to_world = if header.sform_code > 0 {
        let a = [header.srow_x, header.srow_y, header.srow_z].map(|r| r.map(dec));
        check_affine(path, "sform", &a)?;
        lattice_to_world(a, spacing)
    } else if header.qform_code > 0 {
        let a = qform_affine(&header, pixdim_spacing()?);
        check_affine(path, "qform", &a)?;
        lattice_to_world(a, spacing)
    } else {
        IDENTITY
    };

    // Scaling: none when scl_slope is 0 (the standard) or not a number (as nibabel).
    let slope = dec(header.scl_slope);
    let inter = dec(header.scl_inter);
    let rescale = if slope == 0.0 || !slope.is_finite() {
        None
    } else if !inter.is_finite() {
        return Err(corrupt(format!("scl_inter = {inter} with scl_slope = {slope}")));
    } else if slope == 1.0 && inter == 0.0 {
        None
    } else {
        Some(Rescale { slope, inter })
    };

    // The voxels.
    let skip = offset - HEADER_LEN as u64;
    let skipped = io::copy(&mut r.take(skip), &mut io::sink()).map_err(stream_err)?;
    if skipped < skip {
        return Err(ImageError::Truncated {
            path: p(),
            detail: format!("the file ends before the voxel data at byte {offset}"),
        });
    }
    let big = header.endianness == Endianness::Big;
    let mut data = Vec::with_capacity(n);
    voxels::read_voxels(r, kind, big, rescale, n, path, &stream_err, |_, chunk| {
        data.extend_from_slice(chunk)
    })?;
    if compressed {
        // To the end of the stream, so that gzip's checksum is verified.
        io::copy(r, &mut io::sink()).map_err(stream_err)?;
    }
    check_finite(path, dims, &data)?;
    let image = Image { dims, spacing, data, to_world };
    let source = Source::Nifti(NiftiSource { header: Box::new(header), compressed });
    Ok(LoadedImage { image, source })
}

/// A header's `float32` as the `f64` of its shortest decimal form: `0.7f32` reads as
/// `0.7`, not `0.699999988079071`, so that spacings and placements written from `f64`
/// values read back as they were (to `f32` precision), and all header values are read
/// alike (the placement divided by the spacing stays exact).
fn dec(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(v as f64)
}

/// Refuses a voxel → world matrix with a non-finite entry or a singular 3×3 part.
fn check_affine(path: &Path, which: &'static str, a: &[[f64; 4]; 3]) -> Result<(), ImageError> {
    let bad = |reason: String| ImageError::BadTransform { path: path.to_path_buf(), which, reason };
    if a.iter().flatten().any(|v| !v.is_finite()) {
        return Err(bad(format!("an entry is not finite: {a:?}")));
    }
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if det == 0.0 {
        return Err(bad(format!("its axes are degenerate (determinant 0): {a:?}")));
    }
    Ok(())
}

/// The voxel → world matrix of the `qform` (NIfTI-1 standard, method 2): rotation from
/// the quaternion `(a, b, c, d)` with `a = √(1 − b² − c² − d²)` (renormalised when that is
/// not positive, as `nifti1_io` does), columns scaled by the spacing `s` and the third by
/// `qfac = pixdim[0]` (−1 when negative, else 1), then the offsets.
fn qform_affine(h: &NiftiHeader, s: [f64; 3]) -> [[f64; 4]; 3] {
    let (mut b, mut c, mut d) = (dec(h.quatern_b), dec(h.quatern_c), dec(h.quatern_d));
    let mut a = 1.0 - (b * b + c * c + d * d);
    if a < 1e-7 {
        let norm = (b * b + c * c + d * d).sqrt();
        (b, c, d) = (b / norm, c / norm, d / norm);
        a = 0.0;
    } else {
        a = a.sqrt();
    }
    let r = [
        [a * a + b * b - c * c - d * d, 2.0 * (b * c - a * d), 2.0 * (b * d + a * c)],
        [2.0 * (b * c + a * d), a * a + c * c - b * b - d * d, 2.0 * (c * d - a * b)],
        [2.0 * (b * d - a * c), 2.0 * (c * d + a * b), a * a + d * d - c * c - b * b],
    ];
    let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
    let scale = [s[0], s[1], s[2] * qfac];
    let offset = [dec(h.quatern_x), dec(h.quatern_y), dec(h.quatern_z)];
    std::array::from_fn(|row| {
        let m = r[row];
        [m[0] * scale[0], m[1] * scale[1], m[2] * scale[2], offset[row]]
    })
}

/// The quaternion `(b, c, d)` and `qfac` of a 3×3 matrix with orthonormal columns
/// (`nifti_mat44_to_quatern` of `nifti1_io`, without its polar decomposition: the
/// caller checks the columns are orthonormal).
fn quaternion_of(m: [[f64; 3]; 3]) -> ([f64; 3], f64) {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let qfac = if det < 0.0 { -1.0 } else { 1.0 };
    let r = m.map(|row| [row[0], row[1], row[2] * qfac]); // a proper rotation
    let (r11, r12, r13) = (r[0][0], r[0][1], r[0][2]);
    let (r21, r22, r23) = (r[1][0], r[1][1], r[1][2]);
    let (r31, r32, r33) = (r[2][0], r[2][1], r[2][2]);
    let trace = r11 + r22 + r33 + 1.0;
    let (a, mut b, mut c, mut d);
    if trace > 0.5 {
        a = 0.5 * trace.sqrt();
        b = 0.25 * (r32 - r23) / a;
        c = 0.25 * (r13 - r31) / a;
        d = 0.25 * (r21 - r12) / a;
    } else {
        let xd = 1.0 + r11 - (r22 + r33);
        let yd = 1.0 + r22 - (r11 + r33);
        let zd = 1.0 + r33 - (r11 + r22);
        if xd > 1.0 {
            b = 0.5 * xd.sqrt();
            c = 0.25 * (r12 + r21) / b;
            d = 0.25 * (r13 + r31) / b;
            a = 0.25 * (r32 - r23) / b;
        } else if yd > 1.0 {
            c = 0.5 * yd.sqrt();
            b = 0.25 * (r12 + r21) / c;
            d = 0.25 * (r23 + r32) / c;
            a = 0.25 * (r13 - r31) / c;
        } else {
            d = 0.5 * zd.sqrt();
            b = 0.25 * (r13 + r31) / d;
            c = 0.25 * (r23 + r32) / d;
            a = 0.25 * (r21 - r12) / d;
        }
        // The quaternion with a ≥ 0, as the standard stores it.
        if a < 0.0 {
            (b, c, d) = (-b, -c, -d);
        }
    }
    ([b, c, d], qfac)
}

/// A header for an image without a NIfTI header of its own (see the module docs of
/// [`super`]), placed in RAS.
fn header_of(path: &Path, like: &LoadedImage) -> Result<NiftiHeader, ImageError> {
    let im = &like.image;
    check_spacing(path, im.spacing, "the image's spacing")?;
    let too_big = im.dims.iter().any(|&d| d > i16::MAX as usize);
    if too_big {
        return Err(ImageError::CannotWrite {
            path: path.to_path_buf(),
            what: "the image as NIfTI-1",
            reason: format!("its dimensions {:?} exceed NIfTI-1's 32767", im.dims),
        });
    }
    let s = im.spacing;
    // In NIfTI's RAS frame (an input in LPS, such as a MetaImage, has x and y negated).
    let to_world = like.world_frame().convert(im.to_world, WorldFrame::Ras);
    let a = index_to_world(to_world, s);
    if a.iter().flatten().any(|v| !v.is_finite() || v.abs() > f32::MAX as f64) {
        return Err(ImageError::CannotWrite {
            path: path.to_path_buf(),
            what: "the image as NIfTI-1",
            reason: format!("its placement {:?} does not fit in float32", im.to_world),
        });
    }
    let ndim = if like.is_2d_source() { 2 } else { 3 };
    // The qform when to_world is a rotation (proper or not) and a translation.
    let m: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| to_world[r][c]));
    let orthonormal = (0..3).all(|i| {
        (0..3).all(|j| {
            let dot: f64 = (0..3).map(|r| m[r][i] * m[r][j]).sum();
            (dot - if i == j { 1.0 } else { 0.0 }).abs() < 1e-6
        })
    });
    let ([b, c, d], qfac, qform_code) = if orthonormal {
        let (q, qfac) = quaternion_of(m);
        (q, qfac, XFORM_ALIGNED)
    } else {
        ([0.0; 3], 1.0, 0)
    };
    let [srow_x, srow_y, srow_z] = a.map(|r| r.map(|v| v as f32));
    let mut h = NiftiHeader {
        dim: [ndim, im.dims[0] as u16, im.dims[1] as u16, im.dims[2] as u16, 1, 1, 1, 1],
        pixdim: [qfac as f32, s[0] as f32, s[1] as f32, s[2] as f32, 0.0, 0.0, 0.0, 0.0],
        // Unknown units: the image's world units are whatever its spacing means.
        xyzt_units: 0,
        regular: b'r',
        sform_code: XFORM_ALIGNED,
        srow_x,
        srow_y,
        srow_z,
        qform_code,
        quatern_b: b as f32,
        quatern_c: c as f32,
        quatern_d: d as f32,
        quatern_x: if orthonormal { a[0][3] as f32 } else { 0.0 },
        quatern_y: if orthonormal { a[1][3] as f32 } else { 0.0 },
        quatern_z: if orthonormal { a[2][3] as f32 } else { 0.0 },
        ..NiftiHeader::default()
    };
    h.set_description(&b"sparse-levelset"[..]).expect("short description");
    Ok(h)
}

/// Writes `data` like `like` as `.nii` (or `.nii.gz`), atomically.
pub(super) fn write(
    path: &Path,
    like: &LoadedImage,
    compressed: bool,
    data: Payload<'_>,
) -> Result<(), ImageError> {
    let mut h = match &like.source {
        Source::Nifti(n) => {
            let d = n.header.dim;
            let dims: [usize; 3] =
                std::array::from_fn(|a| if a < d[0] as usize { d[a + 1] as usize } else { 1 });
            if dims != like.image.dims {
                return Err(ImageError::CannotWrite {
                    path: path.to_path_buf(),
                    what: "the image with its input's NIfTI header",
                    reason: format!(
                        "the image has {:?} voxels (x, y, z) but the header says {dims:?}",
                        like.image.dims
                    ),
                });
            }
            (*n.header).clone()
        }
        _ => header_of(path, like)?,
    };
    h.sizeof_hdr = HEADER_LEN as i32;
    h.magic = *b"n+1\0";
    h.vox_offset = DATA_OFFSET as f32;
    h.scl_slope = 1.0;
    h.scl_inter = 0.0;
    (h.intent_code, h.intent_p1, h.intent_p2, h.intent_p3) = (0, 0.0, 0.0, 0.0);
    h.intent_name = [0; 16];
    (h.glmax, h.glmin) = (0, 0);
    match data {
        Payload::Mask(_) => {
            (h.datatype, h.bitpix) = (dt::UINT8, 8);
            (h.cal_min, h.cal_max) = (0.0, 1.0);
        }
        Payload::Float(_) => {
            (h.datatype, h.bitpix) = (dt::FLOAT32, 32);
            (h.cal_min, h.cal_max) = (0.0, 0.0);
        }
    }
    let head = header_bytes(&h);
    let write_all = |w: &mut dyn Write| -> io::Result<()> {
        w.write_all(&head)?;
        data.write_to(&mut *w)
    };
    crate::io::fsutil::write_atomic(path, |w| {
        if compressed {
            let mut gz = GzEncoder::new(w, flate2::Compression::default());
            write_all(&mut gz)?;
            gz.finish()?;
            Ok(())
        } else {
            write_all(w)
        }
    })
    .map_err(|source| ImageError::Io { path: path.to_path_buf(), source })
}

/// The little-endian NIfTI-1 header of `h` (offsets of `nifti1.h`), followed by the four
/// bytes of the extension flag (0: no extensions).
fn header_bytes(h: &NiftiHeader) -> [u8; DATA_OFFSET] {
    struct W {
        b: [u8; DATA_OFFSET],
        at: usize,
    }
    impl W {
        fn put(&mut self, bytes: &[u8]) {
            self.b[self.at..self.at + bytes.len()].copy_from_slice(bytes);
            self.at += bytes.len();
        }
        fn f32s(&mut self, v: &[f32]) {
            v.iter().for_each(|x| self.put(&x.to_le_bytes()));
        }
    }
    let mut w = W { b: [0; DATA_OFFSET], at: 0 };
    w.put(&h.sizeof_hdr.to_le_bytes()); // 0
    w.put(&h.data_type); // 4
    w.put(&h.db_name); // 14
    w.put(&h.extents.to_le_bytes()); // 32
    w.put(&h.session_error.to_le_bytes()); // 36
    w.put(&[h.regular, h.dim_info]); // 38
    h.dim.iter().for_each(|d| w.put(&d.to_le_bytes())); // 40
    w.f32s(&[h.intent_p1, h.intent_p2, h.intent_p3]); // 56
    for v in [h.intent_code, h.datatype, h.bitpix, h.slice_start] {
        w.put(&v.to_le_bytes()); // 68
    }
    w.f32s(&h.pixdim); // 76
    w.f32s(&[h.vox_offset, h.scl_slope, h.scl_inter]); // 108
    w.put(&h.slice_end.to_le_bytes()); // 120
    w.put(&[h.slice_code, h.xyzt_units]); // 122
    w.f32s(&[h.cal_max, h.cal_min, h.slice_duration, h.toffset]); // 124
    w.put(&h.glmax.to_le_bytes()); // 140
    w.put(&h.glmin.to_le_bytes()); // 144
    let mut descrip = [0u8; 80];
    let n = h.descrip.len().min(80);
    descrip[..n].copy_from_slice(&h.descrip[..n]);
    w.put(&descrip); // 148
    w.put(&h.aux_file); // 228
    w.put(&h.qform_code.to_le_bytes()); // 252
    w.put(&h.sform_code.to_le_bytes()); // 254
    w.f32s(&[h.quatern_b, h.quatern_c, h.quatern_d, h.quatern_x, h.quatern_y, h.quatern_z]);
    w.f32s(&h.srow_x); // 280
    w.f32s(&h.srow_y); // 296
    w.f32s(&h.srow_z); // 312
    w.put(&h.intent_name); // 328
    w.put(&h.magic); // 344
    debug_assert_eq!(w.at, HEADER_LEN);
    w.b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_bytes_round_trip_through_the_crate() {
        let mut h = NiftiHeader {
            dim: [3, 4, 5, 6, 1, 1, 1, 1],
            datatype: 4,
            bitpix: 16,
            pixdim: [-1.0, 0.5, 0.75, 2.0, 0.0, 0.0, 0.0, 0.0],
            srow_x: [1.0, 2.0, 3.0, 4.0],
            srow_z: [-1.0, 0.0, 0.5, 9.0],
            quatern_c: 0.25,
            quatern_z: -7.0,
            magic: *b"n+1\0",
            vox_offset: 352.0,
            endianness: Endianness::Little,
            ..NiftiHeader::default()
        };
        h.set_description(&b"hello"[..]).unwrap();
        let bytes = header_bytes(&h);
        assert_eq!(&bytes[348..], &[0, 0, 0, 0]);
        let back = NiftiHeader::from_reader(&bytes[..]).unwrap();
        assert_eq!(back, h);
    }

    #[test]
    fn quaternions_round_trip() {
        // Rotations about each axis (including by π, the branches without a large trace),
        // proper and improper.
        let s2 = std::f64::consts::FRAC_1_SQRT_2;
        let cases: [[[f64; 3]; 3]; 5] = [
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]],
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
            [[s2, 0.0, s2], [0.0, 1.0, 0.0], [-s2, 0.0, s2]],
        ];
        for m in cases {
            let ([b, c, d], qfac) = quaternion_of(m);
            let mut h = NiftiHeader {
                quatern_b: b as f32,
                quatern_c: c as f32,
                quatern_d: d as f32,
                ..NiftiHeader::default()
            };
            h.pixdim[0] = qfac as f32;
            let a = qform_affine(&h, [1.0; 3]);
            for r in 0..3 {
                for col in 0..3 {
                    assert!((a[r][col] - m[r][col]).abs() < 1e-6, "{m:?} -> {a:?}");
                }
            }
        }
    }
}
