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
#[path = "../../../tests/common/mod.rs"]
mod shared;
#[allow(unused_imports)] // each test file uses some of them
pub use shared::{ball, npy, tmp};
