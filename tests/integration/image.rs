//! Image input/output (`sparse_levelset::io::image`): every format read and written, the
//! NIfTI placements (sform, qform, none), scaling, and every kind of bad input, including
//! hostile headers refused without allocating. Input files are made by hand here, byte by
//! byte from the formats' specifications (NIfTI-1: the offsets of `nifti1.h`), so that the
//! reader is checked against the formats rather than against the library's own writer;
//! the written NIfTI files are read back with the `nifti` crate.

use flate2::write::GzEncoder;
use nifti::NiftiObject;
use sparse_levelset::io::image::{
    self, check_output, save_f32, save_mask, FileFormat, Image, ImageError, LoadedImage, Output,
    Source, IDENTITY,
};
use std::fs;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use crate::common::alloc::largest_allocation;
use crate::common::TempDir;

// ---------------------------------------------------------------------------------------
// Helpers.

fn gz(bytes: &[u8]) -> Vec<u8> {
    let mut e = GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// A NIfTI-1 header, serialized by hand at the offsets of `nifti1.h`.
#[derive(Clone)]
struct Nii {
    sizeof_hdr: i32,
    dim: [i16; 8],
    datatype: i16,
    bitpix: i16,
    pixdim: [f32; 8],
    vox_offset: f32,
    scl_slope: f32,
    scl_inter: f32,
    xyzt_units: u8,
    descrip: &'static str,
    qform_code: i16,
    sform_code: i16,
    /// quatern_b, c, d, qoffset_x, y, z.
    quatern: [f32; 6],
    srow: [[f32; 4]; 3],
    magic: [u8; 4],
    big: bool,
}

impl Nii {
    fn new(dims: &[i16], datatype: i16, bitpix: i16) -> Nii {
        let mut dim = [1i16; 8];
        dim[0] = dims.len() as i16;
        dim[1..=dims.len()].copy_from_slice(dims);
        Nii {
            sizeof_hdr: 348,
            dim,
            datatype,
            bitpix,
            pixdim: [1.0; 8],
            vox_offset: 352.0,
            scl_slope: 0.0,
            scl_inter: 0.0,
            xyzt_units: 2 | 8, // mm, s
            descrip: "hand-made test image",
            qform_code: 0,
            sform_code: 0,
            quatern: [0.0; 6],
            srow: [[0.0; 4]; 3],
            magic: *b"n+1\0",
            big: false,
        }
    }

    /// The header, the extension flag, padding up to `vox_offset`, then `data`.
    fn file(&self, data: &[u8]) -> Vec<u8> {
        let len = (self.vox_offset as usize).max(352);
        let mut b = vec![0u8; len];
        let big = self.big;
        let mut put = |at: usize, bytes: &[u8]| b[at..at + bytes.len()].copy_from_slice(bytes);
        let i16b = |v: i16| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let i32b = |v: i32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let f32b = |v: f32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        put(0, &i32b(self.sizeof_hdr));
        put(38, b"r");
        for (k, d) in self.dim.iter().enumerate() {
            put(40 + 2 * k, &i16b(*d));
        }
        put(70, &i16b(self.datatype));
        put(72, &i16b(self.bitpix));
        for (k, p) in self.pixdim.iter().enumerate() {
            put(76 + 4 * k, &f32b(*p));
        }
        put(108, &f32b(self.vox_offset));
        put(112, &f32b(self.scl_slope));
        put(116, &f32b(self.scl_inter));
        put(123, &[self.xyzt_units]);
        put(148, self.descrip.as_bytes());
        put(252, &i16b(self.qform_code));
        put(254, &i16b(self.sform_code));
        for (k, q) in self.quatern.iter().enumerate() {
            put(256 + 4 * k, &f32b(*q));
        }
        for (r, row) in self.srow.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                put(280 + 16 * r + 4 * c, &f32b(*v));
            }
        }
        put(344, &self.magic);
        b.extend_from_slice(data);
        b
    }
}

/// Bytes of `values` in the given byte order.
macro_rules! bytes_of {
    ($values:expr, $big:expr) => {
        $values
            .iter()
            .flat_map(|v| if $big { v.to_be_bytes().to_vec() } else { v.to_le_bytes().to_vec() })
            .collect::<Vec<u8>>()
    };
}

/// A `.npy` file: version 1.0 header padded to 64 bytes, then `data`.
fn npy(descr: &str, fortran: bool, shape: &str, data: &[u8]) -> Vec<u8> {
    let py = if fortran { "True" } else { "False" };
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': {py}, 'shape': {shape}, }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((h.len() as u16).to_le_bytes());
    b.extend(h.as_bytes());
    b.extend(data);
    b
}

/// A PNG of the given colour type and depth from raw samples (16-bit ones big-endian).
fn png_file(w: u32, h: u32, color: png::ColorType, depth: png::BitDepth, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut writer = enc.write_header().unwrap();
        writer.write_image_data(data).unwrap();
        writer.finish().unwrap();
    }
    out
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-5 + 1e-6 * b.abs()
}

fn assert_matrix(got: &[[f64; 4]; 3], want: &[[f64; 4]; 3]) {
    for r in 0..3 {
        for c in 0..4 {
            assert!(close(got[r][c], want[r][c]), "row {r} col {c}: {got:?} != {want:?}");
        }
    }
}

fn load_err(path: &Path) -> ImageError {
    match image::load(path, None) {
        Ok(_) => panic!("{}: accepted", path.display()),
        Err(e) => {
            let msg = e.to_string();
            let name = path.file_name().unwrap().to_string_lossy();
            assert!(msg.contains(&*name), "message does not name the file: {msg}");
            e
        }
    }
}

// ---------------------------------------------------------------------------------------
// NIfTI.

/// Every voxel type, in both byte orders: values (type extremes included) decoded as the
/// type's value rounded once to f32, x fastest.
#[test]
fn nifti_every_voxel_type_in_both_byte_orders() {
    let dir = TempDir::new("types");
    macro_rules! case {
        ($t:ty, $code:expr, $lo:expr, $hi:expr) => {{
            let vals: Vec<$t> = (0..12)
                .map(|i| match i {
                    0 => $lo,
                    1 => $hi,
                    i => (i as u8 * 3) as $t,
                })
                .collect();
            let want: Vec<f32> = vals.iter().map(|&v| v as f32).collect();
            for big in [false, true] {
                let mut h = Nii::new(&[3, 2, 2], $code, 8 * std::mem::size_of::<$t>() as i16);
                h.big = big;
                h.pixdim = [1.0, 0.5, 2.0, 3.0, 1.0, 1.0, 1.0, 1.0];
                let name = format!("{}-{}.nii", stringify!($t), big);
                let p = dir.file(&name, &h.file(&bytes_of!(vals, big)));
                let l = image::load(&p, None).unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(l.image.dims, [3, 2, 2], "{name}");
                assert_eq!(l.image.spacing, [0.5, 2.0, 3.0], "{name}");
                assert_eq!(l.image.to_world, IDENTITY, "{name}: no placement");
                assert_eq!(l.image.data, want, "{name}");
                match &l.source {
                    Source::Nifti(n) => assert_eq!(n.datatype(), $code),
                    s => panic!("{s:?}"),
                }
            }
        }};
    }
    case!(u8, 2, u8::MIN, u8::MAX);
    case!(i8, 256, i8::MIN, i8::MAX);
    case!(u16, 512, u16::MIN, u16::MAX);
    case!(i16, 4, i16::MIN, i16::MAX);
    case!(u32, 768, u32::MIN, u32::MAX);
    case!(i32, 8, i32::MIN, i32::MAX);
    case!(u64, 1280, u64::MIN, u64::MAX);
    case!(i64, 1024, i64::MIN, i64::MAX);
    case!(f32, 16, f32::MIN, f32::MAX);
    // f64 extremes within the f32 range (beyond it: `non_finite_voxels_are_named`).
    case!(f64, 64, -3.0e38, 1e-300);
}

#[test]
fn nifti_scaling() {
    let dir = TempDir::new("scl");
    let raw: [i16; 4] = [-3, 0, 7, 1000];
    let read = |slope: f32, inter: f32, name: &str| {
        let mut h = Nii::new(&[4], 4, 16);
        (h.scl_slope, h.scl_inter) = (slope, inter);
        image::load(&dir.file(name, &h.file(&bytes_of!(raw, false))), None)
    };
    let l = read(0.5, -10.0, "a.nii").unwrap();
    assert_eq!(l.image.data, [-11.5, -10.0, -6.5, 490.0]);
    assert_eq!(l.image.dims, [4, 1, 1]);
    // Slope 0 means no scaling (the intercept is ignored), as does a NaN slope.
    for (slope, name) in [(0.0, "b.nii"), (f32::NAN, "c.nii")] {
        assert_eq!(read(slope, 5.0, name).unwrap().image.data, [-3.0, 0.0, 7.0, 1000.0]);
    }
    // 0.1 is applied in f64 and rounded once.
    let l = read(0.1, 0.0, "d.nii").unwrap();
    assert_eq!(l.image.data[2], 0.7);
    // A valid slope with a non-finite intercept is refused.
    let e = read(1.0, f32::INFINITY, "e.nii").unwrap_err();
    assert!(matches!(e, ImageError::Corrupt { .. }), "{e}");
    // Scaling that leaves the f32 range is a non-finite intensity.
    let e = read(1e38, 0.0, "f.nii").unwrap_err();
    assert!(matches!(e, ImageError::NonFinite { voxel: [2, 0, 0], .. }), "{e}");
}

/// A qform only: 90° about z (quaternion d = √½), qfac = −1, pixdim (2, 3, 4), offsets.
#[test]
fn nifti_qform_only() {
    let dir = TempDir::new("qform");
    let mut h = Nii::new(&[2, 3, 4], 2, 8);
    h.pixdim = [-1.0, 2.0, 3.0, 4.0, 1.0, 1.0, 1.0, 1.0];
    h.qform_code = 1;
    let s = std::f32::consts::FRAC_1_SQRT_2;
    h.quatern = [0.0, 0.0, s, 10.0, 20.0, 30.0];
    let p = dir.file("q.nii", &h.file(&[0u8; 24]));
    let l = image::load(&p, None).unwrap();
    assert_eq!(l.image.spacing, [2.0, 3.0, 4.0]);
    // R = [[0, −1, 0], [1, 0, 0], [0, 0, 1]], third column times qfac.
    let want = [[0.0, -1.0, 0.0, 10.0], [1.0, 0.0, 0.0, 20.0], [0.0, 0.0, -1.0, 30.0]];
    assert_matrix(&l.image.to_world, &want);
    // Voxel (1, 2, 3) at lattice position (2, 6, 12): A·(1, 2, 3) + t = (4, 22, 18).
    let w = l.image.world([2.0, 6.0, 12.0]);
    assert!(close(w[0], 4.0) && close(w[1], 22.0) && close(w[2], 18.0), "{w:?}");
    // A code of 0 means no qform: the quaternion is ignored.
    h.qform_code = 0;
    let p = dir.file("q0.nii", &h.file(&[0u8; 24]));
    assert_eq!(image::load(&p, None).unwrap().image.to_world, IDENTITY);
    // A quaternion with b² + c² + d² > 1 is renormalised (nifti1_io), not refused.
    h.qform_code = 1;
    h.quatern = [0.0, 0.0, 2.0, 0.0, 0.0, 0.0];
    let p = dir.file("q2.nii", &h.file(&[0u8; 24]));
    let want = [[-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0]];
    assert_matrix(&image::load(&p, None).unwrap().image.to_world, &want);
}

/// An sform (rotation, anisotropic voxels, shear), preferred over a qform.
#[test]
fn nifti_sform_only_and_over_qform() {
    let dir = TempDir::new("sform");
    let mut h = Nii::new(&[2, 3, 4], 16, 32);
    h.pixdim = [1.0, 0.5, 0.7, 2.0, 1.0, 1.0, 1.0, 1.0];
    h.sform_code = 2;
    let a = [[0.0, -0.7, 0.1, -40.0], [0.5, 0.0, 0.0, 12.5], [0.0, 0.0, 2.0, 7.0]];
    h.srow = a.map(|r| r.map(|v| v as f32));
    let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.25).collect();
    let p = dir.file("s.nii", &h.file(&bytes_of!(data, false)));
    let l = image::load(&p, None).unwrap();
    assert_eq!(l.image.spacing, [0.5, 0.7, 2.0]);
    assert_eq!(l.image.data, data);
    for (i, j, k) in [(0, 0, 0), (1, 2, 3), (1, 0, 2)] {
        let w = l.image.world([i as f64 * 0.5, j as f64 * 0.7, k as f64 * 2.0]);
        for r in 0..3 {
            let want = a[r][0] * i as f64 + a[r][1] * j as f64 + a[r][2] * k as f64 + a[r][3];
            assert!(close(w[r], want), "voxel ({i}, {j}, {k}): {w:?}");
        }
    }
    // The sform wins over a qform.
    h.qform_code = 1;
    h.quatern = [0.0, 0.0, 1.0, 100.0, 100.0, 100.0];
    let p = dir.file("sq.nii", &h.file(&bytes_of!(data, false)));
    assert_matrix(&image::load(&p, None).unwrap().image.to_world, &l.image.to_world);
    // A singular or non-finite sform is refused.
    h.srow[2] = [0.0; 4];
    let e = load_err(&dir.file("singular.nii", &h.file(&bytes_of!(data, false))));
    assert!(matches!(e, ImageError::BadTransform { which: "sform", .. }), "{e}");
    h.srow[2] = [0.0, 0.0, f32::NAN, 0.0];
    let e = load_err(&dir.file("nan-sform.nii", &h.file(&bytes_of!(data, false))));
    assert!(matches!(e, ImageError::BadTransform { .. }), "{e}");
}

/// The spacing argument replaces pixdim; a placed image keeps its voxels' world positions.
#[test]
fn nifti_spacing_argument() {
    let dir = TempDir::new("spacing");
    let mut h = Nii::new(&[2, 2, 2], 2, 8);
    h.pixdim = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
    h.sform_code = 1;
    h.srow = [[2.0, 0.0, 0.0, 1.0], [0.0, 2.0, 0.0, 2.0], [0.0, 0.0, 2.0, 3.0]];
    let p = dir.file("a.nii", &h.file(&[0u8; 8]));
    let l = image::load(&p, Some([0.5, 0.25, 4.0])).unwrap();
    assert_eq!(l.image.spacing, [0.5, 0.25, 4.0]);
    let w = l.image.world([0.5, 0.25, 4.0]); // voxel (1, 1, 1)
    assert_eq!(w, [3.0, 4.0, 5.0]);
    // It rescues a zero pixdim of an image without a qform...
    h.pixdim[2] = 0.0;
    let p = dir.file("zero.nii", &h.file(&[0u8; 8]));
    let e = load_err(&p);
    assert!(matches!(&e, ImageError::BadSpacing { axis: 'y', value, .. } if *value == 0.0), "{e}");
    assert!(e.to_string().contains("pixdim[2]"), "{e}");
    assert_eq!(image::load(&p, Some([1.0; 3])).unwrap().image.spacing, [1.0; 3]);
    // ...but not of one placed by its qform, which is built from pixdim.
    h.sform_code = 0;
    h.qform_code = 1;
    let p = dir.file("zero-q.nii", &h.file(&[0u8; 8]));
    assert!(matches!(image::load(&p, Some([1.0; 3])), Err(ImageError::BadSpacing { .. })));
    // The argument itself must be finite and > 0.
    for bad in [[0.0, 1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, f64::NAN]] {
        let e = image::load(&p, Some(bad)).unwrap_err();
        assert!(
            matches!(&e, ImageError::BadSpacing { from, .. } if from.contains("argument")),
            "{e}"
        );
    }
}

#[test]
fn nifti_pixdim_rules() {
    let dir = TempDir::new("pixdim");
    let read = |pixdim: [f32; 4], dims: &[i16], name: &str| {
        let mut h = Nii::new(dims, 2, 8);
        h.pixdim[..4].copy_from_slice(&pixdim);
        let n: i16 = dims.iter().product();
        image::load(&dir.file(name, &h.file(&vec![0u8; n as usize])), None)
    };
    // A negative pixdim is read by its magnitude.
    assert_eq!(
        read([1.0, -0.5, 2.0, 3.0], &[2, 2, 2], "neg.nii").unwrap().image.spacing,
        [0.5, 2.0, 3.0]
    );
    for (pix, axis) in [([1.0, 0.0, 1.0, 1.0], 'x'), ([1.0, 1.0, f32::INFINITY, 1.0], 'y')] {
        let e = read(pix, &[2, 2, 2], "bad.nii").unwrap_err();
        assert!(matches!(e, ImageError::BadSpacing { axis: a, .. } if a == axis), "{e}");
    }
    let e = read([1.0, 1.0, 1.0, f32::NAN], &[2, 2, 2], "badz.nii").unwrap_err();
    assert!(matches!(e, ImageError::BadSpacing { axis: 'z', .. }), "{e}");
    // A 2-D image does not use pixdim[3]: a zero there gives z spacing 1.
    let l = read([1.0, 0.5, 0.25, 0.0], &[2, 3], "2d.nii").unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([2, 3, 1], [0.5, 0.25, 1.0]));
    assert!(l.is_2d_source());
}

#[test]
fn nifti_dimensions() {
    let dir = TempDir::new("dims");
    // 4-D with one volume is read; dim[4..] beyond dim[0] are ignored.
    let mut h = Nii::new(&[2, 2, 2, 1], 2, 8);
    h.dim[5] = 9;
    let l = image::load(&dir.file("4d1.nii", &h.file(&[1u8; 8])), None).unwrap();
    assert_eq!(l.image.dims, [2, 2, 2]);
    // A time series is refused, saying how many volumes it holds.
    let h = Nii::new(&[2, 2, 2, 3], 2, 8);
    let e = load_err(&dir.file("4d.nii", &h.file(&[1u8; 24])));
    assert!(matches!(e, ImageError::Unsupported4D { volumes: 3, .. }), "{e}");
    assert!(e.to_string().contains("3 volumes"), "{e}");
    let h = Nii::new(&[2, 2, 2, 1, 3], 2, 8);
    let e = load_err(&dir.file("5d.nii", &h.file(&[1u8; 24])));
    assert!(matches!(e, ImageError::Unsupported4D { volumes: 3, .. }), "{e}");
    // Zero, negative sizes and dim[0] out of range.
    for (name, dim) in [
        ("zero.nii", [3, 2, 0, 2, 1, 1, 1, 1]),
        ("negative.nii", [3, 2, -2, 2, 1, 1, 1, 1]),
        ("dim0.nii", [0, 2, 2, 2, 1, 1, 1, 1]),
        ("dim0-8.nii", [8, 2, 2, 2, 1, 1, 1, 1]),
    ] {
        let mut h = Nii::new(&[2, 2, 2], 2, 8);
        h.dim = dim;
        let e = load_err(&dir.file(name, &h.file(&[0u8; 8])));
        assert!(matches!(e, ImageError::BadDimensions { .. }), "{name}: {e}");
    }
}

#[test]
fn nifti_gz_and_file_kinds() {
    let dir = TempDir::new("gz");
    let mut h = Nii::new(&[3, 2, 2], 4, 16);
    h.pixdim[1] = 0.75;
    let vals: Vec<i16> = (0..12).map(|i| i * 100 - 600).collect();
    let raw = h.file(&bytes_of!(vals, false));
    let plain = image::load(&dir.file("a.nii", &raw), None).unwrap();
    let packed = image::load(&dir.file("a.nii.gz", &gz(&raw)), None).unwrap();
    assert_eq!(plain.image.data, packed.image.data);
    assert_eq!(packed.image.spacing, [0.75, 1.0, 1.0]);
    assert!(matches!(&packed.source, Source::Nifti(n) if n.compressed()));
    // Upper-case extensions; a multi-member gzip stream (concatenated files).
    assert!(image::load(&dir.file("B.NII.GZ", &gz(&raw)), None).is_ok());
    let multi = [gz(&raw[..100]), gz(&raw[100..])].concat();
    let l = image::load(&dir.file("multi.nii.gz", &multi), None).unwrap();
    assert_eq!(l.image.data, plain.image.data);
    // A .nii.gz that is not gzip, a gzip stream with a bad checksum.
    let e = load_err(&dir.file("notgz.nii.gz", &raw));
    assert!(matches!(e, ImageError::Corrupt { format: "gzip", .. }), "{e}");
    let mut bad = gz(&raw);
    let n = bad.len();
    bad[n - 6] ^= 0xff; // the CRC32 of the trailer
    let e = load_err(&dir.file("crc.nii.gz", &bad));
    assert!(matches!(e, ImageError::Corrupt { .. }), "{e}");
    // NIfTI-2, a header-only NIfTI-1, bad magic, an unknown size field.
    let mut b = raw.clone();
    b[..4].copy_from_slice(&540i32.to_le_bytes());
    let e = load_err(&dir.file("n2.nii", &b));
    assert!(matches!(&e, ImageError::Unsupported { what, .. } if what.contains("NIfTI-2")), "{e}");
    let mut hh = h.clone();
    hh.magic = *b"ni1\0";
    let e = load_err(&dir.file("pair.nii", &hh.file(&bytes_of!(vals, false))));
    assert!(matches!(&e, ImageError::Unsupported { what, .. } if what.contains(".img")), "{e}");
    hh.magic = *b"xyz\0";
    let e = load_err(&dir.file("magic.nii", &hh.file(&bytes_of!(vals, false))));
    assert!(matches!(e, ImageError::Corrupt { .. }), "{e}");
    let e = load_err(&dir.file("text.nii", b"this is not an image at all"));
    assert!(matches!(e, ImageError::Corrupt { .. }), "{e}");
    let e = load_err(&dir.file("empty.nii", b""));
    assert!(matches!(e, ImageError::Corrupt { .. }), "{e}");
    // Unsupported voxel types name themselves.
    for (code, name) in [(32, "complex64"), (128, "RGB24"), (1, "binary"), (77, "77")] {
        let mut hh = h.clone();
        hh.datatype = code;
        let e = load_err(&dir.file("type.nii", &hh.file(&[0u8; 64])));
        assert!(
            matches!(&e, ImageError::UnsupportedVoxelType { found, .. } if found.contains(name)),
            "{e}"
        );
    }
    // vox_offset before the end of the header, or not whole.
    for off in [300.0, 352.5, f32::NAN] {
        let mut hh = h.clone();
        hh.vox_offset = off;
        let e = load_err(&dir.file("off.nii", &hh.file(&bytes_of!(vals, false))));
        assert!(matches!(e, ImageError::Corrupt { .. }), "{off}: {e}");
    }
    // Data further on (extensions skipped), trailing bytes ignored.
    let mut hh = h.clone();
    hh.vox_offset = 400.0;
    let mut b = hh.file(&bytes_of!(vals, false));
    b.extend_from_slice(b"trailing");
    assert_eq!(image::load(&dir.file("later.nii", &b), None).unwrap().image.data, plain.image.data);
    // A missing file and a directory are I/O errors naming the path.
    let e = load_err(&dir.path("missing.nii"));
    assert!(matches!(e, ImageError::Io { .. }), "{e}");
    fs::create_dir(dir.path("adir.nii")).unwrap();
    assert!(matches!(load_err(&dir.path("adir.nii")), ImageError::Io { .. }));
}

#[test]
fn unknown_extensions_are_listed() {
    let dir = TempDir::new("ext");
    for name in ["a.txt", "a.nii.zip", "a", ".nii", "a.hdr", "a.tif"] {
        let e = load_err(&dir.file(name, b"x"));
        assert!(matches!(e, ImageError::UnsupportedFormat { .. }), "{name}: {e}");
        let msg = e.to_string();
        assert!(msg.contains(".nii.gz") && msg.contains(".npy") && msg.contains(".png"), "{msg}");
    }
    assert_eq!(
        FileFormat::from_path(Path::new("x.Nii.Gz")).unwrap(),
        FileFormat::Nifti { compressed: true }
    );
}

// ---------------------------------------------------------------------------------------
// Truncation, corruption and hostile sizes.

/// Every prefix of a valid file is refused without panicking, in every format.
#[test]
fn truncated_files_are_refused() {
    let dir = TempDir::new("trunc");
    let h = Nii::new(&[3, 2, 2], 16, 32);
    let vals: Vec<f32> = (0..12).map(|i| i as f32).collect();
    let nii = h.file(&bytes_of!(vals, false));
    let npy = npy("<f4", false, "(2, 2, 3)", &bytes_of!(vals, false));
    let png = png_file(3, 4, png::ColorType::Grayscale, png::BitDepth::Eight, &[7u8; 12]);
    for (name, full) in
        [("t.nii", nii.clone()), ("t.nii.gz", gz(&nii)), ("t.npy", npy), ("t.png", png)]
    {
        let p = dir.path(name);
        for cut in 0..full.len() {
            fs::write(&p, &full[..cut]).unwrap();
            let r = std::panic::catch_unwind(|| image::load(&p, None));
            match r {
                Ok(Err(_)) => {}
                Ok(Ok(_)) => panic!("{name}: prefix of {cut} bytes accepted"),
                Err(_) => panic!("{name}: prefix of {cut} bytes panicked"),
            }
        }
        fs::write(&p, &full).unwrap();
        assert!(image::load(&p, None).is_ok(), "{name}");
    }
    // The data cut short is Truncated, with the sizes.
    let e = load_err(&dir.file("cut.nii", &nii[..nii.len() - 3]));
    assert!(matches!(&e, ImageError::Truncated { detail, .. } if detail.contains("48")), "{e}");
    let e = load_err(&dir.file("cut.nii.gz", &gz(&nii[..nii.len() - 3])));
    assert!(matches!(e, ImageError::Truncated { .. }), "{e}");
}

/// Random corruption of headers never panics.
#[test]
fn corrupted_headers_never_panic() {
    let dir = TempDir::new("fuzz");
    let mut h = Nii::new(&[3, 2, 2], 4, 16);
    h.qform_code = 1;
    h.sform_code = 1;
    h.srow = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
    let nii = h.file(&[1u8; 24]);
    let npy = npy("<i2", false, "(2, 2, 3)", &[1u8; 24]);
    let mut rng = fastrand::Rng::with_seed(7);
    for (name, full, header) in [("f.nii", nii, 348), ("f.npy", npy, 64)] {
        let p = dir.path(name);
        for _ in 0..400 {
            let mut b = full.clone();
            for _ in 0..rng.usize(1..4) {
                let i = rng.usize(0..header);
                b[i] = rng.u8(..);
            }
            fs::write(&p, &b).unwrap();
            let r = std::panic::catch_unwind(|| image::load(&p, None));
            assert!(r.is_ok(), "{name} panicked on {b:?}");
        }
    }
}

/// Headers announcing 2⁴⁰ voxels are refused at once, allocating nothing of that size.
#[test]
fn hostile_sizes_are_refused_without_allocating() {
    let dir = TempDir::new("hostile");
    let h = Nii::new(&[16384, 16384, 4096], 16, 32); // 2^40 float32 voxels
    let small = h.file(&[0u8; 64]);
    let plain = dir.file("huge.nii", &small);
    let packed = dir.file("huge.nii.gz", &gz(&small));
    let npy_path = dir.file("huge.npy", &npy("<f4", false, "(4096, 16384, 16384)", &[0u8; 64]));
    let t = Instant::now();
    let ((a, b, c), largest) = largest_allocation(|| {
        (image::load(&plain, None), image::load(&packed, None), image::load(&npy_path, None))
    });
    assert!(t.elapsed().as_secs_f64() < 1.0, "took {:?}", t.elapsed());
    assert!(largest < 16 << 20, "allocated {largest} bytes at once");
    // Uncompressed: the file is smaller than announced.
    let e = a.unwrap_err();
    assert!(matches!(&e, ImageError::Truncated { detail, .. } if detail.contains("4398046511104")));
    // Compressed: the size is unknown in advance, the memory check refuses.
    if sparse_levelset::memory::limit() < 1 << 42 {
        let e = b.unwrap_err();
        assert!(matches!(e, ImageError::TooLarge { needed, .. } if needed >= 1 << 42), "{e}");
        assert!(e.to_string().contains("huge.nii.gz"), "{e}");
    }
    assert!(matches!(c, Err(ImageError::Truncated { .. })));
    // A sparse file of the announced size (1 TiB of uint8): the memory check refuses.
    let h = Nii::new(&[16384, 16384, 4096], 2, 8);
    let sparse = dir.file("sparse.nii", &h.file(&[]));
    let grown = fs::OpenOptions::new().write(true).open(&sparse).unwrap().set_len(352 + (1 << 40));
    if grown.is_ok() && sparse_levelset::memory::limit() < 1 << 42 {
        let (r, largest) = largest_allocation(|| image::load(&sparse, None));
        assert!(largest < 16 << 20, "allocated {largest} bytes at once");
        assert!(matches!(r, Err(ImageError::TooLarge { .. })), "{r:?}");
    }
    let _ = fs::remove_file(&sparse);
    // Shapes whose byte count overflows 64 bits.
    let p =
        dir.file("overflow.npy", &npy("<f8", false, "(2147483647, 2147483647, 2147483647)", &[]));
    assert!(matches!(load_err(&p), ImageError::TooLarge { needed: u64::MAX, .. }));
    let p = dir.file("wide.npy", &npy("<f8", false, "(1, 2147483648)", &[]));
    assert!(matches!(load_err(&p), ImageError::BadDimensions { .. }));
}

#[test]
fn non_finite_voxels_are_named() {
    let dir = TempDir::new("nan");
    let mut vals: Vec<f32> = (0..12).map(|i| i as f32).collect();
    vals[5] = f32::NAN; // (2, 1, 0): 2 + nx · 1
    vals[11] = f32::INFINITY;
    let h = Nii::new(&[3, 2, 2], 16, 32);
    let e = load_err(&dir.file("nan.nii", &h.file(&bytes_of!(vals, false))));
    assert!(matches!(e, ImageError::NonFinite { voxel: [2, 1, 0], .. }), "{e}");
    assert!(e.to_string().contains("(2, 1, 0)") && e.to_string().contains("NaN"), "{e}");
    // f64 beyond the f32 range, in a .npy.
    let mut vals = [0.5f64; 12];
    vals[7] = 1e300; // shape (2, 2, 3): x = 7 % 3 = 1, y = (7 / 3) % 2 = 0, z = 7 / 6 = 1
    let e =
        load_err(&dir.file("big.npy", &npy("<f8", false, "(2, 2, 3)", &bytes_of!(vals, false))));
    assert!(
        matches!(e, ImageError::NonFinite { voxel: [1, 0, 1], value, .. } if value.is_infinite())
    );
}

// ---------------------------------------------------------------------------------------
// .npy and PNG.

#[test]
fn npy_dtypes_shapes_and_orders() {
    let dir = TempDir::new("npy");
    // 3-D f64, (nz, ny, nx) = (2, 3, 4): arr[z, y, x] = x + 10 y + 100 z.
    let f = |x: usize, y: usize, z: usize| (x + 10 * y + 100 * z) as f64 - 0.5;
    let c: Vec<f64> = (0..24).map(|i| f(i % 4, (i / 4) % 3, i / 12)).collect();
    let want: Vec<f32> = c.iter().map(|&v| v as f32).collect();
    let p = dir.file("c.npy", &npy("<f8", false, "(2, 3, 4)", &bytes_of!(c, false)));
    let l = image::load(&p, Some([0.5, 1.0, 2.0])).unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([4, 3, 2], [0.5, 1.0, 2.0]));
    assert_eq!((l.image.data.clone(), l.image.to_world), (want.clone(), IDENTITY));
    assert!(matches!(&l.source, Source::Npy { ndim: 3, .. }));
    // The same array in Fortran order (z fastest), big-endian.
    let mut fo = Vec::new();
    for x in 0..4 {
        for y in 0..3 {
            for z in 0..2 {
                fo.push(f(x, y, z));
            }
        }
    }
    let p = dir.file("f.npy", &npy(">f8", true, "(2, 3, 4)", &bytes_of!(fo, true)));
    assert_eq!(image::load(&p, None).unwrap().image.data, want);
    // 2-D i16 (ny, nx) = (3, 4), C and Fortran order.
    let v: Vec<i16> = (0..12).map(|i| i * 1000 - 6000).collect();
    let p = dir.file("i2.npy", &npy("<i2", false, "(3, 4)", &bytes_of!(v, false)));
    let l = image::load(&p, None).unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([4, 3, 1], [1.0; 3]));
    assert_eq!(l.image.data, v.iter().map(|&v| v as f32).collect::<Vec<_>>());
    assert!(l.is_2d_source());
    let vf: Vec<i16> = (0..12).map(|k| v[(k % 3) * 4 + k / 3]).collect();
    let p = dir.file("i2f.npy", &npy("<i2", true, "(3, 4)", &bytes_of!(vf, false)));
    assert_eq!(image::load(&p, None).unwrap().image.data, l.image.data);
    // u8, bool, u4.
    let p = dir.file("u1.npy", &npy("|u1", false, "(1, 2, 3)", &[0, 1, 2, 253, 254, 255]));
    assert_eq!(image::load(&p, None).unwrap().image.data, [0.0, 1.0, 2.0, 253.0, 254.0, 255.0]);
    let p = dir.file("b1.npy", &npy("|b1", false, "(2, 2)", &[0, 1, 1, 0]));
    assert_eq!(image::load(&p, None).unwrap().image.data, [0.0, 1.0, 1.0, 0.0]);
    let u: [u32; 2] = [7, u32::MAX];
    let p = dir.file("u4.npy", &npy(">u4", false, "(1, 2)", &bytes_of!(u, true)));
    assert_eq!(image::load(&p, None).unwrap().image.data, [7.0, u32::MAX as f32]);
    // Refused: other dtypes, other ranks, empty arrays, trailing bytes, bad headers.
    for (name, descr, shape, data, pred) in [
        ("c8.npy", "<c8", "(2, 2)", vec![0u8; 32], "UnsupportedVoxelType"),
        ("f2.npy", "<f2", "(2, 2)", vec![0u8; 8], "UnsupportedVoxelType"),
        ("1d.npy", "<f4", "(4,)", vec![0u8; 16], "BadDimensions"),
        ("4d.npy", "<f4", "(1, 1, 2, 2)", vec![0u8; 16], "BadDimensions"),
        ("empty.npy", "<f4", "(0, 2)", vec![], "BadDimensions"),
        ("trailing.npy", "<f4", "(2, 2)", vec![0u8; 17], "Corrupt"),
        ("short.npy", "<f4", "(2, 2)", vec![0u8; 15], "Truncated"),
    ] {
        let e = load_err(&dir.file(name, &npy(descr, false, shape, &data)));
        assert!(format!("{e:?}").starts_with(pred), "{name}: {e:?}");
    }
    let mut b = npy("<f4", false, "(2, 2)", &[0u8; 16]);
    b[6] = 4;
    assert!(matches!(load_err(&dir.file("v4.npy", &b)), ImageError::Unsupported { .. }));
    let e = load_err(&dir.file("magic.npy", b"\x93NUMPZ\x01\x00"));
    assert!(matches!(e, ImageError::Corrupt { .. }), "{e}");
}

#[test]
fn png_grey_depths_and_colour() {
    let dir = TempDir::new("png");
    use png::{BitDepth::*, ColorType::*};
    // 8-bit 3×2: row 0 is y = 0.
    let p = dir.file("g8.png", &png_file(3, 2, Grayscale, Eight, &[0, 1, 2, 100, 200, 255]));
    let l = image::load(&p, Some([0.3, 0.3, 1.0])).unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([3, 2, 1], [0.3, 0.3, 1.0]));
    assert_eq!(l.image.data, [0.0, 1.0, 2.0, 100.0, 200.0, 255.0]);
    assert!(matches!(l.source, Source::Png { bit_depth: 8 }));
    // 16-bit, big-endian samples.
    let v: [u16; 4] = [0, 1, 40000, 65535];
    let p = dir.file("g16.png", &png_file(2, 2, Grayscale, Sixteen, &bytes_of!(v, true)));
    assert_eq!(image::load(&p, None).unwrap().image.data, [0.0, 1.0, 40000.0, 65535.0]);
    // Grey + alpha: alpha ignored. 1-bit: scaled to 0/255.
    let p = dir.file("ga.png", &png_file(2, 1, GrayscaleAlpha, Eight, &[10, 0, 20, 255]));
    assert_eq!(image::load(&p, None).unwrap().image.data, [10.0, 20.0]);
    let p = dir.file("g1.png", &png_file(3, 1, Grayscale, One, &[0b1010_0000]));
    assert_eq!(image::load(&p, None).unwrap().image.data, [255.0, 0.0, 255.0]);
    // RGB with R = G = B is grey; one coloured pixel is refused, naming it.
    let p = dir.file("rgb.png", &png_file(2, 1, Rgb, Eight, &[5, 5, 5, 9, 9, 9]));
    assert_eq!(image::load(&p, None).unwrap().image.data, [5.0, 9.0]);
    let px = [1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4, 5, 6, 5, 7, 7, 7];
    let p = dir.file("colour.png", &png_file(3, 2, Rgb, Eight, &px));
    let e = load_err(&p);
    assert!(matches!(e, ImageError::NotGreyscale { x: 1, y: 1, rgb: [5, 6, 5], .. }), "{e}");
    // Not a PNG.
    assert!(matches!(load_err(&dir.file("x.png", b"GIF89a....")), ImageError::Corrupt { .. }));
}

// ---------------------------------------------------------------------------------------
// Writing.

/// A mask written like a NIfTI input keeps its header (read back by the `nifti` crate)
/// with the datatype changed to uint8.
#[test]
fn mask_as_nifti_keeps_the_input_header() {
    let dir = TempDir::new("mask-nii");
    for big in [false, true] {
        let mut h = Nii::new(&[3, 2, 2], 4, 16);
        h.big = big;
        h.pixdim = [-1.0, 0.5, 0.7, 2.0, 1.5, 1.0, 1.0, 1.0];
        (h.scl_slope, h.scl_inter) = (2.0, 1.0);
        h.qform_code = 1;
        h.quatern = [0.0, 0.0, 0.5f32.sqrt(), 1.0, 2.0, 3.0];
        h.sform_code = 4;
        h.srow = [[0.5, 0.0, 0.0, -1.0], [0.0, 0.7, 0.0, -2.0], [0.0, 0.0, 2.0, -3.0]];
        let vals: Vec<i16> = (0..12).collect();
        let input = dir.file("in.nii", &h.file(&bytes_of!(vals, big)));
        let l = image::load(&input, None).unwrap();
        let mask: Vec<u8> = l.image.data.iter().map(|&v| (v > 10.0) as u8).collect();
        for name in ["mask.nii", "mask.nii.gz"] {
            let out = dir.path(name);
            save_mask(&out, &mask, &l).unwrap();
            let obj = nifti::ReaderOptions::new().read_file(&out).unwrap();
            let (orig, back) =
                (nifti::NiftiHeader::from_file(&input).unwrap(), obj.header().clone());
            assert_eq!(back.dim, orig.dim);
            assert_eq!(back.pixdim, orig.pixdim);
            assert_eq!((back.sform_code, back.qform_code), (4, 1));
            assert_eq!(
                [back.srow_x, back.srow_y, back.srow_z],
                [orig.srow_x, orig.srow_y, orig.srow_z]
            );
            assert_eq!(
                [
                    back.quatern_b,
                    back.quatern_c,
                    back.quatern_d,
                    back.quatern_x,
                    back.quatern_y,
                    back.quatern_z
                ],
                [
                    orig.quatern_b,
                    orig.quatern_c,
                    orig.quatern_d,
                    orig.quatern_x,
                    orig.quatern_y,
                    orig.quatern_z
                ]
            );
            assert_eq!((back.xyzt_units, &back.descrip), (orig.xyzt_units, &orig.descrip));
            assert_eq!((back.datatype, back.bitpix), (2, 8));
            assert_eq!((back.scl_slope, back.scl_inter), (1.0, 0.0));
            assert_eq!((back.cal_min, back.cal_max), (0.0, 1.0));
            assert_eq!((back.vox_offset, &back.magic), (352.0, b"n+1\0"));
            let data = obj.into_volume().into_nifti_typed_data::<u8>().unwrap();
            assert_eq!(data, mask);
            // And our reader gives the mask in the same place.
            let m = image::load(&out, None).unwrap();
            assert_eq!(m.image.data, mask.iter().map(|&v| v as f32).collect::<Vec<_>>());
            assert_matrix(&m.image.to_world, &l.image.to_world);
            assert_eq!(m.image.spacing, l.image.spacing);
        }
    }
    // An image no longer matching its header is not written with it.
    let input = dir.path("in.nii");
    let mut l = image::load(&input, None).unwrap();
    l.image.dims = [3, 4, 1];
    let e = save_mask(&dir.path("cropped.nii"), &[0; 12], &l).unwrap_err();
    assert!(matches!(e, ImageError::CannotWrite { .. }), "{e}");
    assert!(!dir.path("cropped.nii").exists());
}

/// Float volumes and masks written in every format read back; images without a NIfTI
/// header get one from their spacing and placement (sform, and qform when rigid).
#[test]
fn round_trips_in_every_format() {
    let dir = TempDir::new("rt");
    let data: Vec<f32> = (0..24).map(|i| (i as f32 - 7.5) * 0.125).collect();
    let mask: Vec<u8> = (0..24).map(|i| (i % 3 == 0) as u8).collect();
    // Rotated 90° about x, improper (z flipped), translated: rigid, so a qform exists.
    let rigid = [[1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, -6.0], [0.0, 1.0, 0.0, 7.5]];
    let sheared = [[1.0, 0.5, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
    for (tag, to_world, qform) in [("id", IDENTITY, 2), ("rigid", rigid, 2), ("shear", sheared, 0)]
    {
        let im = Image { dims: [4, 3, 2], spacing: [0.5, 0.25, 3.0], data: data.clone(), to_world };
        let like = LoadedImage::from_image(im);
        for ext in ["nii", "nii.gz", "npy"] {
            let p = dir.path(&format!("{tag}-f.{ext}"));
            save_f32(&p, &data, &like).unwrap();
            let l = image::load(&p, Some([0.5, 0.25, 3.0])).unwrap();
            assert_eq!((l.image.dims, &l.image.data), ([4, 3, 2], &data), "{tag} {ext}");
            if ext != "npy" {
                let plain = image::load(&p, None).unwrap();
                assert_eq!(plain.image.spacing, [0.5, 0.25, 3.0]);
                assert_matrix(&plain.image.to_world, &to_world);
                let h = nifti::NiftiHeader::from_file(&p).unwrap();
                assert_eq!((h.datatype, h.sform_code, h.qform_code), (16, 2, qform), "{tag}");
                assert_eq!(h.dim, [3, 4, 3, 2, 1, 1, 1, 1]);
            }
            let p = dir.path(&format!("{tag}-m.{ext}"));
            save_mask(&p, &mask, &like).unwrap();
            let l = image::load(&p, None).unwrap();
            assert_eq!(l.image.data, mask.iter().map(|&v| v as f32).collect::<Vec<_>>());
            if ext == "npy" {
                let dtype = "'|u1'".to_string();
                assert!(matches!(l.source, Source::Npy { ndim: 3, dtype: d, .. } if d == dtype));
            }
        }
    }
    // The qform alone places the image as the sform does (checked with the sform off).
    let im =
        Image { dims: [4, 3, 2], spacing: [0.5, 0.25, 3.0], data: data.clone(), to_world: rigid };
    let p = dir.path("q.nii");
    save_f32(&p, &data, &LoadedImage::from_image(im)).unwrap();
    let mut b = fs::read(&p).unwrap();
    b[254..256].copy_from_slice(&0i16.to_le_bytes());
    let l = image::load(&dir.file("q-only.nii", &b), None).unwrap();
    assert_matrix(&l.image.to_world, &rigid);
}

/// A `.npy` of shape (2, 3), read as 2-D.
fn assert_2d_npy(p: &Path) {
    let l = image::load(p, None).unwrap();
    assert!(matches!(l.source, Source::Npy { ndim: 2, .. }), "{:?}", l.source);
    assert_eq!(l.image.dims, [3, 2, 1]);
}

/// Outputs keep the input's shape: 2-D stays 2-D, PNG masks are 0/255.
#[test]
fn outputs_keep_the_input_shape() {
    let dir = TempDir::new("shape");
    // A 2-D .npy input: masks as (ny, nx) .npy, as dim[0] = 2 NIfTI, and as PNG.
    let p = dir.file(
        "in.npy",
        &npy("<f4", false, "(2, 3)", &bytes_of!([0f32, 1., 2., 3., 4., 5.], false)),
    );
    let l = image::load(&p, None).unwrap();
    let mask = [0u8, 1, 1, 0, 0, 1];
    save_mask(&dir.path("m.npy"), &mask, &l).unwrap();
    assert_2d_npy(&dir.path("m.npy"));
    save_mask(&dir.path("m.nii"), &mask, &l).unwrap();
    assert_eq!(nifti::NiftiHeader::from_file(dir.path("m.nii")).unwrap().dim[..3], [2, 3, 2]);
    save_mask(&dir.path("m.png"), &mask, &l).unwrap();
    let back = image::load(&dir.path("m.png"), None).unwrap();
    assert_eq!((back.image.dims, back.image.data), ([3, 2, 1], vec![0., 255., 255., 0., 0., 255.]));
    // A PNG input gives PNG and 2-D .npy masks.
    let p = dir
        .file("in.png", &png_file(3, 2, png::ColorType::Grayscale, png::BitDepth::Eight, &[9; 6]));
    let l = image::load(&p, None).unwrap();
    save_mask(&dir.path("p.npy"), &mask, &l).unwrap();
    assert_2d_npy(&dir.path("p.npy"));
    save_f32(&dir.path("p.nii.gz"), &[1.0; 6], &l).unwrap();
    // A 3-D (nz = 2) image cannot be a PNG; floats never are.
    let im = Image { dims: [3, 1, 2], spacing: [1.0; 3], data: vec![0.0; 6], to_world: IDENTITY };
    let like3 = LoadedImage::from_image(im);
    let e = save_mask(&dir.path("m3.png"), &mask, &like3).unwrap_err();
    assert!(
        matches!(e, ImageError::CannotWrite { .. }) && e.to_string().contains("2 slices"),
        "{e}"
    );
    let e = save_f32(&dir.path("f.png"), &[0.0; 6], &l).unwrap_err();
    assert!(matches!(e, ImageError::CannotWrite { .. }), "{e}");
    // A 3-D image with one slice can.
    let im = Image { dims: [3, 2, 1], spacing: [1.0; 3], data: vec![0.0; 6], to_world: IDENTITY };
    save_mask(&dir.path("one-slice.png"), &mask, &LoadedImage::from_image(im)).unwrap();
    assert!(!dir.path("m3.png").exists() && !dir.path("f.png").exists());
}

#[test]
fn bad_outputs_are_refused_and_leave_files_alone() {
    let dir = TempDir::new("atomic");
    let im = Image { dims: [3, 2, 1], spacing: [1.0; 3], data: vec![0.0; 6], to_world: IDENTITY };
    let like = LoadedImage::from_image(im);
    let mask = [1u8, 0, 1, 0, 1, 0];
    let old = dir.file("old.nii", b"previous contents");
    // Refused before writing: wrong length, a value that is not 0/1, non-finite floats, an
    // unknown extension.
    let e = save_mask(&old, &mask[..5], &like).unwrap_err();
    assert!(matches!(e, ImageError::WrongLength { expected: 6, found: 5, .. }), "{e}");
    let e = save_mask(&old, &[0, 0, 0, 0, 2, 0], &like).unwrap_err();
    assert!(matches!(e, ImageError::BadMask { voxel: [1, 1, 0], value: 2, .. }), "{e}");
    let e = save_f32(&old, &[0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0], &like).unwrap_err();
    assert!(matches!(e, ImageError::NonFinite { voxel: [2, 0, 0], .. }), "{e}");
    let e = save_mask(&dir.path("x.tif"), &mask, &like).unwrap_err();
    assert!(matches!(e, ImageError::UnsupportedFormat { .. }), "{e}");
    assert_eq!(fs::read(&old).unwrap(), b"previous contents");
    // A missing directory: an I/O error, nothing created.
    let missing = dir.path("no/such/dir/m.nii.gz");
    let e = save_mask(&missing, &mask, &like).unwrap_err();
    assert!(matches!(e, ImageError::Io { .. }) && e.to_string().contains("m.nii.gz"), "{e}");
    assert!(!dir.path("no").exists());
    assert!(check_output(&missing, &like, Output::Mask).is_err());
    assert!(check_output(&dir.path("ok.npy"), &like, Output::Float).is_ok());
    // The target is a directory: the rename fails, the directory and its content stay.
    let target = dir.path("adir.npy");
    fs::create_dir(&target).unwrap();
    fs::write(target.join("keep"), b"x").unwrap();
    assert!(matches!(save_mask(&target, &mask, &like), Err(ImageError::Io { .. })));
    assert!(target.join("keep").exists());
    // A read-only directory (unless running as root, who may write anyway).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.path("ro");
        fs::create_dir(&ro).unwrap();
        let file = ro.join("m.nii");
        fs::write(&file, b"old mask").unwrap();
        fs::set_permissions(&ro, fs::Permissions::from_mode(0o555)).unwrap();
        let writable = fs::write(ro.join("probe"), b"").is_ok();
        if !writable {
            assert!(matches!(save_mask(&file, &mask, &like), Err(ImageError::Io { .. })));
            assert_eq!(fs::read(&file).unwrap(), b"old mask");
            assert_eq!(fs::read_dir(&ro).unwrap().count(), 1, "no temporary file left");
        }
        fs::set_permissions(&ro, fs::Permissions::from_mode(0o755)).unwrap();
    }
    // Only what the test made remains: no temporary files.
    assert_eq!(dir.names(), ["adir.npy", "old.nii", "ro"]);
    // Overwriting an existing file replaces it whole.
    save_mask(&old, &mask, &like).unwrap();
    assert_eq!(image::load(&old, None).unwrap().image.data, [1., 0., 1., 0., 1., 0.]);
}
