//! Inputs whose size exceeds what the process may allocate: under `ulimit -v` (the
//! address-space limit) every command refuses them with one `error:` line and exit 1 before
//! allocating, never an abort in the allocator. The large files are sparse (their length set,
//! nothing written), so they cost no disk.

use crate::common::tmp;
use std::io::Write;
use std::path::Path;
use std::process::Output;

/// 1 GB of address space: the command starts, a 2 GB request does not fit.
const ULIMIT_KB: u64 = 1_000_000;

/// Runs `levelset args…` under `ulimit -v`.
fn levelset_limited(args: &[&str]) -> Output {
    let bin = env!("CARGO_BIN_EXE_levelset");
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {ULIMIT_KB} && exec '{bin}' {}", quoted.join(" ")))
        .output()
        .expect("sh runs")
}

fn refused(args: &[&str], out: &Path) {
    let o = levelset_limited(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(err.starts_with("error:") && err.lines().count() == 1, "{args:?}: {err}");
    assert!(!err.contains("memory allocation"), "{args:?}: {err}");
    assert!(err.contains("memory"), "{args:?}: {err}");
    assert!(!out.exists(), "{args:?}: {} written", out.display());
}

/// A `.npy` header for `shape` (float32) followed by a sparse data region of the full size.
fn sparse_npy(path: &Path, shape: [usize; 3]) {
    crate::common::write_npy(path, "<f4", &shape, &[]);
    let header = std::fs::metadata(path).unwrap().len();
    let f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
    f.set_len(header + 4 * shape.iter().product::<usize>() as u64).unwrap();
}

/// A NIfTI-1 single file (`.nii`) of `dims` float32 voxels, the data region sparse.
fn sparse_nifti(path: &Path, dims: [i16; 3]) {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim = [3, dims[0], dims[1], dims[2], 1, 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&16i16.to_le_bytes()); // float32
    h[72..74].copy_from_slice(&32i16.to_le_bytes());
    for i in 0..8 {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&1f32.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    let mut f = std::fs::File::create(path).unwrap();
    f.write_all(&h).unwrap();
    let n: u64 = dims.iter().map(|&d| d as u64).product();
    f.set_len(352 + 4 * n).unwrap();
}

/// A greyscale PNG whose header announces `width × height` pixels, with a few rows of data.
fn large_png(path: &Path, width: u32, height: u32) {
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(data);
        let mut crc_input = kind.to_vec();
        crc_input.extend_from_slice(data);
        c.extend_from_slice(&crate::common::crc32(&crc_input).to_be_bytes());
        c
    };
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    // Four rows of zeros (filter byte 0 each), deflated.
    let rows = vec![0u8; 4 * (width as usize + 1)];
    let idat = zlib_stored(&rows);
    let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    bytes.extend(chunk(b"IHDR", &ihdr));
    bytes.extend(chunk(b"IDAT", &idat));
    bytes.extend(chunk(b"IEND", &[]));
    std::fs::write(path, bytes).unwrap();
}

/// `data` as a zlib stream of stored (uncompressed) deflate blocks.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = data.chunks(65_535).collect();
    for (i, b) in blocks.iter().enumerate() {
        out.push(u8::from(i + 1 == blocks.len()));
        out.extend_from_slice(&(b.len() as u16).to_le_bytes());
        out.extend_from_slice(&(!(b.len() as u16)).to_le_bytes());
        out.extend_from_slice(b);
    }
    let (mut a, mut s) = (1u32, 0u32);
    for &x in data {
        a = (a + x as u32) % 65_521;
        s = (s + a) % 65_521;
    }
    out.extend_from_slice(&((s << 16) | a).to_be_bytes());
    out
}

#[test]
fn a_768_cubed_npy_under_ulimit_is_refused() {
    let big = tmp("limits-768.npy");
    sparse_npy(&big, [768, 768, 768]);
    let out = tmp("limits-768.sls");
    refused(&["convert", big.to_str().unwrap(), out.to_str().unwrap()], &out);
    let _ = std::fs::remove_file(&big);
}

#[test]
fn two_far_triangles_voxelised_to_a_dense_box_under_ulimit_are_refused() {
    // 91 bytes: two triangles 1000 units apart; the default voxel size follows their edges.
    let obj = tmp("limits-far.obj");
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1000 1000 1000\nv 1001 1000 1000\nv 1000 1001 1000\n\
                f 1 2 3\nf 4 5 6\n";
    std::fs::write(&obj, text).unwrap();
    let out = tmp("limits-far.npy");
    refused(&["voxelize", obj.to_str().unwrap(), "-o", out.to_str().unwrap(), "--quiet"], &out);
}

#[test]
fn a_huge_nifti_and_a_huge_png_under_ulimit_are_refused() {
    let nii = tmp("limits-huge.nii");
    sparse_nifti(&nii, [1024, 1024, 1024]);
    let out = tmp("limits-huge-mask.nii");
    refused(
        &[
            "segment",
            nii.to_str().unwrap(),
            "--method",
            "gac",
            "--seed",
            "5,5,5:2",
            "-o",
            out.to_str().unwrap(),
        ],
        &out,
    );
    let _ = std::fs::remove_file(&nii);
    let png = tmp("limits-huge.png");
    large_png(&png, 30_000, 30_000);
    let out = tmp("limits-huge-mask.png");
    refused(
        &[
            "segment",
            png.to_str().unwrap(),
            "--method",
            "gac",
            "--seed",
            "5,5,0:2",
            "-o",
            out.to_str().unwrap(),
        ],
        &out,
    );
}
