//! Outputs that hold: a write interrupted by SIGINT leaves neither a temporary file nor a
//! partial output.

use crate::common::{ball, npy, tmp};
use std::process::Command;
use std::time::{Duration, Instant};

#[test]
fn sigint_during_a_write_leaves_no_temporary_file() {
    let dir = tmp("sigint");
    std::fs::create_dir_all(&dir).unwrap();
    let field = npy("sigint-ball.npy", &ball([24, 24, 24], [11.5; 3], 7.0, 1.0));
    let sls = dir.join("ball.sls");
    let bin = env!("CARGO_BIN_EXE_levelset");
    let o = Command::new(bin).args(["convert", field.to_str().unwrap()]).arg(&sls).output();
    assert!(o.unwrap().status.success());
    // A dense output of about 400³ voxels: its write lasts long enough to be interrupted.
    let out = dir.join("big.npy");
    let mut child = Command::new(bin)
        .arg("convert")
        .arg(&sls)
        .arg(&out)
        .args(["--margin", "190", "--quiet"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let temporary = || {
        std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
    };
    let start = Instant::now();
    let mut seen = false;
    while start.elapsed() < Duration::from_secs(60) {
        if temporary() {
            seen = true;
            break;
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(seen, "the write finished before it could be interrupted");
    let sent = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(sent.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    assert!(!temporary(), "a temporary file was left");
    assert!(!out.exists(), "a partial output was left");
}

/// A command with two outputs whose second write fails (the file-size limit, `ulimit -f`,
/// with SIGXFSZ ignored so the write returns EFBIG): one `error:` line, exit 1, and both
/// outputs as they were before the command, with no temporary file left.
#[test]
fn a_failed_second_output_leaves_the_first_as_it_was() {
    let dir = tmp("second-output");
    std::fs::create_dir_all(&dir).unwrap();
    let bin = env!("CARGO_BIN_EXE_levelset");
    let o = Command::new(bin)
        .args(["phantom", "ball", "--size", "48", "--snr", "4", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (mask, phi) = (dir.join("mask.nii.gz"), dir.join("phi.npy"));
    std::fs::write(&mask, b"the previous mask").unwrap();
    std::fs::write(&phi, b"the previous level set").unwrap();
    let seeds: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ball-seeds.json")).unwrap())
            .unwrap();
    let s = &seeds["seeds"][0];
    let c = &s["center"];
    let seed = format!("{},{},{}:{}", c[0], c[1], c[2], s["radius"]);
    let args = [
        "segment".to_string(),
        dir.join("ball.nii.gz").display().to_string(),
        "--method".into(),
        "threshold".into(),
        "--seed".into(),
        seed,
        "--lower".into(),
        seeds["lower"].to_string(),
        "-o".into(),
        mask.display().to_string(),
        "--level-set".into(),
        phi.display().to_string(),
        "--quiet".into(),
    ];
    let run = |limit: &str| {
        let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
        Command::new("sh")
            .arg("-c")
            .arg(format!("trap '' XFSZ; ulimit -f {limit} && exec '{bin}' {}", quoted.join(" ")))
            .output()
            .unwrap()
    };
    // 100 KiB (512-byte blocks): the mask (a few KiB compressed) fits, the level set's
    // 48³ float32 array (432 KiB) does not.
    let o = run("200");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.starts_with("error:") && err.lines().count() == 1, "{err}");
    assert!(err.contains("phi.npy"), "{err}");
    assert_eq!(std::fs::read(&mask).unwrap(), b"the previous mask");
    assert_eq!(std::fs::read(&phi).unwrap(), b"the previous level set");
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.ends_with(".tmp")), "{names:?}");
    // Without the limit both are replaced together.
    let o = run("unlimited");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(std::fs::read(&mask).unwrap(), b"the previous mask");
    assert!(std::fs::metadata(&phi).unwrap().len() > 48 * 48 * 48 * 4);
}

/// Under an MPI launcher (its environment variables), a command that runs in one process
/// refuses before any work instead of running whole on every rank.
#[test]
fn single_process_commands_refuse_several_mpi_ranks() {
    let f = npy("mpi-ball.npy", &ball([16, 16, 16], [7.5; 3], 4.0, 1.0));
    let out = tmp("mpi-out.sls");
    let o = Command::new(env!("CARGO_BIN_EXE_levelset"))
        .args(["filter", f.to_str().unwrap(), "-o", out.to_str().unwrap(), "--op", "dilate:1"])
        .env("OMPI_COMM_WORLD_SIZE", "2")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("started on 2 MPI ranks"), "{err}");
    assert!(!out.exists());
}
