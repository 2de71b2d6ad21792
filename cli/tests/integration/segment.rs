//! `levelset phantom` and `levelset segment` end to end: NIfTI in, mask out with the
//! input's header, figures as JSON, bad arguments refused before any work.

#[allow(unused_imports)] // the shared helpers re-export more than these tests use
use crate::common;
use crate::common::{levelset, stderr, stdout};

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
    let m = sparse_levelset::io::image::load(std::path::Path::new(&mask), None).unwrap();
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
        (vec!["--method", "threshold", "--seed", "8,8,8"], "--lower or --upper"),
        (vec!["--method", "gac"], "at least one --seed"),
        (vec!["--method", "gac", "--seed", "8,8"], "expected x,y,z"),
        (vec!["--method", "gac", "--seed", "8,8,8:-2"], "expected x,y,z"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--sigma", "nan"], "sigma"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--add", "snake:1"], "expected METHOD:W"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--add", "gac:1"], "appears twice"),
        (vec!["--method", "gac", "--seed", "8,8,8", "--mesh", "/tmp/m.xyz"], "unknown mesh format"),
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
    assert!(text.contains("4 images, 1 failed, 0 leaked"), "{text}");
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

/// A bright shell with a hole around a dark cavity, as `.npy` (0–1 intensities): GAC
/// seeded in the cavity leaves through the hole.
fn write_shell(path: &std::path::Path, hole: bool) {
    use sparse_levelset::io::image::{save_f32, Image, LoadedImage, IDENTITY};
    let n = 40usize;
    let c = 20.0f64;
    let data: Vec<f32> = (0..n * n * n)
        .map(|i| {
            let p = [(i % n) as f64, ((i / n) % n) as f64, (i / (n * n)) as f64];
            let r = p.iter().map(|v| (v - c).powi(2)).sum::<f64>().sqrt();
            let hole = hole && p[0] > c && (p[1] - c).powi(2) + (p[2] - c).powi(2) < 20.0;
            let noise = ((i as u64).wrapping_mul(2654435761) % 1000) as f32 / 1000.0 - 0.5;
            ((12.0..=15.0).contains(&r) && !hole) as u8 as f32 + 0.2 * noise
        })
        .collect();
    let like = LoadedImage::from_image(Image {
        dims: [n; 3],
        spacing: [1.0; 3],
        data,
        to_world: IDENTITY,
    });
    save_f32(path, &like.image.data, &like).unwrap();
}

/// A run that leaks is stopped, written, warned about and exits with code 3; in a batch it
/// is marked and counted, and the batch exits with 3 when nothing failed. So is a Chan–Vese
/// region that tells nothing apart (`weak_contrast`).
#[test]
fn a_leak_is_reported_with_exit_code_3() {
    let dir = std::env::temp_dir().join(format!("levelset-segleak-{}", std::process::id()));
    let (input, output) = (dir.join("in"), dir.join("out"));
    std::fs::create_dir_all(&input).unwrap();
    let shell = input.join("shell.npy");
    write_shell(&shell, true);
    std::fs::write(
        input.join("shell-seeds.json"),
        r#"{"seeds": [{"center": [20, 20, 20], "radius": 3}]}"#,
    )
    .unwrap();
    let mask = dir.join("mask.npy");
    let one = |method: &str, extra: &[&str]| {
        let mut a =
            vec!["segment", shell.to_str().unwrap(), "--method", method, "--seed", "20,20,20:3"];
        a.extend(["-o", mask.to_str().unwrap(), "--json", "--threads", "2"]);
        a.extend(extra);
        levelset(&a)
    };
    // A batch over the folder: its output and summary.
    let batch = |method: &str| {
        let (i, o) = (input.to_str().unwrap(), output.to_str().unwrap());
        let run = levelset(&["segment", i, "--method", method, "-o", o]);
        let summary = std::fs::read_to_string(output.join("summary.json")).unwrap();
        (run, serde_json::from_str::<serde_json::Value>(&summary).unwrap())
    };
    let o = one("gac", &[]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning:") && stderr(&o).contains("leaked"), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["stop"], "leaked");
    assert_eq!(v["leaked"], true);
    assert!(mask.is_file(), "the mask of a leaked run is written");
    let o = one("gac", &["--no-leak-guard", "--max-iterations", "60"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Chan–Vese in the cavity: the region has the background's intensity; it leaks out
    // through the hole or ends without telling anything apart, and says so either way.
    let o = one("chan-vese", &[]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning:"), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["leaked"] == true || v["weak_contrast"].is_string(), "{v}");
    // A batch: the shell leaks, a phantom ball does not.
    let o =
        levelset(&["phantom", "ball", "--size", "24", "--snr", "4", "-o", input.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (o, s) = batch("gac");
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stdout(&o).contains("2 images, 0 failed, 1 leaked"), "{}", stdout(&o));
    assert_eq!(s["leaked"], 1);
    let leaked: Vec<bool> =
        s["records"].as_array().unwrap().iter().map(|r| r["leaked"].as_bool().unwrap()).collect();
    assert_eq!(leaked, vec![false, true], "ball, then shell");
    // Chan–Vese over a closed shell seeded in its cavity tells nothing apart: a batch warns,
    // counts it and exits with 3.
    write_shell(&shell, false);
    let (o, s) = batch("chan-vese");
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stdout(&o).contains("0 leaked, 1 with weak contrast"), "{}", stdout(&o));
    assert!(stderr(&o).contains("not told apart"), "{}", stderr(&o));
    assert_eq!(s["weak_contrast"], 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A run that ends with nothing inside (GAC shrinking from a box over noise, with no object
/// to stop on) writes its empty mask, warns, says `"vanished": true` and exits with 3; a
/// batch counts it.
#[test]
fn an_empty_segmentation_is_reported_with_exit_code_3() {
    let dir = std::env::temp_dir().join(format!("levelset-segvanish-{}", std::process::id()));
    let (input, output) = (dir.join("in"), dir.join("out"));
    std::fs::create_dir_all(&input).unwrap();
    let n = 64usize;
    // Uniform noise around 0.5 (a multiplicative hash, no object), and a box 8 pixels in.
    let noise: Vec<u8> = (0..n * n)
        .flat_map(|i| {
            let u = ((i as u64).wrapping_mul(2654435761) % 1000) as f32 / 1000.0;
            (0.5 + 0.1 * (u - 0.5)).to_le_bytes()
        })
        .collect();
    let image = input.join("noise.npy");
    common::write_npy(&image, "<f4", &[n, n], &noise);
    let inside = |i: usize| (8..n - 8).contains(&(i % n)) && (8..n - 8).contains(&(i / n));
    let start: Vec<u8> = (0..n * n).map(|i| u8::from(inside(i))).collect();
    let box_mask = dir.join("box.npy");
    common::write_npy(&box_mask, "|u1", &[n, n], &start);
    let mask = dir.join("mask.npy");
    let (i, b, m) = (image.to_str().unwrap(), box_mask.to_str().unwrap(), mask.to_str().unwrap());
    let shrink = ["--method", "gac", "--propagation", "-1", "--init-mask", b];
    let mut a = vec!["segment", i, "-o", m, "--json", "--threads", "2"];
    a.extend(shrink);
    let o = levelset(&a);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning:") && stderr(&o).contains("vanished"), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!((v["stop"].as_str(), v["voxels"].as_u64()), (Some("vanished"), Some(0)), "{v}");
    assert_eq!(v["vanished"], true);
    assert!(mask.is_file(), "the empty mask is written");
    // A batch over the folder of the noise image.
    let mut a = vec!["segment", input.to_str().unwrap(), "-o", output.to_str().unwrap()];
    a.extend(shrink);
    let run = levelset(&a);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(stdout(&run).contains(", 1 vanished"), "{}", stdout(&run));
    let summary = std::fs::read_to_string(output.join("summary.json")).unwrap();
    let s: serde_json::Value = serde_json::from_str(&summary).unwrap();
    assert_eq!(s["vanished"], 1, "{s}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A threshold window open at the top: `--lower` alone.
#[test]
fn an_open_threshold_window_from_the_command_line() {
    let dir = std::env::temp_dir().join(format!("levelset-segopen-{}", std::process::id()));
    let d = dir.to_str().unwrap();
    assert!(levelset(&["phantom", "ball", "--size", "32", "--snr", "4", "-o", d]).status.success());
    let (img, truth, mask) =
        (format!("{d}/ball.nii.gz"), format!("{d}/ball-truth.nii.gz"), format!("{d}/m.nii.gz"));
    for window in [
        vec!["--lower", "150"],
        vec!["--lower", "150", "--upper", "inf"],
        vec!["--lower", "150", "--upper", "1e9"],
    ] {
        let mut a = vec!["segment", img.as_str(), "--method", "threshold", "--seed", "16,16,16:3"];
        a.extend(window.iter().copied());
        a.extend(["-o", mask.as_str(), "--truth", truth.as_str(), "--json"]);
        let o = levelset(&a);
        assert!(o.status.success(), "{window:?}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        assert!(v["dice"].as_f64().unwrap() > 0.95, "{window:?}: {v}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
