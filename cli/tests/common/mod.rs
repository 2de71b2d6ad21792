//! Helpers of the command-line tests: the two binaries, temporary paths, ball fields.
#![allow(dead_code)]

use sparse_levelset::dense::DenseField;
use sparse_levelset::Coord;
use std::path::PathBuf;
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

/// A path in this test process's own temporary directory.
pub fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("levelset-cli-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A dense field `scale · (|x − centre| − radius)` over `0..dims` (voxel coordinates):
/// a ball, as a user's `.npy` level set would hold it.
pub fn ball(dims: [usize; 3], centre: [f64; 3], radius: f64, scale: f64) -> DenseField {
    DenseField::from_fn(Coord::new(0, 0, 0), dims, |c| {
        let d = [c.x as f64 - centre[0], c.y as f64 - centre[1], c.z as f64 - centre[2]];
        (scale * ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - radius)) as f32
    })
    .unwrap()
}

/// Writes `field` to the temporary `.npy` file `name` and returns its path.
pub fn npy(name: &str, field: &DenseField) -> PathBuf {
    let path = tmp(name);
    sparse_levelset::npy::write_npy(&path, field).unwrap();
    path
}
