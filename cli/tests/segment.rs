//! `levelset phantom` and `levelset segment` end to end: NIfTI in, mask out with the
//! input's header, figures as JSON, bad arguments refused before any work.

#[allow(unused_imports)] // the shared helpers re-export more than these tests use
mod common;
use common::{levelset, stderr, stdout};

#[test]
fn phantom_then_segment_finds_the_ball() {
    let dir = std::env::temp_dir().join(format!("levelset-seg-{}", std::process::id()));
    let d = dir.to_str().unwrap();
    let o = levelset(&["phantom", "ball", "--size", "40", "--snr", "3", "-o", d]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = format!("{d}/ball.nii.gz");
    let truth = format!("{d}/ball-truth.nii.gz");
    let mask = format!("{d}/mask.nii.gz");
    let ls = format!("{d}/phi.npy");
    let o = levelset(&[
        "segment",
        &img,
        "--method",
        "chan-vese",
        "--seed",
        "20,20,20:3",
        "-o",
        &mask,
        "--truth",
        &truth,
        "--level-set",
        &ls,
        "--json",
        "--threads",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["dice"].as_f64().unwrap() > 0.95, "{v}");
    assert!(v["iterations"].as_u64().unwrap() > 10);
    let m = sparse_levelset::image::load(std::path::Path::new(&mask), None).unwrap();
    assert_eq!(m.image.dims, [40, 40, 40]);
    assert!(m.image.data.iter().all(|&x| x == 0.0 || x == 1.0));
    assert!(std::path::Path::new(&ls).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn segment_refuses_bad_arguments_before_any_work() {
    let dir = std::env::temp_dir().join(format!("levelset-segbad-{}", std::process::id()));
    let d = dir.to_str().unwrap();
    assert!(levelset(&["phantom", "ball", "--size", "16", "-o", d]).status.success());
    let img = format!("{d}/ball.nii.gz");
    let out = format!("{d}/out.nii.gz");
    for (args, expect) in [
        (vec!["--method", "threshold", "--seed", "8,8,8"], "--lower and --upper"),
        (vec!["--method", "gac"], "at least one --seed"),
        (vec!["--method", "gac", "--seed", "8,8"], "expected x,y,z"),
        (vec!["--method", "gac", "--seed", "8,8,8:-2"], "expected x,y,z"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--sigma", "nan"], "sigma"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--add", "snake:1"], "expected METHOD:W"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--add", "gac:1"], "appears twice"),
    ] {
        let mut a = vec!["segment", img.as_str()];
        a.extend(args);
        a.extend(["-o", out.as_str()]);
        let o = levelset(&a);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(expect), "{:?}: {}", a, stderr(&o));
        assert!(!std::path::Path::new(&out).exists());
    }
    let o =
        levelset(&["segment", "missing.nii.gz", "--method", "gac", "--seed", "1,1,1", "-o", &out]);
    assert!(!o.status.success());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Batch mode: every image of a folder with its seeds file, a broken file reported and
/// skipped, the others written, one summary.
#[test]
fn batch_mode_segments_a_folder_and_skips_a_broken_file() {
    let dir = std::env::temp_dir().join(format!("levelset-segbatch-{}", std::process::id()));
    let (input, output) = (dir.join("in"), dir.join("out"));
    let i = input.to_str().unwrap();
    for kind in ["ball", "torus", "blobs"] {
        let o = levelset(&["phantom", kind, "--size", "24", "--snr", "4", "-o", i]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    std::fs::write(input.join("broken.nii.gz"), b"not a scan").unwrap();
    let o = levelset(&[
        "segment",
        i,
        "--method",
        "threshold",
        "-o",
        output.to_str().unwrap(),
        "--threads",
        "2",
    ]);
    assert!(!o.status.success(), "a failed image makes the exit code nonzero");
    let text = stdout(&o);
    assert!(text.contains("broken.nii.gz: FAILED, skipped"), "{text}");
    assert!(text.contains("4 images, 1 failed"), "{text}");
    for kind in ["ball", "torus", "blobs"] {
        assert!(output.join(format!("{kind}-mask.nii.gz")).is_file(), "{kind}");
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(output.join("summary.json")).unwrap())
            .unwrap();
    let records = s["records"].as_array().unwrap();
    assert_eq!(records.len(), 4);
    for r in records.iter().filter(|r| r.get("error").is_none()) {
        // The thresholds came from each seeds file; the truths were found beside the images.
        assert!(r["dice"].as_f64().unwrap() > 0.9, "{r}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
