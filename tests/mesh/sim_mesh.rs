//! The whole mesh as separate processes (`ickon sim`): central unit, four
//! cells, the world and two MSU agents on a loopback Zenoh mesh for 15 s.
//! Checks accuracy, fix rate, occupancy firing (the default: faster cycles,
//! every cell firing the cycles that name it), and that no process of the
//! run is left behind; and the same mesh firing the whole schedule.

use std::process::Command;
use std::time::{Duration, Instant};

use ickon_testkit::{ChildGuard, poll_until};
use support::ICKON;

/// Mesh duration once every node is live, seconds.
const DURATION_S: f64 = 15.0;

/// Processes whose command line mentions `needle` (this run's central endpoint).
fn processes_mentioning(needle: &str) -> Vec<u32> {
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    dir.filter_map(|e| e.ok())
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            std::fs::read(format!("/proc/{pid}/cmdline"))
                .map(|c| {
                    String::from_utf8_lossy(&c)
                        .replace('\0', " ")
                        .contains(needle)
                })
                .unwrap_or(false)
        })
        .collect()
}

/// `ickon sim --robots 2 --seed 2 --json` with `extra` flags for
/// `duration_s`: its JSON report, after checking that it succeeded.
fn sim_json(extra: &[&str], duration_s: f64) -> serde_json::Value {
    let out = Command::new(ICKON)
        .args(["sim", "--robots", "2", "--json", "--seed", "2"])
        .args(extra)
        .args(["--duration", &duration_s.to_string()])
        .output()
        .expect("ickon sim starts");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "ickon sim failed:\n{stderr}");
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document ({e}):\n{stderr}"))
}

#[test]
fn two_robots_on_the_full_mesh_are_accurate_and_every_process_stops() {
    let doc = sim_json(&[], DURATION_S);

    let rate_hz = doc["update_rate_hz"].as_f64().expect("update rate");
    assert!(rate_hz > 1.0, "{doc}");
    // Occupancy firing (the default): the central unit fires only where
    // the robots are, the cells fire what each trigger names, and the MSU
    // agents match their arrivals to the triggers: faster cycles than the
    // whole schedule's.
    let cycles_per_s = doc["cycles_per_s"].as_f64().expect("cycles per second");
    assert!(
        cycles_per_s > 1.5 * rate_hz,
        "occupancy cycles {cycles_per_s}/s against the whole schedule's {rate_hz}/s\n{doc}"
    );
    let expected_cycles = doc["cycles_triggered"].as_f64().expect("cycles");
    let robots = doc["robots"].as_array().expect("robots");
    assert_eq!(robots.len(), 2, "{doc}");
    for r in robots {
        let mean_mm = r["mean_mm"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            mean_mm < 150.0,
            "robot {}: mean {mean_mm} mm\n{doc}",
            r["id"]
        );
        // Every cycle can give a fix; at least 80 % of them must.
        let fixes = r["fixes"].as_f64().unwrap_or(0.0);
        let expected = expected_cycles;
        assert!(
            fixes >= 0.8 * expected,
            "robot {}: {fixes} fixes of {expected:.0} possible\n{doc}",
            r["id"]
        );
        assert!(r["poses"].as_u64().unwrap_or(0) > fixes as u64, "{doc}");
        assert!(r["latency_p50_us"].as_f64().is_some(), "{doc}");
    }
    // Under occupancy firing (the default) a cell is due only in the
    // cycles that name one of its transmitters: each must fire nearly all
    // of those, and some cell fires in every cycle.
    let cells = doc["cells"].as_array().expect("cells");
    assert_eq!(cells.len(), 4, "{doc}");
    for c in cells {
        let share = c["fired_share"].as_f64().unwrap_or(0.0);
        assert!(
            share >= 0.95,
            "cell {} fired {share} of its cycles\n{doc}",
            c["id"]
        );
        assert!(c["cycles_fired"].as_u64().unwrap_or(0) > 0, "{doc}");
    }
    let most_fired = cells
        .iter()
        .filter_map(|c| c["cycles_fired"].as_f64())
        .fold(0.0, f64::max);
    assert!(most_fired >= 0.8 * expected_cycles, "{doc}");
    assert_eq!(doc["bad_messages"], 0, "{doc}");

    // Clean shutdown: nothing of this run survives the launcher.
    let endpoint = doc["central_endpoint"]
        .as_str()
        .expect("endpoint")
        .to_owned();
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let left = processes_mentioning(&endpoint);
        if left.is_empty() {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "processes of the run still alive: {left:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The whole schedule every cycle (`--firing all`): cycles at the schedule's rate, every cell firing in
/// each, and still a fix from nearly every cycle.
#[test]
fn the_whole_schedule_fires_every_cell_every_cycle() {
    let duration_s = 12.0;
    let doc = sim_json(&["--firing", "all"], duration_s);
    let schedule_hz = doc["update_rate_hz"].as_f64().expect("update rate");
    let cycles_per_s = doc["cycles_per_s"].as_f64().expect("cycles per second");
    assert!(
        (0.8 * schedule_hz..=1.05 * schedule_hz).contains(&cycles_per_s),
        "{cycles_per_s} cycles/s against the schedule's {schedule_hz}/s\n{doc}"
    );
    let cycles = doc["cycles_triggered"].as_f64().expect("cycles");
    for c in doc["cells"].as_array().expect("cells") {
        let fired = c["cycles_fired"].as_f64().unwrap_or(0.0);
        assert!(
            fired >= 0.8 * cycles,
            "cell {} fired {fired} of {cycles} cycles\n{doc}",
            c["id"]
        );
    }
    for r in doc["robots"].as_array().expect("robots") {
        let mean_mm = r["mean_mm"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            mean_mm < 150.0,
            "robot {}: mean {mean_mm} mm\n{doc}",
            r["id"]
        );
        let share = r["fix_share"].as_f64().unwrap_or(0.0);
        assert!(
            share >= 0.8,
            "robot {}: fixes in {share} of cycles\n{doc}",
            r["id"]
        );
    }
    assert_eq!(doc["bad_messages"], 0, "{doc}");
}

/// A SIGTERM (what a service manager or `timeout` sends) stops `ickon sim`
/// the way Ctrl-C does: every node is stopped, the report still comes, the
/// exit code says the run was interrupted, and neither the agents'
/// temporary configuration file nor the run file is left behind.
#[test]
fn a_sigterm_stops_the_sim_cleanly_and_leaves_no_file_behind() {
    let tmp = tempfile::tempdir().expect("temporary directory");
    let (temp_dir, runtime_dir, logs) = (
        tmp.path().join("tmp"),
        tmp.path().join("run"),
        tmp.path().join("logs"),
    );
    for dir in [&temp_dir, &runtime_dir, &logs] {
        std::fs::create_dir(dir).expect("directory");
    }
    let mut cmd = Command::new(ICKON);
    cmd.args(["sim", "--robots", "1", "--duration", "120"])
        .env("TMPDIR", &temp_dir)
        .env("XDG_RUNTIME_DIR", &runtime_dir);
    let mut sim = ChildGuard::spawn("sim", cmd, &logs).expect("ickon sim starts");
    // The run file names the central endpoint once every node is live.
    let run_dir = ickon_runtime::RunDir::from_env(
        Some(runtime_dir.clone().into()),
        nix::unistd::getuid().as_raw(),
    );
    let endpoint = poll_until(Duration::from_secs(60), "the run file", || {
        assert!(
            sim.exit_status().is_none(),
            "ickon sim ended early:\n{}",
            sim.log()
        );
        run_dir.read("lab").ok().map(|run| run.central[0].clone())
    })
    .unwrap_or_else(|e| panic!("{e}:\n{}", sim.log()));
    let agents_files = || {
        std::fs::read_dir(&temp_dir)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with("ickon-sim-msu-")
            })
            .count()
    };
    assert_eq!(agents_files(), 1, "the agents' file is where TMPDIR says");
    let status = sim.stop(Duration::from_secs(60)).expect("stopped");
    let log = sim.log();
    assert_eq!(status.code(), Some(1), "{log}");
    assert!(log.contains("interrupted (Ctrl-C or SIGTERM)"), "{log}");
    assert!(
        log.contains("robot   fixes"),
        "the report still comes:\n{log}"
    );
    poll_until(Duration::from_secs(5), "the run's processes to end", || {
        processes_mentioning(&endpoint).is_empty().then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}: {:?}", processes_mentioning(&endpoint)));
    assert_eq!(agents_files(), 0, "the agents' file is left behind");
    assert!(run_dir.sites().is_empty(), "the run file is left behind");
}
