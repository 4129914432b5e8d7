//! A path to something that never ends (`/dev/zero`) or is far too large,
//! given wherever `ickon` reads a file of the user's: refused with exit
//! code 2 and a reason, at once, never read into memory.

use std::process::Command;
use std::time::Duration;

use ickon_testkit::{ChildGuard, poll_until};
use support::ICKON;

/// Runs `ickon args`, killed if it has not ended within 30 s; (exit code,
/// what it wrote).
fn ickon(args: &[&str]) -> (Option<i32>, String) {
    let logs = tempfile::tempdir().expect("log directory");
    let mut cmd = Command::new(ICKON);
    cmd.args(args);
    let mut child = ChildGuard::spawn("ickon", cmd, logs.path()).expect("ickon starts");
    let status = poll_until(Duration::from_secs(30), "ickon to exit", || {
        child.exit_status()
    })
    .unwrap_or_else(|e| panic!("ickon {args:?}: {e}"));
    (status.code(), child.log())
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
        let (code, said) = ickon(args);
        assert_eq!(code, Some(2), "ickon {args:?}: {said}");
        assert!(said.contains("larger than"), "ickon {args:?}: {said}");
    }
}
