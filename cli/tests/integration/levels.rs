//! The instruction-set levels as a user meets them: `LEVELSET_SIMD` forces a level, the
//! answers are the same bits at every level with FMA (and on both grids), and a level the
//! CPU cannot run, or a value that names none, is refused before any work.

use crate::common::{levelset, speedup, stderr, stdout, tmp};
use levelset_kernels::Level;
use std::process::Command;

/// The checksum of `levelset run SCENARIO` at `level` (`None`: the detected one).
fn checksum(level: Option<Level>, args: &[&str]) -> String {
    let out = tmp("levels-run");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_levelset"));
    cmd.args(args).args(["--threads", "2", "--out"]).arg(&out);
    match level {
        Some(l) => cmd.env("LEVELSET_SIMD", l.name()),
        None => cmd.env_remove("LEVELSET_SIMD"),
    };
    let o = cmd.output().expect("binary runs");
    assert!(o.status.success(), "{args:?} at {level:?}: {}", stderr(&o));
    let text = stdout(&o);
    let _ = std::fs::remove_dir_all(&out);
    text.split("checksum ").nth(1).expect("a checksum").split_whitespace().next().unwrap().into()
}

#[test]
fn every_level_with_fma_gives_the_same_bits_on_both_grids() {
    let available: Vec<Level> = Level::ALL.into_iter().filter(|l| l.available()).collect();
    for scenario in [
        &["run", "spiral", "--size", "48", "--steps", "12"][..],
        &[
            "run",
            "enright",
            "--size",
            "32",
            "--steps",
            "6",
            "--scheme",
            "weno5",
            "--integrator",
            "rk3",
        ][..],
    ] {
        let detected = checksum(None, scenario);
        let mut fused = Vec::new();
        for &level in &available {
            let tiles = checksum(Some(level), scenario);
            let scalar = checksum(Some(level), &[scenario, &["--lanes", "scalar"]].concat());
            let dtgrid = checksum(Some(level), &[scenario, &["--grid", "dtgrid"]].concat());
            assert_eq!(tiles, scalar, "{scenario:?}: SIMD and scalar lanes at {level}");
            assert_eq!(tiles, dtgrid, "{scenario:?}: tiles and the DT-Grid at {level}");
            if level.fused() {
                fused.push(tiles.clone());
            } else if Level::detected().fused() {
                // A build without FMA at the baseline: two roundings, other bits.
                assert_ne!(tiles, detected, "{scenario:?}: the unfused baseline");
            }
        }
        assert!(fused.iter().all(|c| *c == fused[0]), "{scenario:?}: {fused:?}");
        if Level::detected().fused() {
            assert_eq!(detected, fused[0], "{scenario:?}: the detected level");
        }
    }
}

#[test]
fn the_report_names_the_level_it_ran_at() {
    for level in Level::ALL.into_iter().filter(|l| l.available()) {
        let o = Command::new(env!("CARGO_BIN_EXE_levelset-speedup"))
            .args(["--kernels", "--quick"])
            .env("LEVELSET_SIMD", level.name())
            .output()
            .expect("binary runs");
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stdout(&o).starts_with(&format!("level: {}", level.describe())), "{}", stdout(&o));
    }
}

#[test]
fn a_level_that_is_not_one_or_that_the_cpu_lacks_is_refused() {
    let run = |value: &str| {
        Command::new(env!("CARGO_BIN_EXE_levelset"))
            .args(["info", "--shape", "sphere", "--radius", "8"])
            .env("LEVELSET_SIMD", value)
            .output()
            .expect("binary runs")
    };
    let o = run("avx9000");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("LEVELSET_SIMD=avx9000: not a level"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty());
    for level in Level::ALL.into_iter().filter(|l| !l.available()) {
        let o = run(level.name());
        assert_eq!(o.status.code(), Some(1));
        assert!(stderr(&o).contains("this CPU cannot run"), "{}", stderr(&o));
    }
    let o = speedup(&["--kernels", "--quick"]);
    assert!(o.status.success());
    let o = levelset(&["info", "--shape", "sphere", "--radius", "8"]);
    assert!(o.status.success(), "{}", stderr(&o));
}
