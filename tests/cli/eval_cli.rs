//! `ickon eval` end to end: one tour of one route, JSON on stdout.

use support::run::{estimator, ickon, json, replay_tdoa};

#[test]
fn one_tour_json_has_the_the_ickon_papers_table_for_every_estimator() {
    let out = ickon()
        .args([
            "eval",
            "--route",
            "rectangle",
            "--tours",
            "1",
            "--json",
            "--seed",
            "3",
        ])
        .output()
        .unwrap();
    let doc = json(&out);
    assert_eq!(doc["profile"], "paper");
    assert_eq!(doc["seed"], 3);
    let results = doc["results"].as_array().unwrap();
    let names: Vec<&str> = results
        .iter()
        .map(|r| r["estimator"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "odometry",
            "msu-raw",
            "ickon-akf",
            "gyro-ckf",
            "cda",
            "cda-msu",
            "tdoa-ekf"
        ]
    );
    for r in results {
        assert_eq!(r["route"], "rectangle");
        let tours = r["tours"].as_array().unwrap();
        assert_eq!(tours.len(), 1);
        assert_eq!(tours[0]["tour"], 1);
        for key in [
            "mean_mm",
            "std_mm",
            "under_30",
            "under_60",
            "under_100",
            "rmse_mm",
            "heading_std_deg",
        ] {
            assert!(r["mean"][key].as_f64().unwrap().is_finite(), "{key}");
        }
    }
    let raw = results
        .iter()
        .find(|r| r["estimator"] == "msu-raw")
        .unwrap();
    assert!(raw["fix_mean_mm"].as_f64().unwrap() > 0.0);
    let akf = results
        .iter()
        .find(|r| r["estimator"] == "ickon-akf")
        .unwrap();
    assert!(akf["mean"]["mean_mm"].as_f64() < raw["mean"]["mean_mm"].as_f64());
}

#[test]
fn unknown_names_exit_with_code_two_and_list_the_valid_ones() {
    for (flag, value, listed) in [
        ("--estimator", "kalman", "ickon-akf"),
        ("--route", "nowhere", "route-2"),
        ("--profile", "rough", "harsh"),
    ] {
        let out = ickon().args(["eval", flag, value]).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{flag}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(value) && err.contains(listed), "{err}");
        assert!(out.stdout.is_empty());
    }
}

/// A flag that does not apply to the kind of run asked for is refused, not
/// silently ignored (`--plot` with `--robots` would draw nothing and say
/// nothing).
#[test]
fn flags_of_the_other_kind_of_run_are_refused() {
    let cases: [&[&str]; 6] = [
        &["--robots", "2", "--plot", "/tmp/never-written"],
        &["--robots", "2", "--tours", "3"],
        &["--robots", "2", "--route", "route-1"],
        &["--duration", "5"],
        &["--firing", "all"],
        &["--fire-range-m", "9"],
    ];
    for args in cases {
        let out = ickon().arg("eval").args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--robots"), "{args:?}: {err}");
        assert!(out.stdout.is_empty());
    }
    assert!(!std::path::Path::new("/tmp/never-written").exists());
}

/// `--learn-cell-sync` and `--local-wind` are options of `tdoa-ekf`: with
/// another estimator they are refused by name (exit 2), not silently dropped.
#[test]
fn the_filter_options_are_refused_for_an_estimator_without_them() {
    for flag in ["--learn-cell-sync", "--local-wind"] {
        for args in [
            &["eval", "--estimator", "ickon-akf", flag][..],
            &["eval", "--estimator", "gyro-ckf", "--robots", "2", flag],
            &["sim", "--estimator", "msu-raw", flag],
        ] {
            let out = ickon().args(args).output().unwrap();
            assert_eq!(out.status.code(), Some(2), "{args:?}");
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(
                err.contains(flag) && err.contains("tdoa-ekf"),
                "{args:?}: {err}"
            );
            assert!(out.stdout.is_empty());
        }
    }
}

/// `--local-wind` reaches `tdoa-ekf`: the same seed and tour in a hall's
/// air gives another track with the state than without it.
#[test]
fn the_local_wind_switch_changes_what_the_filter_estimates() {
    let run = |extra: &[&str]| {
        let out = ickon()
            .args([
                "eval",
                "--estimator",
                "tdoa-ekf",
                "--profile",
                "building",
                "--route",
                "route-1",
                "--tours",
                "1",
                "--seed",
                "1",
                "--json",
            ])
            .args(extra)
            .output()
            .unwrap();
        let doc = json(&out);
        doc["results"][0]["mean"]["mean_mm"].as_f64().unwrap()
    };
    let still = run(&[]);
    let windy = run(&["--local-wind"]);
    assert!(still.is_finite() && windy.is_finite());
    assert!(
        (still - windy).abs() > 0.01,
        "without {still} mm, with {windy} mm"
    );
}

#[test]
fn plot_directory_gets_one_picture_per_estimator_route_and_tour_plus_the_comparison() {
    let dir = std::env::temp_dir().join(format!("ickon-eval-plot-{}", std::process::id()));
    let out = ickon()
        .args([
            "eval",
            "--route",
            "eight",
            "--tours",
            "1",
            "--estimator",
            "ickon-akf",
            "--json",
            "--plot",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.join("ickon-akf_eight_tour01.png").is_file());
    assert!(dir.join("comparison.png").is_file());
    std::fs::remove_dir_all(&dir).ok();
}

/// `ickon eval --export-tdoa` writes the run's arrivals, truth and odometry;
/// `ickon replay tdoa` on them gives the raw fixes' score of `ickon eval`
/// (`msu-raw`: every fix against the truth at its own time) as `ls`, within
/// 10 %: the same solver on the same arrivals, where the MSU also relates
/// each arrival to where the wheels say the robot was when it came, retries
/// without transmitters hidden from it and picks roots by its last fix.
#[test]
fn an_exported_run_replays_to_the_raw_fixes_of_eval() {
    let dir = tempfile::tempdir().unwrap();
    let export = dir.path().join("run");
    let doc = json(&export_one_tour("rectangle", &export));
    let raw = &doc["results"][0];
    let (mean_mm, rmse_mm) = (
        raw["fix_mean_mm"].as_f64().unwrap(),
        raw["fix_rmse_mm"].as_f64().unwrap(),
    );
    let run = export.join("rectangle");
    let odometry = run.join("odometry.csv");
    let doc = json(&replay_tdoa(
        &run.join("anchors.csv"),
        &run.join("measurements.csv"),
        Some(&run.join("truth.csv")),
        &["--json", "--odometry", odometry.to_str().unwrap()],
    ));
    assert_eq!(doc["dim"], 2);
    assert_eq!(doc["truth_offset"], serde_json::Value::Null);
    let ls = estimator(&doc, "ls");
    let ls_mean_mm = ls["mean_3d_m"].as_f64().unwrap() * 1e3;
    let ls_rmse_mm = ls["rmse_3d_m"].as_f64().unwrap() * 1e3;
    eprintln!(
        "eval msu-raw {mean_mm:.2} / {rmse_mm:.2} mm, replay ls {ls_mean_mm:.2} / {ls_rmse_mm:.2} mm"
    );
    assert!(
        (ls_mean_mm / mean_mm - 1.0).abs() < 0.10,
        "{ls_mean_mm} vs {mean_mm}"
    );
    assert!(
        (ls_rmse_mm / rmse_mm - 1.0).abs() < 0.10,
        "{ls_rmse_mm} vs {rmse_mm}"
    );
    // Every cycle the MSU solved is an epoch the replay solved or counted.
    let rate_hz = raw["fix_rate_hz"].as_f64().unwrap();
    let ls_rate_hz = ls["output_rate_hz"].as_f64().unwrap();
    assert!(
        (ls_rate_hz / rate_hz - 1.0).abs() < 0.05,
        "{ls_rate_hz} vs {rate_hz}"
    );
    // The odometry and the truth's heading start the ground filter and
    // dead reckoning at the truth's first pose.
    assert_eq!(doc["start_from_truth"], true);
    for name in ["tdoa-ekf", "odometry", "cv-fix"] {
        assert!(
            estimator(&doc, name)["scored"].as_u64().unwrap() > 100,
            "{name}"
        );
    }
    // A second export into the same directory does not overwrite it.
    let again = export_one_tour("rectangle", &export);
    assert_eq!(again.status.code(), Some(1));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.contains("cannot create") && err.contains("anchors.csv"),
        "{err}"
    );
}

/// `deploy/examples/ickon-robot/` is `ickon eval --export-tdoa` of one
/// tour of `rectangle` (seed 1), byte for byte (`ICKON_WRITE_EXAMPLES=1`
/// writes it anew after a change to the simulation), and replays with
/// dead reckoning from the truth's heading.
#[test]
fn the_robot_example_is_an_export_and_replays_with_its_odometry() {
    let example =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/examples/ickon-robot");
    let dir = tempfile::tempdir().unwrap();
    let out = export_one_tour("rectangle", dir.path());
    json(&out);
    let names = [
        "anchors.csv",
        "measurements.csv",
        "truth.csv",
        "odometry.csv",
    ];
    for name in names {
        let fresh = std::fs::read(dir.path().join("rectangle").join(name)).unwrap();
        if std::env::var_os("ICKON_WRITE_EXAMPLES").is_some() {
            std::fs::write(example.join(name), &fresh).unwrap();
        }
        let kept = std::fs::read(example.join(name)).unwrap();
        assert!(
            kept == fresh,
            "{name} differs from a fresh export: run this test with ICKON_WRITE_EXAMPLES=1"
        );
    }
    let odometry = example.join("odometry.csv");
    let doc = json(&replay_tdoa(
        &example.join("anchors.csv"),
        &example.join("measurements.csv"),
        Some(&example.join("truth.csv")),
        &[
            "--json",
            "--dim",
            "2",
            "--odometry",
            odometry.to_str().unwrap(),
        ],
    ));
    assert_eq!(doc["start_from_truth"], true);
    let rmse = |name: &str| estimator(&doc, name)["rmse_3d_m"].as_f64().unwrap();
    // Within the 1 m of a lost filter, beyond a few centimetres of a fix.
    assert!(
        rmse("odometry") > 0.1 && rmse("odometry") < 1.0,
        "{}",
        rmse("odometry")
    );
    assert!(rmse("tdoa-ekf") < 0.06, "{}", rmse("tdoa-ekf"));
    assert!(rmse("ls") < 0.06, "{}", rmse("ls"));
}

/// An exported figure-eight replays with the ground filter on the robot:
/// at the start a transmitter of the neighbouring cell, heard by a
/// reflection, fires first in the cycle, and differences against each
/// epoch's first arrival would hand that reflection to every one of them
/// (the filter would lose the robot for the whole tour, over a metre off);
/// the chain of consecutive differences the MSU hands the filter confines
/// it to one arrival.
#[test]
fn an_exported_figure_eight_keeps_the_ground_filter_on_the_robot() {
    let dir = tempfile::tempdir().unwrap();
    let out = export_one_tour("eight", dir.path());
    json(&out);
    let run = dir.path().join("eight");
    let odometry = run.join("odometry.csv");
    let doc = json(&replay_tdoa(
        &run.join("anchors.csv"),
        &run.join("measurements.csv"),
        Some(&run.join("truth.csv")),
        &[
            "--json",
            "--estimator",
            "tdoa-ekf,odometry,ls",
            "--odometry",
            odometry.to_str().unwrap(),
        ],
    ));
    let rmse_m = |name| estimator(&doc, name)["rmse_3d_m"].as_f64().unwrap();
    let ekf = estimator(&doc, "tdoa-ekf");
    eprintln!(
        "tdoa-ekf {:.4} m ({} % rejected), odometry {:.4} m, ls {:.4} m",
        rmse_m("tdoa-ekf"),
        ekf["rejected_pct"],
        rmse_m("odometry"),
        rmse_m("ls")
    );
    // Better than the per-epoch fix and than the wheels alone.
    assert!(rmse_m("tdoa-ekf") < rmse_m("ls"), "{doc}");
    assert!(rmse_m("tdoa-ekf") < rmse_m("odometry"), "{doc}");
    assert!(ekf["rejected_pct"].as_f64().unwrap() < 30.0, "{doc}");
}

/// `ickon eval` of one tour of `route` with raw fixes, the central unit's
/// learning off, exported into `dir`.
fn export_one_tour(route: &str, dir: &std::path::Path) -> std::process::Output {
    ickon()
        .args([
            "eval",
            "--route",
            route,
            "--tours",
            "1",
            "--estimator",
            "msu-raw",
            "--no-survey-calibration",
            "--no-speed-of-sound",
            "--json",
            "--export-tdoa",
        ])
        .arg(dir)
        .output()
        .unwrap()
}
