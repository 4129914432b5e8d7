//! A path to something that never ends (`/dev/zero`) or is far too large,
//! given wherever `ickon` reads a file of the user's: refused with exit
//! code 2 and a reason, at once, never read into memory.

use std::process::Command;
use std::time::{Duration, Instant};

/// Runs `ickon args`, killing it after 30 s; (exit code, stderr).
fn ickon(args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ickon"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("ickon starts");
    let deadline = Instant::now() + Duration::from_secs(30);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("ickon {args:?} still running after 30 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn an_endless_file_is_refused_everywhere_a_file_is_read() {
    let cases: [&[&str]; 6] = [
        &["site", "check", "/dev/zero"],
        &["msu", "check", "/dev/zero"],
        &["eval", "--profile", "/dev/zero"],
        &["sim", "--profile", "/dev/zero", "--duration", "1"],
        &[
            "sim",
            "--http",
            "--http-token-file",
            "/dev/zero",
            "--duration",
            "1",
        ],
        &["admin", "reload", "/dev/zero"],
    ];
    for args in cases {
        let (code, stderr) = ickon(args);
        assert_eq!(code, Some(2), "ickon {args:?}: {stderr}");
        assert!(stderr.contains("larger than"), "ickon {args:?}: {stderr}");
    }
}
