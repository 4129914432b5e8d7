//! `ickon convert mcap --to tdoa` end to end: a recording of the mesh
//! (`ickon sim --record`, one robot, occupancy firing), converted, replayed
//! by `ickon replay tdoa`, and its per-epoch least-squares baseline `ls`
//! held against the one `ickon replay mcap` computes from the recording
//! itself: the same arrivals, the same solver, the same scoring, so the
//! two agree to within rounding; and the fixes of the converted log are
//! those of the agent (`msu-raw`) within the difference of their methods.

use std::path::Path;
use std::process::{Command, Output};

use support::ICKON;
use support::run::{estimator, json, replay_tdoa};

/// Mesh duration once every node is live, seconds: enough cycles (about
/// ten a second) for a score, short for a test.
const DURATION_S: &str = "8";

fn ickon(args: &[&str], path: &Path) -> Output {
    Command::new(ICKON)
        .args(args)
        .arg(path)
        .output()
        .expect("ickon starts")
}

fn succeeded(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_converted_recording_replays_to_the_least_squares_of_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    let out = ickon(
        &[
            "sim",
            "--robots",
            "1",
            "--json",
            "--duration",
            DURATION_S,
            "--record",
        ],
        &file,
    );
    succeeded(&out, "ickon sim --record");
    let logs = dir.path().join("logs");
    let out = ickon(&["convert", "mcap", "--to", "tdoa"], &logs);
    assert!(!out.status.success(), "no file given, yet it succeeded");
    let out = Command::new(ICKON)
        .args(["convert", "mcap", "--to", "tdoa"])
        .arg(&file)
        .arg(&logs)
        .output()
        .unwrap();
    succeeded(&out, "ickon convert mcap");
    let out = ickon(
        &["replay", "mcap", "--json", "--estimator", "msu-raw"],
        &file,
    );
    let recording = json(&out);
    let robot = &recording["robots"][0];
    let id = robot["id"].as_str().unwrap();
    let native = &robot["ls"];
    let run = logs.join(id);
    let odometry = run.join("odometry.csv");
    let converted = json(&replay_tdoa(
        &run.join("anchors.csv"),
        &run.join("measurements.csv"),
        Some(&run.join("truth.csv")),
        &["--json", "--odometry", odometry.to_str().unwrap()],
    ));
    let ls = estimator(&converted, "ls");
    eprintln!("replay mcap ls: {native}\nreplay tdoa ls: {ls}");
    assert_eq!(converted["epochs"], native["epochs"]);
    assert_eq!(converted["solved_epochs"], native["fixes"]);
    assert!(native["scored"].as_u64().unwrap() > 40, "{native}");
    for (mcap, tdoa) in [
        ("rmse_m", "rmse_3d_m"),
        ("mean_m", "mean_3d_m"),
        ("median_m", "median_3d_m"),
    ] {
        let (a, b) = (native[mcap].as_f64().unwrap(), ls[tdoa].as_f64().unwrap());
        assert!((b / a - 1.0).abs() < 0.01, "{mcap}: {a} vs {b}");
    }
    // The agent's raw fixes: the same solver, which also relates each
    // arrival to where the wheels say the robot was when it came: close,
    // not equal.
    let raw = &robot["estimators"][0];
    assert_eq!(raw["estimator"], "msu-raw");
    let raw_rmse_m = raw["score"]["rmse_mm"].as_f64().unwrap() * 1e-3;
    let ls_rmse_m = ls["rmse_3d_m"].as_f64().unwrap();
    eprintln!("msu-raw rmse {raw_rmse_m:.4} m, converted ls rmse {ls_rmse_m:.4} m");
    assert!(
        (ls_rmse_m / raw_rmse_m - 1.0).abs() < 0.5,
        "{raw_rmse_m} vs {ls_rmse_m}"
    );
}
