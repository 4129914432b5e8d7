//! `ickon replay tdoa` and `ickon convert util --to tdoa` through the
//! binary: the example set, exit code 2 with file, line and column on bad
//! input (a gigabyte of garbage included, generated and streamed), and the
//! UTIL round trip on the real flights (skipped in one line without them).

use std::io::Write;
use std::path::{Path, PathBuf};
use support::run::{estimator, ickon, json, replay_tdoa as replay};

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../deploy/examples/mic-network")
        .join(name)
}

#[test]
fn the_example_set_replays_with_its_truth_clock_found() {
    let out = replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        Some(&example("truth.csv")),
        &["--dim", "2", "--json"],
    );
    let doc = json(&out);
    assert_eq!(doc["dim"], 2);
    let offset = doc["truth_offset"]["offset_s"].as_f64().unwrap();
    assert!((offset - 0.35).abs() < 0.005, "{offset}");
    for name in ["cv-fix", "ls"] {
        assert!(
            estimator(&doc, name)["scored"].as_u64().unwrap() > 50,
            "{doc}"
        );
    }
    // The table names the baseline and the unsolved epochs.
    let out = replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        Some(&example("truth.csv")),
        &[],
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("least squares fixed") && text.contains("\nls "),
        "{text}"
    );
    let out = replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        None,
        &["--dim", "3"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("2D and 3D do not mix"));
}

#[test]
fn an_unknown_anchor_is_named_with_its_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("m.csv");
    std::fs::write(
        &m,
        "# format: ickon-tdoa-log/1\nepoch,time_s,anchor,reference,kind,value\n0,1.0,mic9,,range_m,3.0\n",
    )
    .unwrap();
    let out = replay(&example("anchors.csv"), &m, None, &[]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("m.csv:3:3: column `anchor`: anchor `mic9` is not in the anchors file"),
        "{err}"
    );
}

/// A valid header, then a gigabyte of pseudo-random bytes, written in
/// blocks (never held whole): refused in words at its first bad line.
#[test]
fn a_gigabyte_of_garbage_is_refused_in_words() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("garbage.csv");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&m).unwrap());
    f.write_all(b"# format: ickon-tdoa-log/1\nepoch,time_s,anchor,reference,kind,value\n")
        .unwrap();
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut block = vec![0_u8; 1 << 20];
    for _ in 0..1024 {
        for chunk in block.chunks_mut(8) {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            chunk.copy_from_slice(&state.to_le_bytes());
        }
        f.write_all(&block).unwrap();
    }
    f.flush().unwrap();
    drop(f);
    let out = replay(&example("anchors.csv"), &m, None, &[]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("garbage.csv:3:"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// The real flights: a UTIL flight converted replays to the numbers of
/// `ickon replay util` within 1 %.
#[test]
fn a_converted_util_flight_replays_to_the_same_numbers() {
    let Some(util) = ickon_testkit::real_data("util") else {
        return;
    };
    let flight = util.join("const1-trial1-tdoa3.csv");
    let dir = tempfile::tempdir().unwrap();
    let conv = dir.path().join("log");
    let out = ickon()
        .args(["convert", "util", "--data"])
        .arg(&flight)
        .arg("--anchors")
        .arg(util.join("anchors.csv"))
        .args(["--constellation", "1", "--to", "tdoa"])
        .arg(&conv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let native = json(
        &ickon()
            .args(["replay", "util", "--data"])
            .arg(&flight)
            .arg("--anchors")
            .arg(util.join("anchors.csv"))
            .args(["--constellation", "1", "--json"])
            .output()
            .unwrap(),
    );
    let converted = json(&replay(
        &conv.join("anchors.csv"),
        &conv.join("measurements.csv"),
        Some(&conv.join("truth.csv")),
        &["--dim", "3", "--shadow-m", "0.0908", "--json"],
    ));
    for name in ["tdoa-ekf", "cv-ekf", "window-gn"] {
        for field in ["rmse_3d_m", "mean_3d_m", "p95_3d_m"] {
            let a = estimator(&native, name)[field].as_f64().unwrap();
            let b = estimator(&converted, name)[field].as_f64().unwrap();
            eprintln!("{name} {field}: util {a:.5}, tdoa {b:.5}");
            assert!(
                (a - b).abs() <= 0.01 * a,
                "{name} {field}: util {a}, tdoa {b}"
            );
        }
    }
}

/// The real Plaza runs: converted with their odometry, they replay to the
/// numbers of `ickon replay plaza` within 1 % (the ground filter and dead
/// reckoning, both runs).
#[test]
fn converted_plaza_runs_replay_to_the_same_numbers() {
    let Some(plaza) = ickon_testkit::real_data("plaza") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let conv = dir.path().join("plaza");
    let out = ickon()
        .args(["convert", "plaza", "--data"])
        .arg(&plaza)
        .args(["--to", "tdoa"])
        .arg(&conv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let native = json(
        &ickon()
            .args(["replay", "plaza", "--json", "--data"])
            .arg(&plaza)
            .output()
            .unwrap(),
    );
    for run in native["runs"].as_array().unwrap() {
        let name = run["run"].as_str().unwrap();
        let d = conv.join(name);
        let converted = json(&replay(
            &d.join("anchors.csv"),
            &d.join("measurements.csv"),
            Some(&d.join("truth.csv")),
            &[
                "--odometry",
                d.join("odometry.csv").to_str().unwrap(),
                "--truth-max-gap-s",
                "0.5",
                "--json",
            ],
        ));
        assert_eq!(converted["start_from_truth"], true, "{converted}");
        for (plaza_track, tdoa_name) in [("filter", "tdoa-ekf"), ("odometry", "odometry")] {
            for (plaza_field, tdoa_field) in [
                ("rmse_m", "rmse_3d_m"),
                ("mean_m", "mean_3d_m"),
                ("p95_m", "p95_3d_m"),
                ("max_m", "max_3d_m"),
            ] {
                let a = run[plaza_track][plaza_field].as_f64().unwrap();
                let b = estimator(&converted, tdoa_name)[tdoa_field]
                    .as_f64()
                    .unwrap();
                eprintln!("{name} {tdoa_name} {tdoa_field}: plaza {a:.4}, tdoa {b:.4}");
                assert!(
                    (a - b).abs() <= 0.01 * a,
                    "{name} {tdoa_name} {tdoa_field}: plaza {a}, tdoa {b}"
                );
            }
        }
        // The ground filter's published covariance is judged alike by
        // both readers (the share of poses inside its 95 % ellipse).
        let a = run["inside_95_pct"].as_f64().unwrap();
        let b = estimator(&converted, "tdoa-ekf")["inside_95_pct"]
            .as_f64()
            .unwrap();
        eprintln!("{name} tdoa-ekf inside 95 %: plaza {a:.1}, tdoa {b:.1}");
        assert!(
            (a - b).abs() <= 1.0,
            "{name} inside 95 %: plaza {a}, tdoa {b}"
        );
    }
}

/// A small 2D log with odometry: the ground filter and dead reckoning
/// run beside the baseline, and bad odometry is named by file, line and
/// column with exit code 2.
#[test]
fn odometry_adds_the_ground_filters_and_bad_odometry_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let odo = dir.path().join("odometry.csv");
    // The example's loop is not driven by these increments: the test is
    // about what runs and what is refused, not about accuracy.
    let mut text = String::from("time_s,dx_m,dy_m,dtheta_rad\n");
    for k in 1..=400 {
        text.push_str(&format!("{},0.02,0,0.001\n", 100.0 + f64::from(k) * 0.05));
    }
    std::fs::write(&odo, &text).unwrap();
    let doc = json(&replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        Some(&example("truth.csv")),
        &["--odometry", odo.to_str().unwrap(), "--json"],
    ));
    for name in ["tdoa-ekf", "cv-fix", "ls"] {
        assert!(
            estimator(&doc, name)["estimates"].as_u64().is_some(),
            "{doc}"
        );
    }
    // The example's truth has no heading: dead reckoning has no start,
    // and `all` says it left it out; asked for by name, it is refused.
    assert_eq!(doc["left_out"][0]["name"], "odometry", "{doc}");
    assert!(
        !doc["estimators"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["name"] == "odometry"),
        "{doc}"
    );
    let out = replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        Some(&example("truth.csv")),
        &[
            "--odometry",
            odo.to_str().unwrap(),
            "--estimator",
            "odometry",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("`heading_rad`"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(
        &odo,
        "time_s,dx_m,dy_m,dtheta_rad\n1.0,0.1,0,0\n0.5,0.1,0,nan\n",
    )
    .unwrap();
    let out = replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        None,
        &["--odometry", odo.to_str().unwrap()],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("odometry.csv:3:1: column `time_s`: 0.5 s after 1 s: times go backwards"),
        "{err}"
    );
    // A 2D log takes no IMU; a 3D one no odometry.
    let out = replay(
        &example("anchors.csv"),
        &example("measurements.csv"),
        None,
        &["--imu", odo.to_str().unwrap()],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--imu"));
}

/// A real flight with its IMU: converted with `--imu`, the IMU filter's
/// replay gives the numbers of `ickon replay util --imu` within 1 %, and
/// the other filters' too.
#[test]
fn a_converted_imu_flight_replays_to_the_same_numbers() {
    let Some(util) = ickon_testkit::real_data("util-imu") else {
        return;
    };
    let flight = util.join("pre0425-traj7-tdoa2.csv");
    let anchors = util.join("anchors_0425.csv");
    let dir = tempfile::tempdir().unwrap();
    let conv = dir.path().join("log");
    let out = ickon()
        .args(["convert", "util", "--imu", "--data"])
        .arg(&flight)
        .arg("--anchors")
        .arg(&anchors)
        .args(["--to", "tdoa"])
        .arg(&conv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let native = json(
        &ickon()
            .args(["replay", "util", "--imu", "--json", "--data"])
            .arg(&flight)
            .arg("--anchors")
            .arg(&anchors)
            .output()
            .unwrap(),
    );
    let converted = json(&replay(
        &conv.join("anchors.csv"),
        &conv.join("measurements.csv"),
        Some(&conv.join("truth.csv")),
        &[
            "--imu",
            conv.join("imu.csv").to_str().unwrap(),
            "--imu-lever-arm-m",
            "-0.01245,0.00127,0.0908",
            "--shadow-m",
            "0.0908",
            "--json",
        ],
    ));
    for name in ["imu-eskf", "tdoa-ekf", "cv-ekf", "window-gn"] {
        for field in ["rmse_3d_m", "mean_3d_m", "p95_3d_m"] {
            let a = estimator(&native, name)[field].as_f64().unwrap();
            let b = estimator(&converted, name)[field].as_f64().unwrap();
            eprintln!("{name} {field}: util --imu {a:.5}, tdoa --imu {b:.5}");
            assert!(
                (a - b).abs() <= 0.01 * a,
                "{name} {field}: util {a}, tdoa {b}"
            );
        }
    }
    // Bad IMU rows are named by file, line and column, exit code 2.
    let bad = dir.path().join("imu.csv");
    for (rows, expected) in [
        ("1,0,0,9.8,0,0,0\n0.5,0,0,9.8,0,0,0\n", "imu.csv:3:1:"),
        ("1,0,0,9.8,0,0,0\n2,0,nan,9.8,0,0,0\n", "imu.csv:3:3:"),
    ] {
        std::fs::write(
            &bad,
            format!("time_s,ax_m_s2,ay_m_s2,az_m_s2,gx_rad_s,gy_rad_s,gz_rad_s\n{rows}"),
        )
        .unwrap();
        let out = replay(
            &conv.join("anchors.csv"),
            &conv.join("measurements.csv"),
            None,
            &["--imu", bad.to_str().unwrap()],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(expected), "{err}");
    }
}
