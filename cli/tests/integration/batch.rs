//! `levelset voxelize DIR -o OUTDIR`: the folder mode in one process (a folder of meshes,
//! one `.npy` each, one summary; a broken mesh recorded and the exit code nonzero). The
//! segmentation's batch mode is tested in `segment.rs`, both under `mpirun` in
//! `batch_mpi.rs`.

#[allow(unused_imports)] // the shared helpers re-export more than these tests use
use crate::common;

use crate::common::{box_obj, levelset, stderr, stdout, tmp};
use std::path::{Path, PathBuf};

/// A fresh directory `name` holding `files` (name, contents).
fn folder(name: &str, files: &[(&str, String)]) -> PathBuf {
    let dir = tmp(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for (f, text) in files {
        std::fs::write(dir.join(f), text).unwrap();
    }
    dir
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).expect("summary.json"))
        .expect("summary.json is JSON")
}

#[test]
fn folder_mode_voxelizes_every_mesh_and_records_a_broken_one() {
    let input = folder(
        "meshes",
        &[
            ("a.obj", box_obj(4, 3, 2)),
            ("b.OBJ", box_obj(2, 2, 2)),
            ("broken.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n".into()),
            ("c.obj", box_obj(3, 1, 2)),
            ("notes.txt", "not a mesh: left alone".into()),
        ],
    );
    let out = tmp("meshes-out");
    let (i, od) = (input.to_str().unwrap(), out.to_str().unwrap());
    let args = ["voxelize", i, "-o", od, "--voxel-size", "0.5", "--threads", "2", "--quiet"];
    let run = levelset(&args);
    assert!(!run.status.success(), "a failed mesh makes the exit code nonzero");
    assert!(stderr(&run).contains("1 of 4 meshes failed"), "{}", stderr(&run));
    let text = stdout(&run);
    assert!(text.contains("broken.obj: FAILED, skipped") && text.contains("not finite"), "{text}");
    assert!(text.contains("4 meshes, 1 failed"), "{text}");
    assert!(!text.contains("rank "), "one process: no rank prefixes: {text}");
    for stem in ["a", "b", "c"] {
        assert!(out.join(format!("{stem}.npy")).is_file(), "{stem}.npy");
    }
    assert!(!out.join("broken.npy").exists());
    assert!(!out.join("notes.npy").exists());

    let s = summary(&out);
    assert_eq!((s["meshes"].as_u64(), s["failed"].as_u64()), (Some(4), Some(1)), "{s}");
    assert_eq!((s["ranks"].as_u64(), s["threads"].as_u64()), (Some(1), Some(2)), "{s}");
    let records = s["records"].as_array().unwrap();
    let meshes: Vec<&str> = records.iter().map(|r| r["mesh"].as_str().unwrap()).collect();
    let names: Vec<&str> = meshes.iter().map(|m| m.rsplit('/').next().unwrap()).collect();
    assert_eq!(names, ["a.obj", "b.OBJ", "broken.obj", "c.obj"], "in name order");
    assert!(records[2]["error"].as_str().unwrap().contains("not finite"), "{s}");
    let mut total = 0;
    for r in [&records[0], &records[1], &records[3]] {
        assert!(r.get("error").is_none(), "{r}");
        assert_eq!(r["triangles"], 12, "{r}");
        // Four meshes on two threads: each mesh on one worker thread.
        assert_eq!(r["threads"], 1, "{r}");
        assert!(Path::new(r["output"].as_str().unwrap()).is_file(), "{r}");
        total += r["band_voxels"].as_u64().unwrap();
    }
    assert_eq!(s["band_voxels"].as_u64(), Some(total), "{s}");

    // Each mesh goes through the single-file path: the same file as voxelising it alone.
    let alone = tmp("a-alone.npy");
    let mesh = input.join("a.obj");
    let o = levelset(&[
        "voxelize",
        mesh.to_str().unwrap(),
        "-o",
        alone.to_str().unwrap(),
        "--voxel-size",
        "0.5",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&alone).unwrap(), std::fs::read(out.join("a.npy")).unwrap());
    assert_eq!(records[0]["origin"], serde_json::json!([-3, -3, -3]), "{}", records[0]);
    assert_eq!(records[0]["dims"], serde_json::json!([15, 13, 11]), "{}", records[0]);

    // Fewer meshes than threads: one after another, each with every thread; all succeed.
    std::fs::remove_file(input.join("broken.obj")).unwrap();
    let args = ["voxelize", i, "-o", od, "--voxel-size", "0.5", "--threads", "4", "--quiet"];
    let run = levelset(&args);
    assert!(run.status.success(), "{}", stderr(&run));
    let s = summary(&out);
    assert_eq!((s["meshes"].as_u64(), s["failed"].as_u64()), (Some(3), Some(0)), "{s}");
    assert!(s["records"].as_array().unwrap().iter().all(|r| r["threads"] == 4), "{s}");
}

#[test]
fn folder_mode_refuses_before_any_work() {
    let out = tmp("refused-out");
    let o = out.to_str().unwrap();
    // No mesh in the folder.
    let empty = folder("no-meshes", &[("readme.txt", "nothing".into())]);
    let r = levelset(&["voxelize", empty.to_str().unwrap(), "-o", o, "--quiet"]);
    assert!(!r.status.success());
    assert!(stderr(&r).contains("no mesh (.obj, .ply, .stl)"), "{}", stderr(&r));
    // Two meshes with one output name.
    let twins = folder("twins", &[("a.obj", box_obj(2, 2, 2)), ("a.ply", String::new())]);
    let r = levelset(&["voxelize", twins.to_str().unwrap(), "-o", o, "--quiet"]);
    assert!(!r.status.success());
    assert!(stderr(&r).contains("two meshes"), "{}", stderr(&r));
    assert!(!out.exists(), "nothing created");
    // An output directory that cannot be created (a file is in the way).
    let blocker = tmp("blocker");
    std::fs::write(&blocker, "a file").unwrap();
    let under = blocker.join("out");
    let r = levelset(&["voxelize", empty.to_str().unwrap(), "-o", under.to_str().unwrap()]);
    assert!(!r.status.success());
    assert!(stderr(&r).contains("cannot write the output"), "{}", stderr(&r));
    assert!(!stderr(&r).contains("panicked"), "{}", stderr(&r));
}

/// Under a launcher of several ranks, one mesh (or one image) is refused before any work:
/// every rank would write the same file. The launcher's variable is all the check reads.
#[test]
fn one_input_on_several_ranks_is_refused() {
    let mesh = folder("one-mesh", &[("a.obj", box_obj(2, 2, 2))]).join("a.obj");
    let out = tmp("one-mesh.npy");
    let seg_out = tmp("one-mask.npy");
    for args in [
        vec!["voxelize", mesh.to_str().unwrap(), "-o", out.to_str().unwrap()],
        vec!["segment", out.to_str().unwrap(), "--method", "gac", "-o", seg_out.to_str().unwrap()],
    ] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_levelset"))
            .args(&args)
            .env("OMPI_COMM_WORLD_SIZE", "2")
            .output()
            .expect("binary runs");
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains("runs in one process"), "{args:?}: {}", stderr(&o));
    }
    assert!(!out.exists() && !seg_out.exists());
}
