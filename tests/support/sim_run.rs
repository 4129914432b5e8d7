//! A running `ickon sim` as a test drives it: started in the background
//! with its run file in a directory of the test's own (so `ickon admin`
//! finds it), asked for its status, and waited for.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use ickon_testkit::{ChildGuard, poll_until};
use serde_json::Value;

use crate::ICKON;
/// From `ickon sim` to its run file (the nodes built, started and live).
const START_TIMEOUT: Duration = Duration::from_secs(90);

/// Starts `ickon sim` on `lab` for `run_s` with `args`, JSON report, its
/// run file in `runtime_dir`; returns once the run file is there.
pub fn start_sim(dir: &Path, runtime_dir: &Path, run_s: u64, args: &[&str]) -> ChildGuard {
    let mut sim = Command::new(ICKON);
    sim.args(["sim", "--json"])
        .args(args)
        .args(["--duration", &run_s.to_string()])
        .env("XDG_RUNTIME_DIR", runtime_dir);
    let mut sim = ChildGuard::spawn("sim", sim, dir).expect("ickon sim starts");
    let run_file = runtime_dir.join("ickon").join("lab.json");
    poll_until(START_TIMEOUT, "the run file", || {
        if let Some(status) = sim.exit_status() {
            panic!("ickon sim {status}:\n{}", sim.log());
        }
        run_file.exists().then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    sim
}

/// Waits for the run to end well; its log and its JSON report (the last
/// document on stdout; logs go to stderr, into the same file here, and
/// may be none).
pub fn finish(mut sim: ChildGuard, run_s: u64) -> (String, Value) {
    let status = poll_until(Duration::from_secs(run_s + 60), "ickon sim to end", || {
        sim.exit_status()
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    let log = sim.log();
    assert!(status.success(), "ickon sim {status}:\n{log}");
    let report_at = log.rfind("\n{").map_or(0, |i| i + 1);
    let doc: Value =
        serde_json::from_str(&log[report_at..]).unwrap_or_else(|e| panic!("{e}:\n{log}"));
    (log, doc)
}

/// `ickon admin status --json` of the run whose run file is in `runtime_dir`.
pub fn admin_status(runtime_dir: &Path) -> Value {
    let out = Command::new(ICKON)
        .args(["admin", "status", "--json", "--timeout-ms", "10000"])
        .env("XDG_RUNTIME_DIR", runtime_dir)
        .output()
        .expect("ickon admin runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("status JSON")
}
