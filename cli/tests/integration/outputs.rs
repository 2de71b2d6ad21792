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
