//! Helpers of the command-line tests: the two binaries, temporary paths, ball fields.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Runs the `levelset` binary with `args`.
pub fn levelset(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_levelset")).args(args).output().expect("binary runs")
}

/// Runs the speed-up report binary (what `cargo run --release` runs) with `args`.
pub fn speedup(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_levelset-speedup")).args(args).output().expect("binary runs")
}

/// The standard error of a run, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The standard output of a run, as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

// The temporary paths, ball fields and `.npy` files of the library's integration tests.
#[path = "../../../../tests/integration/common/mod.rs"]
mod shared;
#[allow(unused_imports)] // each test file uses some of them
pub use shared::{ball, crc32, npy, tmp};

/// An axis-aligned box `0..sx × 0..sy × 0..sz` as OBJ text (quads, outward).
pub fn box_obj(sx: u32, sy: u32, sz: u32) -> String {
    let mut s = String::new();
    for i in 0..8 {
        let (x, y, z) = (sx * (i & 1), sy * (i >> 1 & 1), sz * (i >> 2));
        s += &format!("v {x} {y} {z}\n");
    }
    for f in [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]] {
        s += &format!("f {} {} {} {}\n", f[0], f[1], f[2], f[3]);
    }
    s
}

/// A .npy v1.0 file with the given dtype descriptor, shape and raw little-endian data.
pub fn write_npy(path: &std::path::Path, descr: &str, shape: &[usize], data: &[u8]) {
    let shape_s = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!("({})", shape.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_s}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(data);
    std::fs::write(path, bytes).unwrap();
}
