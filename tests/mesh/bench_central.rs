//! Fleets larger than a site defines, and the central unit's capacity
//! benchmark, through the `ickon` binary: `ickon bench central` on `lab`
//! extended to 30 robots (25 of them added on its routes) reports sane
//! figures and a central unit that saw every synthetic robot; `ickon sim`
//! with robots added runs them with fixes, every node reading the same
//! extended site; absurd sizes are refused with exit 2 before anything
//! starts.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;
use support::ICKON;

/// A bench or sim run of a few seconds, its start-up included.
const RUN_TIMEOUT: Duration = Duration::from_secs(120);

/// Runs `ickon` with `args` to its end (killed after [`RUN_TIMEOUT`]);
/// its exit code, stdout and stderr.
fn ickon(args: &[&str]) -> (Option<i32>, String, String) {
    let dir = tempfile::tempdir().expect("temp dir");
    let (out_path, err_path) = (dir.path().join("out"), dir.path().join("err"));
    let mut child = Command::new(ICKON)
        .args(args)
        .env("XDG_RUNTIME_DIR", dir.path())
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).expect("out file"))
        .stderr(std::fs::File::create(&err_path).expect("err file"))
        .spawn()
        .expect("ickon starts");
    let deadline = Instant::now() + RUN_TIMEOUT;
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "ickon {args:?} still running after {} s: {}",
                RUN_TIMEOUT.as_secs(),
                std::fs::read_to_string(&err_path).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let read = |p: &std::path::Path| std::fs::read_to_string(p).unwrap_or_default();
    (status.code(), read(&out_path), read(&err_path))
}

fn number(v: &Value, field: &str) -> f64 {
    v[field]
        .as_f64()
        .unwrap_or_else(|| panic!("{field} is not a number: {v}"))
}

#[test]
fn bench_central_serves_every_synthetic_robot_with_sane_figures() {
    let (code, out, err) = ickon(&[
        "bench",
        "central",
        "--site",
        "lab",
        "--robots",
        "30",
        "--duration",
        "6",
        "--json",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let sizes: Value = serde_json::from_str(&out).expect("one JSON document");
    let sizes = sizes.as_array().expect("one entry per size");
    assert_eq!(sizes.len(), 1);
    let r = &sizes[0];
    assert_eq!(r["robots"], 30);
    assert!(r["failure"].is_null(), "{r}");
    // Every synthetic robot up at the central unit, and posed.
    assert_eq!(r["robots_up_at_central"], 30, "{r}");
    assert_eq!(r["robots_posed_at_central"], 30, "{r}");
    // Every token came up within the bench's start-up timeout.
    let live_s = number(r, "live_s");
    assert!(live_s > 0.0 && live_s < 60.0, "{r}");
    // Cycles triggered all along (lab runs several a second).
    assert!(number(r, "cycles") >= 6.0, "{r}");
    let period_ms = number(r, "cycle_period_ms");
    assert!((20.0..2_000.0).contains(&period_ms), "{r}");
    let p50 = number(r, "trigger_jitter_p50_us");
    let p99 = number(r, "trigger_jitter_p99_us");
    assert!(p50 >= 0.0 && p50 <= p99 && p99 <= number(r, "trigger_jitter_max_us"));
    assert!(p99 < period_ms * 1e3, "jitter beyond a cycle: {r}");
    let cpu = number(r, "central_cpu_share");
    assert!(cpu > 0.0 && cpu < 1.5, "{r}");
    assert!(number(r, "central_peak_rss_mib") > 1.0, "{r}");
    assert!(number(r, "fleet_cpu_share") > 0.0, "{r}");
    // The cells fired, in sync within the simulated clocks' reach.
    assert!(number(r, "sync_error_max_us") < 10_000.0, "{r}");
    // The survey calibration published (once a second by default), and its
    // step's time is a time.
    assert!(number(r, "survey_publications") >= 1.0, "{r}");
    let mean_ms = number(r, "survey_publish_mean_ms");
    assert!(
        mean_ms > 0.0 && mean_ms <= number(r, "survey_publish_max_ms"),
        "{r}"
    );
    // The admin status and the web API answered, nearly every time.
    for (asked, failed, p50, p99) in [
        (
            "admin_status_asked",
            "admin_status_unanswered",
            "admin_status_p50_ms",
            "admin_status_p99_ms",
        ),
        (
            "web_status_asked",
            "web_status_failed",
            "web_status_p50_ms",
            "web_status_p99_ms",
        ),
    ] {
        assert!(number(r, asked) >= 8.0, "{asked}: {r}");
        assert!(number(r, failed) <= 1.0, "{failed}: {r}");
        assert!(
            number(r, p50) > 0.0 && number(r, p50) <= number(r, p99),
            "{r}"
        );
        assert!(number(r, p99) < 5_000.0, "{r}");
    }
}

#[test]
fn sim_runs_robots_added_to_the_site_with_fixes() {
    let (code, out, err) = ickon(&[
        "sim",
        "--site",
        "lab",
        "--robots",
        "7",
        "--duration",
        "5",
        "--json",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let report: Value = serde_json::from_str(&out).expect("one JSON document");
    let robots = report["robots"].as_array().expect("robots");
    assert_eq!(robots.len(), 7, "{report}");
    // The site's five and two added ones, each localised by the agent
    // that read the extended site from the central unit.
    let ids: Vec<&str> = robots.iter().filter_map(|r| r["id"].as_str()).collect();
    assert!(ids.contains(&"r6") && ids.contains(&"r7"), "{ids:?}");
    for r in robots {
        assert!(number(r, "fixes") > 0.0, "{r}");
    }
}

#[test]
fn absurd_fleet_sizes_are_refused_before_anything_starts() {
    for (args, says) in [
        (
            &["bench", "central", "--robots", "0", "--duration", "1"][..],
            "--robots 0",
        ),
        (
            &[
                "bench",
                "central",
                "--robots",
                "100,10001",
                "--duration",
                "1",
            ],
            "10001 robots is more than the 10000",
        ),
        (
            &["bench", "central", "--robots", "-3", "--duration", "1"],
            "'-3'",
        ),
        (
            &["bench", "central", "--robots", "10", "--duration", "0"],
            "--duration",
        ),
        (
            &["sim", "--robots", "10001", "--duration", "1"],
            "10001 robots is more than the 10000",
        ),
        (&["sim", "--robots", "0", "--duration", "1"], "--robots 0"),
        (
            &["bench", "scale", "--robots", "16,99999", "--duration", "1"],
            "99999 robots is more than the 10000",
        ),
    ] {
        let (code, _, err) = ickon(args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
