//! The whole simulation through devices (`ickon sim --devices emulated`,
//! `ickon sim --receivers marvelmind`): every cell fires through a
//! transmitter board and every robot hears through a receiver board the
//! world emulates over TCP, each with a clock of its own; or every robot
//! ranges with an emulated Marvelmind hedgehog. Every robot must fix and
//! track as on the direct simulation's bounds (`sim_mesh`), and the report
//! must score the kit's own positions beside the agent's poses.

use std::process::Command;
use std::time::Duration;

use ickon_testkit::poll_until;
use serde_json::Value;

use support::ICKON;
use support::sim_run::{admin_status, finish, start_sim};

/// Length of each run once every node is live, seconds.
const RUN_S: u64 = 16;

/// Runs `ickon sim` on `lab` with `args` for [`RUN_S`], waiting meanwhile
/// until `ickon admin status --json` satisfies `shown` (what the operator
/// must see); the run's log and its JSON report.
fn run_watching_admin(
    args: &[&str],
    what: &str,
    shown: impl Fn(&Value) -> bool,
) -> (String, Value) {
    let dir = tempfile::tempdir().unwrap();
    let runtime_dir = dir.path().join("run");
    std::fs::create_dir_all(&runtime_dir).unwrap();
    let sim = start_sim(dir.path(), &runtime_dir, RUN_S, args);
    let seen = poll_until(Duration::from_secs(RUN_S - 2), what, || {
        shown(&admin_status(&runtime_dir)).then_some(())
    });
    let (log, doc) = finish(sim, RUN_S);
    // The end of the log, where a failure's cause shows.
    seen.unwrap_or_else(|e| panic!("{e}\n{}", &log[log.len().saturating_sub(4_000)..]));
    (log, doc)
}

#[test]
fn a_site_run_through_emulated_boards_fixes_every_robot() {
    // The operator sees every device: each cell's transmitter board and
    // each robot's receiver board, ready once its clock is learnt.
    let (stderr, doc) = run_watching_admin(
        &["--robots", "2", "--seed", "3", "--devices", "emulated"],
        "every device ready in admin",
        |status| {
            let ready = |v: &Value, prefix: &str| {
                v.as_str()
                    .is_some_and(|d| d.starts_with(prefix) && d.contains("ready"))
            };
            let cells = status["cells"].as_array();
            let robots = status["robots"].as_array();
            cells.is_some_and(|c| {
                c.iter()
                    .all(|c| ready(&c["device"], "transmitter board on tcp:"))
            }) && robots.is_some_and(|r| {
                r.len() == 2
                    && r.iter()
                        .all(|r| ready(&r["receivers"], "receiver board on tcp:"))
            })
        },
    );
    let cycles = doc["cycles_triggered"].as_f64().expect("cycles");
    let robots = doc["robots"].as_array().expect("robots");
    assert_eq!(robots.len(), 2, "{doc}");
    for r in robots {
        // The direct simulation's bounds (sim_mesh): the boards' clocks
        // are learnt, so neither the error nor the fix rate may suffer.
        let mean_mm = r["mean_mm"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            mean_mm < 150.0,
            "robot {}: mean {mean_mm} mm\n{doc}",
            r["id"]
        );
        let fixes = r["fixes"].as_f64().unwrap_or(0.0);
        assert!(
            fixes >= 0.8 * cycles,
            "robot {}: {fixes} fixes of {cycles:.0} cycles\n{doc}\n{stderr}",
            r["id"]
        );
        // The world shows each group it framed, numbered as the board
        // numbers it: the latency from a group to its pose is measured.
        assert!(r["latency_p50_us"].as_f64().is_some(), "{doc}");
    }
    // The boards fired every burst the cells reported (no report without
    // its sound), and every cell fired most cycles it was due in: not the
    // first ones (until its host has learnt the board's clock, two seconds
    // of exchanges, a cell cannot arm, and the central unit fires every
    // cell while it knows no robot), nor slots whose trigger came too late
    // on a loaded machine, as on the direct simulation.
    assert!(
        !stderr.contains("no transmitter board fired"),
        "reports without a firing:\n{stderr}"
    );
    let mut bursts = 0;
    for c in doc["cells"].as_array().expect("cells") {
        bursts += c["bursts"].as_u64().unwrap_or(0);
        let fired = c["cycles_fired"].as_f64().unwrap_or(0.0);
        let missed = c["cycles_missed"].as_f64().unwrap_or(f64::INFINITY);
        if fired + missed > 10.0 {
            assert!(
                fired >= 0.85 * (fired + missed),
                "cell {}: {missed} cycles missed\n{doc}",
                c["id"]
            );
        }
    }
    assert!(bursts as f64 > cycles, "{doc}");
}

#[test]
fn every_robot_tracks_on_an_emulated_marvelmind_kit_and_the_kit_is_scored() {
    // The operator sees each robot's kit streaming.
    let (stderr, doc) = run_watching_admin(
        &["--robots", "2", "--seed", "3", "--receivers", "marvelmind"],
        "every kit up in admin",
        |status| {
            status["robots"].as_array().is_some_and(|robots| {
                robots.len() == 2
                    && robots.iter().all(|r| {
                        r["receivers"].as_str().is_some_and(|d| {
                            d.starts_with("marvelmind hedgehog: link tcp:") && d.contains(" up ")
                        })
                    })
            })
        },
    );
    for r in doc["robots"].as_array().expect("robots") {
        let scored = r["scored_poses"].as_u64().unwrap_or(0);
        assert!(
            scored > 100,
            "robot {}: {scored} poses scored\n{doc}\n{stderr}",
            r["id"]
        );
        // Four ranges of 2 cm noise at 8 Hz, fused with the wheels: within
        // a few centimetres (the kit's own positions are scored alike).
        let mean_mm = r["mean_mm"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            mean_mm < 60.0,
            "robot {}: mean {mean_mm} mm\n{doc}",
            r["id"]
        );
        let kit = r["kit_positions"].as_u64().unwrap_or(0);
        assert!(kit > 40, "robot {}: {kit} kit positions\n{doc}", r["id"]);
        let kit_mm = r["kit_mean_mm"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            kit_mm < 200.0,
            "robot {}: the kit's own mean {kit_mm} mm\n{doc}",
            r["id"]
        );
    }
}

#[test]
fn a_site_whose_transmitters_cannot_be_marvelmind_beacons_is_refused_before_any_node_starts() {
    let dir = tempfile::tempdir().unwrap();
    let site = dir.path().join("site.toml");
    let lab = ickon_proto::site::Site::builtin("lab")
        .expect("built-in lab")
        .1;
    std::fs::write(&site, lab.replacen("id = 11", "id = 311", 1)).unwrap();
    let out = Command::new(ICKON)
        .args([
            "sim",
            "--receivers",
            "marvelmind",
            "--duration",
            "1",
            "--site",
        ])
        .arg(&site)
        .output()
        .expect("ickon sim starts");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("transmitter 311"), "{stderr}");
}
