//! Running the `ickon` binary under test and reading what it printed:
//! the command, its `--json` document (the run must have succeeded, else
//! the test fails with its stderr), one estimator's entry of a replay's
//! document, and `ickon replay tdoa` on a log's files.

use std::path::Path;
use std::process::{Command, Output};

use crate::ICKON;

/// A command running the `ickon` binary under test.
pub fn ickon() -> Command {
    Command::new(ICKON)
}

/// The JSON document `out` printed; fails the test with its stderr when
/// the run did not succeed.
pub fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The entry of estimator `name` in a replay's `--json` document
/// (`estimators`, each with its `name`).
pub fn estimator<'a>(doc: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    doc["estimators"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == name)
        .unwrap_or_else(|| panic!("no {name} in {doc}"))
}

/// `ickon replay tdoa` on `anchors` and `measurements` (with `truth` when
/// given), then `extra`.
pub fn replay_tdoa(
    anchors: &Path,
    measurements: &Path,
    truth: Option<&Path>,
    extra: &[&str],
) -> Output {
    let mut cmd = ickon();
    cmd.args(["replay", "tdoa", "--anchors"])
        .arg(anchors)
        .arg("--measurements")
        .arg(measurements);
    if let Some(t) = truth {
        cmd.arg("--truth").arg(t);
    }
    cmd.args(extra).output().unwrap()
}
