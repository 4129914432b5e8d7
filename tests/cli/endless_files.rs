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

/// The replays' measurement files are read however large they are, but an
/// endless line is refused at once, never buffered.
#[test]
fn an_endless_line_is_refused_by_the_replays() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let util_anchors = dir.path().join("anchors.csv");
    std::fs::write(&util_anchors, "anchor_id,x_m,y_m,z_m\n0,0,0,0\n1,1,0,0\n").expect("written");
    let util_anchors = util_anchors.to_str().expect("UTF-8 path");
    let out = dir.path().join("out");
    let log_anchors = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../deploy/examples/mic-network/anchors.csv"
    );
    let cases: [&[&str]; 3] = [
        &[
            "replay",
            "util",
            "--data",
            "/dev/zero",
            "--anchors",
            util_anchors,
        ],
        &[
            "replay",
            "tdoa",
            "--anchors",
            log_anchors,
            "--measurements",
            "/dev/zero",
        ],
        &[
            "convert",
            "util",
            "--data",
            "/dev/zero",
            "--anchors",
            util_anchors,
            "--to",
            "tdoa",
            out.to_str().expect("UTF-8 path"),
        ],
    ];
    for args in cases {
        let (code, said) = ickon(args);
        assert_eq!(code, Some(2), "ickon {args:?}: {said}");
        assert!(said.contains("longer than"), "ickon {args:?}: {said}");
    }
}
