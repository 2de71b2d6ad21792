//! MetaImage (`.mha`, `.mhd`) and NRRD (`.nrrd`, `.nhdr`) in `sparse_levelset::io::image`:
//! files written by SimpleITK read as SimpleITK reads them (`tests/data/itk`, with the
//! values SimpleITK reports in `reference.json`), masks and float volumes written back with
//! exactly the input's geometry, hand-made headers for what SimpleITK does not write
//! (big-endian data, every type name, skips, a leading axis), and every kind of bad input:
//! hostile sizes refused without allocating, truncated and fuzzed files never panicking.

use sparse_levelset::io::image::{
    self, save_f32, save_mask, FileFormat, Image, ImageError, LoadedImage, Source, WorldFrame,
    IDENTITY,
};
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::common::alloc::largest_allocation;
use crate::common::TempDir;

// ---------------------------------------------------------------------------------------
// Helpers.

/// Replaces a file by a new one (removed, then written: rewriting a file in place may
/// make the file system flush it at every close, which is slow).
fn rewrite(path: &Path, bytes: &[u8]) {
    let _ = fs::remove_file(path);
    fs::write(path, bytes).unwrap();
}

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/itk")
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + b.abs())
}

/// Whether two placements agree entry by entry within `tol` (relative, plus `tol`).
fn near(a: &[[f64; 4]; 3], b: &[[f64; 4]; 3], tol: f64) -> bool {
    a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
}

/// The voxel index → world matrix `A = to_world · diag(spacing)`.
fn index_to_world(im: &Image) -> [[f64; 4]; 3] {
    let s = im.spacing;
    im.to_world.map(|r| [r[0] * s[0], r[1] * s[1], r[2] * s[2], r[3]])
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

/// Bytes of `values`, little- or big-endian.
macro_rules! bytes_of {
    ($values:expr, $big:expr) => {
        $values
            .iter()
            .flat_map(|v| if $big { v.to_be_bytes().to_vec() } else { v.to_le_bytes().to_vec() })
            .collect::<Vec<u8>>()
    };
}

fn zlib(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// A MetaImage header of `lines` (ending with ElementDataFile), then `data`.
fn mha(lines: &[&str], data: &[u8]) -> Vec<u8> {
    let mut b = (lines.join("\n") + "\n").into_bytes();
    b.extend_from_slice(data);
    b
}

/// A NRRD file: magic, `fields`, a blank line, then `data`.
fn nrrd(fields: &[&str], data: &[u8]) -> Vec<u8> {
    let mut b = format!("NRRD0004\n{}\n\n", fields.join("\n")).into_bytes();
    b.extend_from_slice(data);
    b
}

const MHA_3D: [&str; 5] = [
    "ObjectType = Image",
    "NDims = 3",
    "DimSize = 3 2 2",
    "ElementSpacing = 0.5 1 2",
    "Offset = 1 2 3",
];

// ---------------------------------------------------------------------------------------
// Files written by SimpleITK.

/// Every reference file reads with SimpleITK's size, voxels, spacing and index → world
/// matrix (in LPS: the RAS file's matrix has x and y negated).
#[test]
fn simpleitk_files_read_as_simpleitk_reads_them() {
    let text = fs::read_to_string(data_dir().join("reference.json")).unwrap();
    let reference: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(&text).unwrap();
    assert_eq!(reference.len(), 10);
    for (name, r) in &reference {
        let l = image::load(&data_dir().join(name), None).unwrap_or_else(|e| panic!("{e}"));
        let im = &l.image;
        let nums = |key: &str| -> Vec<f64> {
            r[key].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
        };
        let size = nums("size");
        let d = size.len();
        let dims: Vec<usize> = size.iter().map(|&s| s as usize).chain([1]).take(3).collect();
        assert_eq!(im.dims[..], dims[..], "{name}");
        let values: Vec<f32> = nums("values").iter().map(|&v| v as f32).collect();
        assert_eq!(im.data, values, "{name}");
        for (a, s) in nums("spacing").iter().enumerate() {
            assert!(close(im.spacing[a], *s), "{name}: spacing {:?}", im.spacing);
        }
        let frame = l.world_frame();
        let lps = frame.convert(im.to_world, WorldFrame::Lps);
        let a = index_to_world(&Image { to_world: lps, ..im.clone() });
        let want = r["index_to_world"].as_array().unwrap();
        for row in 0..d {
            let w: Vec<f64> =
                want[row].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            let got: Vec<f64> = a[row][..d].iter().chain([&a[row][3]]).copied().collect();
            for (g, w) in got.iter().zip(&w) {
                assert!(close(*g, *w), "{name}: row {row}: {got:?} != {w:?}");
            }
        }
        if d == 2 {
            assert_eq!(im.to_world[2], [0.0, 0.0, 1.0, 0.0], "{name}");
            assert!(l.is_2d_source());
        }
        let expected_frame = match name.as_str() {
            "ct-ras.nrrd" => WorldFrame::Ras,
            "slice.nrrd" => WorldFrame::Unspecified, // `space dimension: 2`
            _ => WorldFrame::Lps,
        };
        assert_eq!(frame, expected_frame, "{name}");
        match (&l.source, name.as_str()) {
            (Source::MetaImage(m), n) => {
                assert_eq!(m.compressed(), n.contains("zlib"), "{n}");
                assert_eq!(m.ndim(), d);
            }
            (Source::Nrrd(s), n) => assert_eq!(s.gzip(), n.contains("gzip") || n == "words.nhdr"),
            (other, n) => panic!("{n}: {other:?}"),
        }
    }
    // One image in six files: the same voxels and placement (RAS converted to LPS).
    let ct = image::load(&data_dir().join("ct.mha"), None).unwrap();
    for other in ["ct-zlib.mha", "ct.nrrd", "ct-gzip.nrrd", "ct-ras.nrrd"] {
        let l = image::load(&data_dir().join(other), None).unwrap();
        assert_eq!(l.image.data, ct.image.data, "{other}");
        let lps = l.world_frame().convert(l.image.to_world, WorldFrame::Lps);
        assert!(near(&lps, &ct.image.to_world, 1e-12), "{other}: {lps:?}");
    }
}

/// Masks and float volumes written in the input's format (both of its forms) read back
/// with the input's dims, spacing and placement, bit for bit, compressed when it was.
#[test]
fn outputs_keep_the_input_geometry_exactly() {
    let dir = TempDir::new("back");
    for name in [
        "ct.mha",
        "ct-zlib.mha",
        "floats.mhd",
        "ct.nrrd",
        "ct-ras.nrrd",
        "words.nhdr",
        "slice.mha",
        "slice.nrrd",
    ] {
        let l = image::load(&data_dir().join(name), None).unwrap();
        let mask: Vec<u8> = l.image.data.iter().map(|&v| (v > 0.0) as u8).collect();
        let meta = name.ends_with(".mha") || name.ends_with(".mhd");
        let exts: [&str; 2] = if meta { ["mha", "mhd"] } else { ["nrrd", "nhdr"] };
        for ext in exts {
            let stem = name.split('.').next().unwrap();
            let m = dir.path(&format!("{stem}-mask.{ext}"));
            save_mask(&m, &mask, &l).unwrap();
            let back = image::load(&m, None).unwrap();
            assert_eq!(back.image.dims, l.image.dims, "{name} → {ext}");
            assert_eq!(back.image.spacing, l.image.spacing, "{name} → {ext}");
            assert_eq!(back.image.to_world, l.image.to_world, "{name} → {ext}");
            assert_eq!(back.world_frame(), l.world_frame());
            assert_eq!(back.is_2d_source(), l.is_2d_source());
            assert_eq!(back.image.data, mask.iter().map(|&v| v as f32).collect::<Vec<_>>());
            let f = dir.path(&format!("{stem}-phi.{ext}"));
            let phi: Vec<f32> = l.image.data.iter().map(|&v| v * 0.5 - 1.25).collect();
            save_f32(&f, &phi, &l).unwrap();
            let back = image::load(&f, None).unwrap();
            assert_eq!(back.image.to_world, l.image.to_world, "{name} → {ext}");
            assert_eq!(back.image.data, phi);
            match (&l.source, &back.source) {
                (Source::MetaImage(a), Source::MetaImage(b)) => {
                    assert_eq!(a.compressed(), b.compressed());
                    assert_eq!(b.element_type(), "MET_FLOAT");
                }
                (Source::Nrrd(a), Source::Nrrd(b)) => {
                    assert_eq!((a.gzip(), a.space()), (b.gzip(), b.space()));
                    assert_eq!(b.type_name(), "float");
                }
                other => panic!("{other:?}"),
            }
        }
    }
    // The data files of detached headers, named in them.
    let header = fs::read_to_string(dir.path("ct-mask.mhd")).unwrap();
    assert!(header.ends_with("ElementDataFile = ct-mask.raw\n"), "{header}");
    assert_eq!(fs::read(dir.path("ct-mask.raw")).unwrap().len(), 60);
    assert!(dir.path("ct-zlib-mask.zraw").exists());
    let header = fs::read_to_string(dir.path("words-mask.nhdr")).unwrap();
    assert!(header.contains("data file: words-mask.raw.gz\n"), "{header}");
    assert!(header.contains("space: left-posterior-superior\n"), "{header}");
    let header = fs::read(dir.path("ct-zlib-mask.mha")).unwrap();
    assert!(header.windows(21).any(|w| w == b"CompressedData = True"));
}

/// Outputs in another format land in the same physical place: an LPS input written as
/// NIfTI has x and y negated (RAS); a NIfTI input written as MetaImage the other way.
#[test]
fn outputs_in_other_formats_convert_the_frame() {
    let dir = TempDir::new("cross");
    let ct = image::load(&data_dir().join("ct.mha"), None).unwrap();
    let mask: Vec<u8> = ct.image.data.iter().map(|&v| (v > 0.0) as u8).collect();
    let ras = WorldFrame::Lps.convert(ct.image.to_world, WorldFrame::Ras);
    save_mask(&dir.path("m.nii.gz"), &mask, &ct).unwrap();
    let nii = image::load(&dir.path("m.nii.gz"), None).unwrap();
    assert_eq!(nii.world_frame(), WorldFrame::Ras);
    assert!(near(&nii.image.to_world, &ras, 1e-5), "{:?}", nii.image.to_world);
    // NIfTI → MetaImage → NIfTI, and → NRRD (space RAS, kept).
    save_mask(&dir.path("m.mha"), &mask, &nii).unwrap();
    let mha = image::load(&dir.path("m.mha"), None).unwrap();
    assert_eq!(mha.image.to_world, WorldFrame::Ras.convert(nii.image.to_world, WorldFrame::Lps));
    save_mask(&dir.path("m.nrrd"), &mask, &nii).unwrap();
    let n = image::load(&dir.path("m.nrrd"), None).unwrap();
    assert!(matches!(&n.source, Source::Nrrd(s) if s.space() == Some("right-anterior-superior")));
    // The voxels in the same place (NRRD's spacing is the length of its directions, here
    // not quite pixdim: the sform is float32).
    let (a, b) = (index_to_world(&n.image), index_to_world(&nii.image));
    assert!(near(&a, &b, 1e-12), "{a:?} != {b:?}");
    // MetaImage → NRRD: LPS, the same numbers.
    save_mask(&dir.path("lps.nhdr"), &mask, &ct).unwrap();
    let n = image::load(&dir.path("lps.nhdr"), None).unwrap();
    assert_eq!(n.world_frame(), WorldFrame::Lps);
    assert_eq!(n.image.data, mask.iter().map(|&v| v as f32).collect::<Vec<_>>());
    assert!(near(&n.image.to_world, &ct.image.to_world, 1e-12));
    // A PNG (no frame): identity placement written as it is, 2-D kept 2-D.
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, 3, 2);
        enc.set_color(png::ColorType::Grayscale);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[1; 6]).unwrap();
    }
    let like = image::load(&dir.file("in.png", &png_bytes), Some([0.5, 2.0, 1.0])).unwrap();
    for ext in ["mha", "nrrd"] {
        let p = dir.path(&format!("flat.{ext}"));
        save_mask(&p, &[0, 1, 0, 1, 1, 0], &like).unwrap();
        let back = image::load(&p, None).unwrap();
        assert!(back.is_2d_source(), "{ext}");
        assert_eq!((back.image.dims, back.image.spacing), ([3, 2, 1], [0.5, 2.0, 1.0]));
        assert_eq!(back.image.to_world, IDENTITY);
        // Every MetaImage is in ITK's LPS; a NRRD without a space has no frame.
        let frame = if ext == "mha" { WorldFrame::Lps } else { WorldFrame::Unspecified };
        assert_eq!(back.world_frame(), frame);
    }
    assert!(fs::read_to_string(dir.path("flat.mha")).unwrap().contains("NDims = 2\n"));
    assert!(fs::read_to_string(dir.path("flat.nrrd")).unwrap().contains("space dimension: 2\n"));
}

/// Images made in memory (rigid and sheared placements) round-trip through all four
/// extensions; `FileFormat` knows them in any case.
#[test]
fn round_trips_from_memory() {
    let dir = TempDir::new("memory");
    let data: Vec<f32> = (0..24).map(|i| (i as f32 - 7.5) * 0.125).collect();
    let rigid = [[1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, -6.0], [0.0, 1.0, 0.0, 7.5]];
    let sheared = [[1.0, 0.5, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.1]];
    for to_world in [IDENTITY, rigid, sheared] {
        let im = Image { dims: [4, 3, 2], spacing: [0.5, 0.25, 3.0], data: data.clone(), to_world };
        let like = LoadedImage::from_image(im);
        for ext in ["mha", "mhd", "nrrd", "nhdr"] {
            let p = dir.path(&format!("m.{ext}"));
            save_f32(&p, &data, &like).unwrap();
            let l = image::load(&p, None).unwrap();
            assert_eq!((l.image.dims, &l.image.data), ([4, 3, 2], &data), "{ext}");
            // The voxels in the same place.
            let (a, b) = (index_to_world(&l.image), index_to_world(&like.image));
            assert!(near(&a, &b, 1e-12), "{ext}: {a:?} != {b:?}");
            if ext.starts_with("mh") || to_world != sheared {
                // MetaImage keeps directions and spacing as they are; NRRD has no spacing
                // but the length of its directions, which are not unit vectors when sheared.
                assert_eq!(l.image.spacing, [0.5, 0.25, 3.0], "{ext}");
            }
            if ext.starts_with("mh") {
                assert_eq!(l.image.to_world, to_world, "{ext}");
            }
        }
    }
    for (name, format) in [
        ("a.MHA", FileFormat::MetaImage { detached: false }),
        ("a.mhd", FileFormat::MetaImage { detached: true }),
        ("a.Nrrd", FileFormat::Nrrd { detached: false }),
        ("a.NHDR", FileFormat::Nrrd { detached: true }),
    ] {
        assert_eq!(FileFormat::from_path(Path::new(name)).unwrap(), format);
    }
    assert!(FileFormat::from_path(Path::new(".mha")).is_err());
    let e = load_err(&dir.file("x.raw", b""));
    assert!(e.to_string().contains(".mha, .mhd, .nrrd, .nhdr"), "{e}");
}

// ---------------------------------------------------------------------------------------
// Hand-made headers.

/// Every MetaImage element type, in both byte orders (by either key), attached, detached
/// and compressed; HeaderSize, synonyms, ElementSize and the spacing argument.
#[test]
fn metaimage_types_byte_orders_and_options() {
    let dir = TempDir::new("meta");
    let v: Vec<i64> = vec![-3, 0, 1, 2, 5, 7, 9, 11, 13, 100, -100, 42];
    let want: Vec<f32> = v.iter().map(|&x| x as f32).collect();
    for big in [false, true] {
        macro_rules! check {
            ($met:expr, $t:ty) => {{
                let vals: Vec<$t> = v.iter().map(|&x| x as $t).collect();
                let want: Vec<f32> = vals.iter().map(|&x| x as f32).collect();
                let order = if big { "True" } else { "False" };
                for key in ["BinaryDataByteOrderMSB", "ElementByteOrderMSB"] {
                    let mut lines = MHA_3D.to_vec();
                    let bo = format!("{key} = {order}");
                    let et = format!("ElementType = {}", $met);
                    lines.extend([bo.as_str(), et.as_str(), "ElementDataFile = LOCAL"]);
                    let p = dir.file("t.mha", &mha(&lines, &bytes_of!(vals, big)));
                    let l = image::load(&p, None).unwrap_or_else(|e| panic!("{}: {e}", $met));
                    assert_eq!(l.image.data, want, "{} big={big}", $met);
                    assert!(matches!(&l.source, Source::MetaImage(m) if m.element_type() == $met));
                }
            }};
        }
        check!("MET_UCHAR", u8);
        check!("MET_CHAR", i8);
        check!("MET_USHORT", u16);
        check!("MET_SHORT", i16);
        check!("MET_UINT", u32);
        check!("MET_INT", i32);
        check!("MET_ULONG", u32);
        check!("MET_LONG", i32);
        check!("MET_ULONG_LONG", u64);
        check!("MET_LONG_LONG", i64);
        check!("MET_FLOAT", f32);
        check!("MET_DOUBLE", f64);
    }
    let raw = bytes_of!(v.iter().map(|&x| x as i16).collect::<Vec<_>>(), false);
    let head = |extra: &[&str], file: &str| {
        let mut l = MHA_3D.to_vec();
        l.push("ElementType = MET_SHORT");
        l.extend_from_slice(extra);
        let f = format!("ElementDataFile = {file}");
        l.push(&f);
        mha(&l, &[])
    };
    // Detached, with HeaderSize bytes before the data, or -1: at the end.
    let mut prefixed = vec![0xAB; 17];
    prefixed.extend_from_slice(&raw);
    dir.file("prefixed.dat", &prefixed);
    for (extra, file) in
        [(&["HeaderSize = 17"][..], "prefixed.dat"), (&["HeaderSize = -1"][..], "prefixed.dat")]
    {
        let p = dir.file("d.mhd", &head(extra, file));
        assert_eq!(image::load(&p, None).unwrap().image.data, want, "{extra:?}");
    }
    // Attached with HeaderSize counted from the start of the file, and -1.
    let mut f = head(&["HeaderSize = 400"], "LOCAL");
    let at = f.len();
    f.resize(400, b'x');
    f.extend_from_slice(&raw);
    assert!(at < 400);
    assert_eq!(image::load(&dir.file("h.mha", &f), None).unwrap().image.data, want);
    let mut f = head(&["HeaderSize = -1"], "LOCAL");
    f.extend_from_slice(b"ignored bytes");
    f.extend_from_slice(&raw);
    assert_eq!(image::load(&dir.file("end.mha", &f), None).unwrap().image.data, want);
    // Compressed: zlib (with or without its size) and gzip, attached and detached.
    for (extra, payload) in [
        (vec!["CompressedData = True"], zlib(&raw)),
        (vec!["CompressedData = True", "CompressedDataSize = 0"], zlib(&raw)),
        (vec!["CompressedData = True"], gzip(&raw)),
    ] {
        let mut with_size = vec!["CompressedData = True"];
        let size = format!("CompressedDataSize = {}", payload.len());
        with_size.push(&size);
        for e in [&extra, &with_size] {
            let mut f = head(e, "LOCAL");
            f.extend_from_slice(&payload);
            assert_eq!(image::load(&dir.file("z.mha", &f), None).unwrap().image.data, want);
        }
        dir.file("z.zraw", &payload);
        let p = dir.file("z.mhd", &head(&extra, "z.zraw"));
        assert_eq!(image::load(&p, None).unwrap().image.data, want);
    }
    // Synonyms, ElementSize for a missing ElementSpacing, 2-D, the spacing argument.
    let f = mha(
        &[
            "NDims = 2",
            "DimSize = 4 3",
            "ElementSize = 0.5 4",
            "Position = 10 20",
            "Rotation = 0 1 -1 0",
            "ElementType = MET_SHORT",
            "ElementDataFile = LOCAL",
        ],
        &raw,
    );
    let p = dir.file("two.mha", &f);
    let l = image::load(&p, None).unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([4, 3, 1], [0.5, 4.0, 1.0]));
    assert_eq!(
        l.image.to_world,
        [[0.0, -1.0, 0.0, 10.0], [1.0, 0.0, 0.0, 20.0], [0.0, 0.0, 1.0, 0.0]]
    );
    let l = image::load(&p, Some([1.0, 2.0, 1.0])).unwrap();
    // The voxels stay where they were: A = to_world · diag(s) is the file's.
    assert_eq!(index_to_world(&l.image)[0], [0.0, -4.0, 0.0, 10.0]);
    assert_eq!(index_to_world(&l.image)[1], [0.5, 0.0, 0.0, 20.0]);
}

/// NRRD types by every name, both byte orders, skips, detached data, a leading axis of
/// size 1, spacings without a space, and the frames of the spaces.
#[test]
fn nrrd_types_skips_axes_and_spaces() {
    let dir = TempDir::new("nrrd");
    let v: Vec<i64> = vec![-3, 0, 1, 2, 5, 7, 9, 11, 13, 100, -100, 42];
    macro_rules! check {
        ($names:expr, $t:ty) => {{
            let vals: Vec<$t> = v.iter().map(|&x| x as $t).collect();
            let want: Vec<f32> = vals.iter().map(|&x| x as f32).collect();
            for name in $names {
                for big in [false, true] {
                    let t = format!("type: {name}");
                    let e = format!("endian: {}", if big { "big" } else { "little" });
                    let fields = [t.as_str(), "dimension: 3", "sizes: 3 2 2", &e, "encoding: raw"];
                    let p = dir.file("t.nrrd", &nrrd(&fields, &bytes_of!(vals, big)));
                    let l = image::load(&p, None).unwrap_or_else(|e| panic!("{name}: {e}"));
                    assert_eq!(l.image.data, want, "{name} big={big}");
                }
            }
        }};
    }
    check!(["signed char", "int8", "int8_t"], i8);
    check!(["uchar", "unsigned char", "uint8", "uint8_t"], u8);
    check!(["short", "short int", "signed short", "signed short int", "int16", "int16_t"], i16);
    check!(["ushort", "unsigned short", "unsigned short int", "uint16", "uint16_t"], u16);
    check!(["int", "signed int", "int32", "int32_t"], i32);
    check!(["uint", "unsigned int", "uint32", "uint32_t"], u32);
    check!(
        [
            "longlong",
            "long long",
            "long long int",
            "signed long long",
            "signed long long int",
            "int64",
            "int64_t"
        ],
        i64
    );
    check!(
        ["ulonglong", "unsigned long long", "unsigned long long int", "uint64", "uint64_t"],
        u64
    );
    check!(["float"], f32);
    check!(["double"], f64);

    let raw = bytes_of!(v.iter().map(|&x| x as i16).collect::<Vec<_>>(), true);
    let want: Vec<f32> = v.iter().map(|&x| x as f32).collect();
    let base = ["type: short", "dimension: 3", "sizes: 3 2 2", "endian: big"];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    let file = |name: &str, fields: Vec<String>, data: &[u8]| {
        let f: Vec<&str> = fields.iter().map(String::as_str).collect();
        dir.file(name, &nrrd(&f, data))
    };
    // Line and byte skips (in the file for raw data, in the stream for gzip); -1.
    let mut skipped = b"line one\nline two\n".to_vec();
    skipped.extend_from_slice(&[9; 5]);
    skipped.extend_from_slice(&raw);
    let p = file("skip.nrrd", with(&["encoding: raw", "line skip: 2", "byte skip: 5"]), &skipped);
    assert_eq!(image::load(&p, None).unwrap().image.data, want);
    let mut tail = b"anything".to_vec();
    tail.extend_from_slice(&raw);
    let p = file("end.nrrd", with(&["encoding: raw", "byteskip: -1"]), &tail);
    assert_eq!(image::load(&p, None).unwrap().image.data, want);
    let mut padded = vec![1u8; 7];
    padded.extend_from_slice(&raw);
    let p = file("gz.nrrd", with(&["encoding: gz", "byte skip: 7"]), &gzip(&padded));
    assert_eq!(image::load(&p, None).unwrap().image.data, want);
    // Detached, relative to the header's directory (a .nrrd header may name a file too).
    fs::create_dir(dir.path("sub")).unwrap();
    fs::write(dir.path("sub/v.raw.gz"), gzip(&raw)).unwrap();
    for name in ["sub/h.nhdr", "sub/h.nrrd"] {
        let mut b = b"NRRD0005\n# a comment\nkey:=value with: colon\n".to_vec();
        for f in with(&["encoding: gzip", "data file: v.raw.gz"]) {
            b.extend_from_slice(f.as_bytes());
            b.push(b'\n');
        }
        let p = dir.file(name, &b); // no blank line: the header ends with the file
        assert_eq!(image::load(&p, None).unwrap().image.data, want, "{name}");
    }
    // A leading non-spatial axis of size 1; spacings without a space (nan is 1).
    let p = file(
        "lead.nrrd",
        vec![
            "type: short".into(),
            "dimension: 4".into(),
            "space: RAS".into(),
            "sizes: 1 3 2 2".into(),
            "space directions: none (0,0,-2) (0.5,0,0) (0,1,0)".into(),
            "kinds: list domain domain domain".into(),
            "endian: big".into(),
            "encoding: raw".into(),
            "space origin: (1, 2, 3)".into(),
        ],
        &raw,
    );
    let l = image::load(&p, None).unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([3, 2, 2], [2.0, 0.5, 1.0]));
    assert_eq!(
        l.image.to_world,
        [[0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 2.0], [-1.0, 0.0, 0.0, 3.0]]
    );
    assert_eq!(l.world_frame(), WorldFrame::Ras);
    assert!(!l.is_2d_source());
    let p = file("sp.nrrd", with(&["encoding: raw", "spacings: 0.5 nan 3"]), &raw);
    let l = image::load(&p, None).unwrap();
    assert_eq!((l.image.spacing, l.image.to_world), ([0.5, 1.0, 3.0], IDENTITY));
    // Written back: the spacings as they were, nan included.
    save_mask(&dir.path("sp-mask.nrrd"), &[0; 12], &l).unwrap();
    let h = fs::read_to_string(dir.path("sp-mask.nrrd")).unwrap();
    assert!(h.contains("spacings: 0.5 nan 3\n"), "{h}");
    // 2-D in 3-D space: the third axis is the plane's normal.
    let p = file(
        "plane.nrrd",
        vec![
            "type: short".into(),
            "dimension: 2".into(),
            "space: left-posterior-superior".into(),
            "sizes: 4 3".into(),
            "space directions: (0,0,2) (0,3,0)".into(),
            "endian: big".into(),
            "encoding: raw".into(),
        ],
        &raw,
    );
    let l = image::load(&p, None).unwrap();
    assert_eq!((l.image.dims, l.image.spacing), ([4, 3, 1], [2.0, 3.0, 1.0]));
    assert_eq!(
        l.image.to_world,
        [[0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
    );
    // Space names.
    for (space, frame) in [
        ("LAS", WorldFrame::Las),
        ("left-posterior-superior", WorldFrame::Lps),
        ("scanner-xyz", WorldFrame::Unspecified),
        ("3D-right-handed", WorldFrame::Unspecified),
        ("3D-left-handed", WorldFrame::Unspecified),
    ] {
        let s = format!("space: {space}");
        let p = file(
            "s.nrrd",
            with(&["encoding: raw", &s, "space directions: (1,0,0) (0,1,0) (0,0,1)"]),
            &raw,
        );
        assert_eq!(image::load(&p, None).unwrap().world_frame(), frame, "{space}");
    }
}

// ---------------------------------------------------------------------------------------
// Bad input.

/// Each kind of bad header gets its own error, naming the file.
#[test]
fn bad_headers_are_refused_with_their_reason() {
    let dir = TempDir::new("bad");
    let data = [0u8; 24];
    let meta = |extra: &[&str], data: &[u8]| {
        let mut l = MHA_3D.to_vec();
        l.extend_from_slice(extra);
        mha(&l, data)
    };
    let short_local = ["ElementType = MET_SHORT", "ElementDataFile = LOCAL"];
    type Check = fn(&ImageError) -> bool;
    let cases: Vec<(&str, Vec<u8>, Check)> = vec![
        ("ok.mha", meta(&short_local, &data), |_| false),
        ("missing-type.mha", meta(&["ElementDataFile = LOCAL"], &data), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        ("no-end.mha", meta(&["ElementType = MET_SHORT"], &[]), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        (
            "twice.mha",
            meta(&["NDims = 3", "ElementType = MET_SHORT", "ElementDataFile = LOCAL"], &data),
            |e| matches!(e, ImageError::Corrupt { reason, .. } if reason.contains("twice")),
        ),
        (
            "type.mha",
            meta(&["ElementType = MET_FLOAT_ARRAY", "ElementDataFile = LOCAL"], &data),
            |e| matches!(e, ImageError::UnsupportedVoxelType { .. }),
        ),
        (
            "rgb.mha",
            meta(
                &[
                    "ElementNumberOfChannels = 3",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &data,
            ),
            |e| matches!(e, ImageError::Unsupported { what, .. } if what.contains("ElementNumberOfChannels = 3")),
        ),
        (
            "ascii.mha",
            meta(
                &["BinaryData = False", "ElementType = MET_UCHAR", "ElementDataFile = LOCAL"],
                &data,
            ),
            |e| matches!(e, ImageError::Unsupported { .. }),
        ),
        ("list.mha", meta(&["ElementType = MET_UCHAR", "ElementDataFile = LIST"], &data), |e| {
            matches!(e, ImageError::Unsupported { .. })
        }),
        (
            "missing.mhd",
            meta(&["ElementType = MET_UCHAR", "ElementDataFile = nowhere.raw"], &[]),
            |e| {
                matches!(e, ImageError::DataFile { data, source, .. }
                if data.ends_with("nowhere.raw") && source.kind() == std::io::ErrorKind::NotFound)
            },
        ),
        ("dir.mhd", meta(&["ElementType = MET_UCHAR", "ElementDataFile = ."], &[]), |e| {
            matches!(e, ImageError::DataFile { .. })
        }),
        (
            "msb.mha",
            meta(
                &[
                    "BinaryDataByteOrderMSB = True",
                    "ElementByteOrderMSB = False",
                    "ElementType = MET_SHORT",
                    "ElementDataFile = LOCAL",
                ],
                &data,
            ),
            |e| matches!(e, ImageError::Corrupt { .. }),
        ),
        (
            "version.mha",
            meta(
                &["FileFormatVersion = 1", "ElementType = MET_SHORT", "ElementDataFile = LOCAL"],
                &data,
            ),
            |e| matches!(e, ImageError::Unsupported { .. }),
        ),
        (
            "tube.mha",
            mha(&["ObjectType = Tube", "NDims = 3", "ElementDataFile = LOCAL"], &[]),
            |e| matches!(e, ImageError::Unsupported { .. }),
        ),
        (
            "singular.mha",
            meta(
                &[
                    "TransformMatrix = 1 0 0 0 1 0 1 0 0",
                    "ElementType = MET_SHORT",
                    "ElementDataFile = LOCAL",
                ],
                &data,
            ),
            |e| matches!(e, ImageError::BadTransform { which: "TransformMatrix", .. }),
        ),
        (
            "inf.mha",
            mha(
                &[
                    "NDims = 2",
                    "DimSize = 2 2",
                    "Origin = 0 inf",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &[0; 4],
            ),
            |e| matches!(e, ImageError::BadTransform { which: "Offset", .. }),
        ),
        (
            "disagree.mha",
            mha(
                &[
                    "NDims = 2",
                    "DimSize = 2 2",
                    "Origin = 0 1",
                    "Offset = 0 2",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &[0; 4],
            ),
            |e| matches!(e, ImageError::Corrupt { reason, .. } if reason.contains("disagree")),
        ),
        (
            "spacing.mha",
            mha(
                &[
                    "NDims = 2",
                    "DimSize = 2 2",
                    "ElementSpacing = 1 0",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &[0; 4],
            ),
            |e| matches!(e, ImageError::BadSpacing { axis: 'y', .. }),
        ),
        (
            "count.mha",
            mha(
                &[
                    "NDims = 2",
                    "DimSize = 2 2 2",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &[0; 8],
            ),
            |e| matches!(e, ImageError::Corrupt { .. }),
        ),
        (
            "negative.mha",
            mha(
                &[
                    "NDims = 2",
                    "DimSize = 2 -2",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &[],
            ),
            |e| matches!(e, ImageError::BadDimensions { .. }),
        ),
        (
            "4d.mha",
            mha(
                &[
                    "NDims = 4",
                    "DimSize = 2 2 2 2",
                    "ElementType = MET_UCHAR",
                    "ElementDataFile = LOCAL",
                ],
                &[0; 16],
            ),
            |e| matches!(e, ImageError::BadDimensions { .. }),
        ),
        ("garbage.mha", b"\x00\x01binary\xff\n".to_vec(), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        ("empty.mha", Vec::new(), |e| matches!(e, ImageError::Corrupt { .. })),
        (
            "nan.mha",
            mha(
                &[
                    "NDims = 2",
                    "DimSize = 2 1",
                    "ElementType = MET_FLOAT",
                    "ElementDataFile = LOCAL",
                ],
                &bytes_of!([0.5f32, f32::NAN], false),
            ),
            |e| matches!(e, ImageError::NonFinite { voxel: [1, 0, 0], .. }),
        ),
        (
            "bad-zlib.mha",
            meta(
                &["CompressedData = True", "ElementType = MET_SHORT", "ElementDataFile = LOCAL"],
                b"not zlib at all",
            ),
            |e| matches!(e, ImageError::Corrupt { format: "zlib", .. }),
        ),
    ];
    let nrrd_cases: Vec<(&str, Vec<u8>, Check)> = vec![
        ("ok.nrrd", nrrd(&["type: short", "dimension: 3", "sizes: 3 2 2", "endian: little", "encoding: raw"], &data), |_| false),
        ("magic.nrrd", b"NRRX0004\ntype: short\n\n".to_vec(), |e| matches!(e, ImageError::Corrupt { .. })),
        ("version.nrrd", b"NRRD0009\ntype: short\n\n".to_vec(), |e| matches!(e, ImageError::Unsupported { .. })),
        ("endian.nrrd", nrrd(&["type: short", "dimension: 3", "sizes: 3 2 2", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Corrupt { reason, .. } if reason.contains("endian"))
        }),
        ("twice.nrrd", nrrd(&["type: short", "type: short", "dimension: 3", "sizes: 3 2 2", "endian: little", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Corrupt { reason, .. } if reason.contains("twice"))
        }),
        ("block.nrrd", nrrd(&["type: block", "dimension: 3", "sizes: 3 2 2", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::UnsupportedVoxelType { .. })
        }),
        ("ascii.nrrd", nrrd(&["type: uchar", "dimension: 2", "sizes: 2 2", "encoding: ascii"], b"1 2 3 4"), |e| {
            matches!(e, ImageError::Unsupported { .. })
        }),
        ("rgb.nrrd", nrrd(&["type: uchar", "dimension: 3", "sizes: 3 2 2", "kinds: RGB-color domain domain", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Unsupported { what, .. } if what.contains("3 samples"))
        }),
        ("trailing.nrrd", nrrd(&["type: uchar", "dimension: 3", "sizes: 2 2 3", "kinds: domain domain vector", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Unsupported { .. })
        }),
        ("5d.nrrd", nrrd(&["type: uchar", "dimension: 5", "sizes: 1 1 2 2 3", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::BadDimensions { .. })
        }),
        ("negative.nrrd", nrrd(&["type: uchar", "dimension: 2", "sizes: 2 -4", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::BadDimensions { .. })
        }),
        ("time.nrrd", nrrd(&["type: uchar", "dimension: 2", "space: RAST", "sizes: 2 2", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Unsupported { .. })
        }),
        ("parallel.nrrd", nrrd(&["type: uchar", "dimension: 2", "space: RAS", "sizes: 2 2", "space directions: (1,0,0) (2,0,0)", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::BadTransform { which: "space directions", .. })
        }),
        ("zero.nrrd", nrrd(&["type: uchar", "dimension: 2", "space: RAS", "sizes: 2 2", "space directions: (1,0,0) (0,0,0)", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::BadSpacing { axis: 'y', .. })
        }),
        ("both.nrrd", nrrd(&["type: uchar", "dimension: 2", "space: RAS", "sizes: 2 2", "spacings: 1 1", "space directions: (1,0,0) (0,1,0)", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        ("components.nrrd", nrrd(&["type: uchar", "dimension: 2", "space: RAS", "sizes: 2 2", "space directions: (1,0) (0,1)", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        ("nospace.nrrd", nrrd(&["type: uchar", "dimension: 2", "sizes: 2 2", "space origin: (1,2,3)", "encoding: raw"], &data), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        ("missing.nhdr", b"NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\nencoding: raw\ndata file: ./gone/x.raw\n".to_vec(), |e| {
            matches!(e, ImageError::DataFile { .. })
        }),
        ("attached.nhdr", b"NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\nencoding: raw\n".to_vec(), |e| {
            matches!(e, ImageError::Truncated { .. })
        }),
        ("gzip-end.nrrd", nrrd(&["type: uchar", "dimension: 2", "sizes: 2 2", "encoding: gzip", "byte skip: -1"], &gzip(&[1; 4])), |e| {
            matches!(e, ImageError::Corrupt { .. })
        }),
        ("bad-gzip.nrrd", nrrd(&["type: uchar", "dimension: 2", "sizes: 2 2", "encoding: gzip"], b"\x1f\x8b not really"), |e| {
            matches!(e, ImageError::Corrupt { format: "gzip", .. } | ImageError::Truncated { .. })
        }),
        ("inf.nrrd", nrrd(&["type: float", "dimension: 2", "sizes: 2 1", "endian: big", "encoding: raw"], &bytes_of!([f32::INFINITY, 0.0], true)), |e| {
            matches!(e, ImageError::NonFinite { voxel: [0, 0, 0], .. })
        }),
    ];
    for (name, bytes, check) in cases.into_iter().chain(nrrd_cases) {
        let p = dir.file(name, &bytes);
        if name.starts_with("ok.") {
            assert!(image::load(&p, None).is_ok(), "{name}");
            continue;
        }
        let e = load_err(&p);
        assert!(check(&e), "{name}: {e:?}");
    }
    // A header beyond 64 KiB.
    let mut long = b"NRRD0004\n".to_vec();
    long.extend(
        std::iter::repeat_n(b"# comment comment comment comment\n".to_vec(), 3000).flatten(),
    );
    let e = load_err(&dir.file("long.nrrd", &long));
    assert!(matches!(&e, ImageError::Corrupt { reason, .. } if reason.contains("64 KiB")), "{e}");
    let mut long = b"ObjectType = Image\n".to_vec();
    long.extend(vec![b'x'; 70_000]);
    assert!(matches!(load_err(&dir.file("long.mha", &long)), ImageError::Corrupt { .. }));
}

/// Headers announcing 10¹⁵ voxels are refused at once, allocating nothing of that size;
/// sizes whose byte count overflows are too large.
#[test]
fn hostile_sizes_are_refused_without_allocating() {
    let dir = TempDir::new("hostile");
    let huge = ["NDims = 3", "DimSize = 100000 100000 100000", "ElementType = MET_FLOAT"];
    let with = |extra: &[&str]| {
        let mut l = huge.to_vec();
        l.extend_from_slice(extra);
        mha(&l, &[0; 64])
    };
    let plain = dir.file("huge.mha", &with(&["ElementDataFile = LOCAL"]));
    let packed =
        dir.file("huge-z.mha", &with(&["CompressedData = True", "ElementDataFile = LOCAL"]));
    dir.file("huge.raw", &[0; 64]);
    let detached = dir.file("huge.mhd", &with(&["ElementDataFile = huge.raw"]));
    let n = dir.file(
        "huge.nrrd",
        &nrrd(
            &[
                "type: float",
                "dimension: 3",
                "sizes: 100000 100000 100000",
                "endian: little",
                "encoding: raw",
            ],
            &[0; 64],
        ),
    );
    let nz = dir.file(
        "huge-gz.nrrd",
        &nrrd(
            &[
                "type: float",
                "dimension: 3",
                "sizes: 100000 100000 100000",
                "endian: little",
                "encoding: gzip",
            ],
            &gzip(&[0; 64]),
        ),
    );
    let t = Instant::now();
    let (results, largest) =
        largest_allocation(|| [&plain, &packed, &detached, &n, &nz].map(|p| image::load(p, None)));
    assert!(t.elapsed().as_secs_f64() < 1.0, "took {:?}", t.elapsed());
    assert!(largest < 1 << 20, "allocated {largest} bytes at once");
    for (r, p) in results.iter().zip([&plain, &packed, &detached, &n, &nz]) {
        let e = r.as_ref().unwrap_err();
        assert!(e.to_string().contains(&*p.file_name().unwrap().to_string_lossy()), "{e}");
        let compressed = p.file_name().unwrap().to_string_lossy().contains('-');
        if compressed {
            assert!(matches!(e, ImageError::TooLarge { .. }), "{e}");
        } else {
            assert!(
                matches!(e, ImageError::Truncated { detail, .. } if detail.contains("4000000000000000")),
                "{e}"
            );
        }
    }
    // Sizes beyond i32, and byte counts beyond 64 bits.
    let p = dir.file(
        "wide.nrrd",
        &nrrd(&["type: uchar", "dimension: 2", "sizes: 3000000000 1", "encoding: raw"], &[]),
    );
    assert!(matches!(load_err(&p), ImageError::BadDimensions { .. }));
    let p = dir.file(
        "overflow.mha",
        &mha(
            &[
                "NDims = 3",
                "DimSize = 2147483647 2147483647 2147483647",
                "ElementType = MET_DOUBLE",
                "ElementDataFile = LOCAL",
            ],
            &[],
        ),
    );
    assert!(matches!(load_err(&p), ImageError::TooLarge { needed: u64::MAX, .. }));
    let p = dir.file(
        "long-number.mha",
        &mha(&["NDims = 99999999999999999999999", "ElementDataFile = LOCAL"], &[]),
    );
    assert!(matches!(load_err(&p), ImageError::Corrupt { .. }));
}

/// Every prefix of a valid file (and of a detached data file) is refused without
/// panicking; the whole file reads.
#[test]
fn truncated_files_are_refused() {
    let dir = TempDir::new("trunc");
    for name in ["ct.mha", "ct-zlib.mha", "ct.nrrd", "ct-gzip.nrrd", "slice.nrrd"] {
        let full = fs::read(data_dir().join(name)).unwrap();
        let p = dir.path(name);
        for cut in 0..full.len() {
            rewrite(&p, &full[..cut]);
            match std::panic::catch_unwind(|| image::load(&p, None)) {
                Ok(Err(_)) => {}
                Ok(Ok(_)) => panic!("{name}: prefix of {cut} bytes accepted"),
                Err(_) => panic!("{name}: prefix of {cut} bytes panicked"),
            }
        }
        fs::write(&p, &full).unwrap();
        assert!(image::load(&p, None).is_ok(), "{name}");
    }
    for (header, data) in [("floats.mhd", "floats.raw"), ("words.nhdr", "words.raw.gz")] {
        fs::copy(data_dir().join(header), dir.path(header)).unwrap();
        let full = fs::read(data_dir().join(data)).unwrap();
        for cut in 0..full.len() {
            rewrite(&dir.path(data), &full[..cut]);
            let e = load_err(&dir.path(header));
            assert!(
                matches!(e, ImageError::Truncated { .. } | ImageError::Corrupt { .. }),
                "{header}: {cut}: {e}"
            );
        }
    }
    let e = load_err(&dir.file("cut.mha", &fs::read(data_dir().join("ct.mha")).unwrap()[..600]));
    assert!(
        matches!(&e, ImageError::Truncated { detail, .. } if detail.contains("120 bytes")),
        "{e}"
    );
}

/// Random byte mutations of valid files (headers and data) give Ok or Err, never a panic.
#[test]
fn fuzzed_files_never_panic() {
    let dir = TempDir::new("fuzz");
    let mut rng = fastrand::Rng::with_seed(11);
    fs::copy(data_dir().join("floats.raw"), dir.path("floats.raw")).unwrap();
    let files = ["ct.mha", "ct-zlib.mha", "floats.mhd", "ct.nrrd", "ct-gzip.nrrd", "slice.nrrd"];
    let t = Instant::now();
    let mut outcomes = [0usize; 2];
    for name in files {
        let full = fs::read(data_dir().join(name)).unwrap();
        let header_len = full.windows(2).position(|w| w == b"\n\n").unwrap_or(full.len());
        let p = dir.path(name);
        for i in 0..600 {
            let mut b = full.clone();
            for _ in 0..rng.usize(1..4) {
                // Mostly in the header, where the structure is.
                let at = if i % 4 == 0 {
                    rng.usize(0..b.len())
                } else {
                    rng.usize(0..header_len.min(b.len()))
                };
                b[at] = match rng.u8(0..4) {
                    0 => rng.u8(..),
                    1 => b"0123456789-. \n=:(),"[rng.usize(0..19)],
                    _ => b[at] ^ (1 << rng.u8(0..8)),
                };
            }
            rewrite(&p, &b);
            match std::panic::catch_unwind(|| image::load(&p, None)) {
                Ok(r) => outcomes[r.is_ok() as usize] += 1,
                Err(_) => panic!("{name} panicked on {:?}", String::from_utf8_lossy(&b)),
            }
        }
    }
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "{outcomes:?}");
    assert!(t.elapsed().as_secs_f64() < 10.0, "took {:?}", t.elapsed());
}
