//! `ickon replay plaza` on the real CMU Plaza runs (`$ICKON_DATA/plaza`,
//! skipped in one line without it unless `ICKON_REQUIRE_DATA=1`): the targets
//! (2D RMSE at least 20 % below the data README's simple
//! filter, 1.10 m and 0.81 m, with one parameter set; no error above 5 m
//! after the first minute), the odometry baseline beside them, the plots,
//! and bad input (exit code 2 with the file and line named).

use std::path::PathBuf;
use support::run::{ickon, json};

/// The Plaza folder; called only after `real_data("plaza")` found it.
fn data() -> PathBuf {
    ickon_testkit::data::data_root()
        .expect("ICKON_DATA is checked by real_data first")
        .join("plaza")
}

#[test]
fn both_runs_meet_the_targets_with_the_odometry_baseline_beside_them() {
    let Some(_) = ickon_testkit::real_data("plaza") else {
        return;
    };
    let plots = std::env::temp_dir().join(format!("ickon-plaza-plots-{}", std::process::id()));
    let out = ickon()
        .args(["replay", "plaza", "--json", "--data"])
        .arg(data())
        .arg("--plot")
        .arg(&plots)
        .output()
        .unwrap();
    let doc = json(&out);
    let runs = doc["runs"].as_array().unwrap();
    let names: Vec<&str> = runs.iter().map(|r| r["run"].as_str().unwrap()).collect();
    assert_eq!(names, ["Plaza1", "Plaza2"]);
    for (run, simple_m) in runs.iter().zip([1.10, 0.81]) {
        let f = &run["filter"];
        let rmse = f["rmse_m"].as_f64().unwrap();
        assert!(rmse <= 0.8 * simple_m, "{}: {rmse} m", run["run"]);
        assert!(f["max_after_60s_m"].as_f64().unwrap() < 5.0, "{run}");
        // Dead reckoning from the same start is far worse (data README:
        // 1.9 m on Plaza1, tens of metres on Plaza2).
        let odo = run["odometry"]["rmse_m"].as_f64().unwrap();
        assert!(
            odo > 1.5 && odo > 3.0 * rmse,
            "{}: odometry {odo} m",
            run["run"]
        );
        let name = run["run"].as_str().unwrap();
        for kind in ["trajectory", "error"] {
            assert!(plots.join(format!("{name}_{kind}.png")).is_file());
        }
    }
    std::fs::remove_dir_all(plots).unwrap();
}

#[test]
fn a_malformed_file_is_named_with_its_line_and_exit_code_2() {
    let Some(_) = ickon_testkit::real_data("plaza") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("ickon-plaza-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["gt.csv", "odometry.csv", "beacons.csv"] {
        std::fs::copy(data().join("Plaza2").join(name), dir.join(name)).unwrap();
    }
    std::fs::write(
        dir.join("ranges.csv"),
        "t_s,antenna_id,beacon_id,range_m\n3152.0127,2,1,47.26\n3152.2,2,6,far\n",
    )
    .unwrap();
    let out = ickon()
        .args(["replay", "plaza", "--data"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("ranges.csv:3: `far` is not a number"), "{err}");
    std::fs::remove_dir_all(dir).unwrap();
}
