//! `mpirun -n 2 levelset voxelize DIR` and `mpirun -n 2 levelset segment DIR`: the
//! inputs spread over two ranks give the one-process run's summary (timings aside) and
//! files, with a failed input on one rank. Needs `--features mpi` and OpenMPI's `mpirun`.
#![cfg(feature = "mpi")]

#[allow(unused_imports)] // the shared helpers re-export more than these tests use
use crate::common;

use crate::common::{box_obj, levelset, stderr, stdout, tmp};
use std::path::{Path, PathBuf};
use std::process::Output;

/// `mpirun -n 2 levelset ARGS` ([`crate::mpirun`]).
fn mpirun(args: &[&str]) -> Output {
    crate::mpirun(2).args(args).output().expect("mpirun runs (OpenMPI installed)")
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).expect("summary.json"))
        .expect("summary.json is JSON")
}

/// The records of a summary without what differs between runs: timings, rates and the
/// output directory (the output's file name stays).
fn records(s: &serde_json::Value) -> Vec<serde_json::Value> {
    let mut out = s["records"].as_array().expect("records").clone();
    for r in &mut out {
        let m = r.as_object_mut().expect("a record is an object");
        m.retain(|k, _| !k.contains("seconds") && !k.ends_with("_per_s"));
        if let Some(o) = m.get_mut("output") {
            let name = Path::new(o.as_str().expect("output")).file_name().expect("file name");
            *o = serde_json::json!(name.to_string_lossy());
        }
    }
    out
}

/// A fresh directory `name`.
fn fresh(name: &str) -> PathBuf {
    let dir = tmp(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn voxelize_a_folder_on_two_ranks_gives_the_one_process_summary() {
    let input = fresh("mpi-meshes");
    for (name, text) in [
        ("a.obj", box_obj(4, 3, 2)),
        ("b.obj", box_obj(2, 2, 2)),
        // Index 2: rank 0's second mesh fails while rank 1 works.
        ("broken.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n".into()),
        ("c.obj", box_obj(3, 1, 2)),
        ("d.obj", box_obj(1, 2, 3)),
    ] {
        std::fs::write(input.join(name), text).unwrap();
    }
    let (one, two) = (tmp("mpi-meshes-1"), tmp("mpi-meshes-2"));
    let (i, o1, o2) = (input.to_str().unwrap(), one.to_str().unwrap(), two.to_str().unwrap());
    let args = |out| ["voxelize", i, "-o", out, "--voxel-size", "0.5", "--threads", "1", "--quiet"];
    let o = levelset(&args(o1));
    assert!(!o.status.success(), "the broken mesh fails the run");
    let o = mpirun(&args(o2));
    assert!(!o.status.success(), "the broken mesh fails the distributed run too");
    let text = stdout(&o);
    assert!(text.contains("rank 0: ") && text.contains("rank 1: "), "{text}\n{}", stderr(&o));
    assert!(text.contains("broken.obj: FAILED, skipped"), "{text}");
    assert_eq!(text.matches("wrote ").count(), 5, "4 meshes and the summary: {text}");
    let (s1, s2) = (summary(&one), summary(&two));
    assert_eq!(s2["ranks"], 2, "{s2}");
    assert_eq!(s2["threads"], 1, "threads per rank: {s2}");
    for k in ["meshes", "failed", "band_voxels"] {
        assert_eq!(s1[k], s2[k], "{k}");
    }
    assert_eq!(records(&s1), records(&s2));
    for m in ["a", "b", "c", "d"] {
        let f = format!("{m}.npy");
        assert_eq!(
            std::fs::read(one.join(&f)).unwrap(),
            std::fs::read(two.join(&f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn segment_a_folder_on_two_ranks_gives_the_one_process_summary() {
    let input = fresh("mpi-scans");
    let i = input.to_str().unwrap();
    for kind in ["ball", "torus", "blobs"] {
        let o = levelset(&["phantom", kind, "--size", "24", "--snr", "4", "-o", i]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let (one, two) = (tmp("mpi-masks-1"), tmp("mpi-masks-2"));
    let (o1, o2) = (one.to_str().unwrap(), two.to_str().unwrap());
    let args = |o| ["segment", i, "--method", "threshold", "-o", o, "--threads", "1", "--quiet"];
    let run1 = levelset(&args(o1));
    assert!(run1.status.success(), "{}", stderr(&run1));
    let run2 = mpirun(&args(o2));
    assert!(run2.status.success(), "{}\n{}", stdout(&run2), stderr(&run2));
    let text = stdout(&run2);
    assert!(text.contains("3 images, 0 failed") && text.contains("2 ranks"), "{text}");
    let (s1, s2) = (summary(&one), summary(&two));
    assert_eq!((s2["ranks"].as_u64(), s2["threads"].as_u64()), (Some(2), Some(1)), "{s2}");
    assert_eq!(s1["images"], s2["images"]);
    assert_eq!(records(&s1), records(&s2));
    for kind in ["ball", "torus", "blobs"] {
        let f = format!("{kind}-mask.nii.gz");
        assert_eq!(
            std::fs::read(one.join(&f)).unwrap(),
            std::fs::read(two.join(&f)).unwrap(),
            "{f}"
        );
    }
}
