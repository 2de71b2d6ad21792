//! `mpirun -n N levelset run ...` and `levelset evolve` (feature `mpi`): the papers'
//! scenarios and a user's level set distributed over 2 ranks and over 3 (oversubscribed on
//! a 2-core machine) end with the single-process band, bit for bit (the checksum, the
//! output), and the same volume and area records.
#![cfg(feature = "mpi")]

use crate::common::{stderr, tmp};
use std::path::Path;
use std::process::Command;

/// `levelset` on `ranks` MPI ranks (`None`: without mpirun).
fn launch(ranks: Option<usize>) -> Command {
    let bin = env!("CARGO_BIN_EXE_levelset");
    match ranks {
        None => Command::new(bin),
        // OpenMPI refuses root unless told (CI runs as root); more ranks than cores need
        // --oversubscribe: both in `crate::mpirun`.
        Some(n) => crate::mpirun(n),
    }
}

/// Runs `levelset run ARGS --out DIR` on `ranks` MPI ranks (`None`: without mpirun) with
/// one thread each and returns the summary.
fn run(ranks: Option<usize>, args: &[&str], dir: &Path) -> serde_json::Value {
    let out = launch(ranks)
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
    let out = crate::mpirun(2)
        .args(["run", "sphere", "--size", "32", "--steps", "2", "--export-npy", "--out"])
        .arg(&dir)
        .output()
        .expect("mpirun runs");
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--export-npy"), "{}", stderr(&out));
    let dt = crate::mpirun(2)
        .args(["run", "sphere", "--size", "32", "--steps", "2", "--grid", "dtgrid", "--out"])
        .arg(&dir)
        .output()
        .expect("mpirun runs");
    assert!(!dt.status.success());
    assert!(stderr(&dt).contains("tile engine"), "{}", stderr(&dt));
}

/// `mpirun -n N levelset evolve`: a user's `.sls` ball under mean curvature and a normal
/// speed, on 2 and 3 ranks, writes the single-process output
/// byte for byte (the dense `.npy` of the band's box: values, and inside/outside beyond the
/// band) and the same checksum, gathered by rank 0; a command that runs in one process is
/// refused under mpirun.
#[test]
fn evolve_on_2_and_3_ranks_matches_one_process() {
    let bin = env!("CARGO_BIN_EXE_levelset");
    let ball = crate::common::npy(
        "mpi-evo-ball.npy",
        &crate::common::ball([40, 40, 40], [19.5, 18.2, 20.1], 11.0, 1.0),
    );
    let sls = tmp("mpi-evo-ball.sls");
    let o =
        Command::new(bin).args(["convert"]).arg(&ball).arg(&sls).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let mut outputs = Vec::new();
    for ranks in [None, Some(2), Some(3)] {
        let out = tmp(&format!("mpi-evo-{ranks:?}.npy"));
        let summary = tmp(&format!("mpi-evo-{ranks:?}.json"));
        let o = launch(ranks)
            .arg("evolve")
            .arg(&sls)
            .arg("-o")
            .arg(&out)
            .args(["--curvature", "1", "--speed", "0.3", "--steps", "12", "--threads", "1"])
            .arg("--summary")
            .arg(&summary)
            .arg("--quiet")
            .output()
            .expect("mpirun runs");
        assert!(o.status.success(), "{ranks:?} ranks: {}", stderr(&o));
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        assert_eq!(s["ranks"], ranks.unwrap_or(1) as u64);
        outputs.push((
            std::fs::read(&out).unwrap(),
            s["checksum"].clone(),
            s["band_voxels"].clone(),
        ));
    }
    for (k, o) in outputs.iter().enumerate().skip(1) {
        assert!(o.0 == outputs[0].0, "output {k} differs from one process's");
        assert_eq!((&o.1, &o.2), (&outputs[0].1, &outputs[0].2));
    }
    let filter = launch(Some(2))
        .arg("filter")
        .arg(&sls)
        .arg("-o")
        .arg(tmp("mpi-evo-filter.sls"))
        .args(["--op", "dilate:1"])
        .output()
        .expect("mpirun runs");
    assert!(!filter.status.success());
    assert!(stderr(&filter).contains("runs in one process"), "{}", stderr(&filter));
}
