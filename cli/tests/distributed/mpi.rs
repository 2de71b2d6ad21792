//! `mpirun -n N levelset run ...` (feature `mpi`): the papers' scenarios distributed over
//! 2 ranks and over 3 (oversubscribed on a 2-core machine) end with the single-process
//! band, bit for bit (the checksum), and the same volume and area records.
#![cfg(feature = "mpi")]

use crate::common::{stderr, tmp};
use std::path::Path;
use std::process::Command;

/// Runs `levelset run ARGS --out DIR` on `ranks` MPI ranks (`None`: without mpirun) with
/// one thread each and returns the summary.
fn run(ranks: Option<usize>, args: &[&str], dir: &Path) -> serde_json::Value {
    let bin = env!("CARGO_BIN_EXE_levelset");
    let mut cmd =
        match ranks {
            None => Command::new(bin),
            Some(n) => {
                let mut c = Command::new("mpirun");
                // OpenMPI refuses root unless told; CI runs as root. More ranks than cores
                // need --oversubscribe.
                c.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
                    .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
                    .args(["-n", &n.to_string(), "--oversubscribe", bin]);
                c
            }
        };
    let out = cmd
        .args(["run"])
        .args(args)
        .args(["--threads", "1", "--quiet", "--out"])
        .arg(dir)
        .output()
        .expect("mpirun runs");
    assert!(out.status.success(), "{ranks:?} ranks: {}", stderr(&out));
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).expect("JSON")
}

/// The figures that must not depend on the ranks: every record's step, time, Δt, band
/// voxels, volume and area, and the checksum.
fn figures(s: &serde_json::Value) -> serde_json::Value {
    let records: Vec<serde_json::Value> = s["records"]
        .as_array()
        .expect("records")
        .iter()
        .map(|r| {
            serde_json::json!([
                r["step"],
                r["time"],
                r["dt"],
                r["band_voxels"],
                r["volume"],
                r["area"]
            ])
        })
        .collect();
    serde_json::json!({"checksum": s["checksum"], "records": records, "steps": s["steps_taken"]})
}

fn same_on_every_rank_count(name: &str, args: &[&str]) {
    let one = run(None, args, &tmp(&format!("mpi-{name}-1")));
    assert!(one.get("distributed").is_none());
    for ranks in [2, 3] {
        let s = run(Some(ranks), args, &tmp(&format!("mpi-{name}-{ranks}")));
        assert_eq!(figures(&s), figures(&one), "{name} on {ranks} ranks");
        let d = &s["distributed"];
        assert_eq!(d["ranks"], ranks);
        let tiles = d["tiles_per_rank"].as_array().expect("tiles per rank");
        assert_eq!(tiles.len(), ranks);
        assert!(tiles.iter().all(|t| t.as_u64().is_some_and(|t| t > 0)), "{d}");
        // Every rank exchanged ghost tiles with a neighbour.
        for h in d["halo"].as_array().expect("halo") {
            assert!(h["bytes"].as_u64().is_some_and(|b| b > 0), "{h}");
        }
    }
}

#[test]
fn sphere_on_2_and_3_ranks_matches_one_process() {
    same_on_every_rank_count("sphere", &["sphere", "--size", "64", "--steps", "30"]);
}

#[test]
fn spiral_on_2_and_3_ranks_matches_one_process() {
    // Volume-conserving: κ̄ is a reduction over the ranks in every stage.
    same_on_every_rank_count("spiral", &["spiral", "--size", "64", "--steps", "40"]);
}

#[test]
fn enright_on_2_and_3_ranks_matches_one_process() {
    // Advection carries the band across the cuts; rebalancing moves them.
    same_on_every_rank_count(
        "enright",
        &["enright", "--size", "64", "--steps", "80", "--rebalance", "0.05"],
    );
}

#[test]
fn what_needs_the_whole_band_is_refused_under_mpirun() {
    let dir = tmp("mpi-refused");
    let out = Command::new("mpirun")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .args(["-n", "2", "--oversubscribe", env!("CARGO_BIN_EXE_levelset")])
        .args(["run", "sphere", "--size", "32", "--steps", "2", "--export-npy", "--out"])
        .arg(&dir)
        .output()
        .expect("mpirun runs");
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--export-npy"), "{}", stderr(&out));
    let dt = Command::new("mpirun")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .args(["-n", "2", "--oversubscribe", env!("CARGO_BIN_EXE_levelset")])
        .args(["run", "sphere", "--size", "32", "--steps", "2", "--grid", "dtgrid", "--out"])
        .arg(&dir)
        .output()
        .expect("mpirun runs");
    assert!(!dt.status.success());
    assert!(stderr(&dt).contains("tile engine"), "{}", stderr(&dt));
}
