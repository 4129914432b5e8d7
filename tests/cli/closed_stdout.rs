//! A command whose reader goes away (`ickon site secure ... | head -1`)
//! ends quietly, as a Unix filter does; a stdout that fails otherwise (a
//! full disk) is still reported.

use std::process::{Command, Stdio};
use support::ICKON;

/// Runs `ickon args` in `dir` with its stdout a pipe whose reader is
/// already gone; returns its exit code and its stderr.
fn with_closed_stdout(args: &[&str], dir: &std::path::Path) -> (Option<i32>, String) {
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    let out = Command::new(ICKON)
        .args(args)
        .current_dir(dir)
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .expect("ickon runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_reader_that_went_away_ends_the_command_quietly() {
    let tmp = tempfile::tempdir().unwrap();
    for args in [
        &["site", "secure", "--out", "s", "--sim"][..],
        &["site", "check", "--site", "lab"][..],
    ] {
        let (code, stderr) = with_closed_stdout(args, tmp.path());
        // 141: the status a shell shows for a process a closed pipe ended.
        assert_eq!(code, Some(141), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    // What it did before printing is done whole.
    assert!(tmp.path().join("s/users.txt").is_file());
}

#[test]
fn a_stdout_that_fails_otherwise_is_still_reported() {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full");
    let out = Command::new(ICKON)
        .args(["site", "check", "--site", "lab"])
        .stdout(full)
        .output()
        .expect("ickon runs");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("No space left on device"), "{stderr}");
}
