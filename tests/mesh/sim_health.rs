//! Health as an operator reads it from a running `ickon sim` on `lab` with
//! one robot: under occupancy-aware firing (the default) the cells far from
//! the robot are not asked to fire. `ickon admin status --json` must report
//! every cell alive (`up` when due, `idle` when not, never `down`) and count
//! as missed only cycles a cell was due to fire in; the run's own report
//! says the same; and logs written to a file carry no terminal colour codes.
//! A flood of garbage from an outside client is counted whole in the
//! report and logged a few times, not once per message.

use std::time::{Duration, Instant};

use ickon_testkit::Observer;
use serde_json::Value;
use zenoh::Wait;

use support::sim_run::{admin_status, finish, start_sim};

/// Long enough for several looks and 4 s after the last one for its
/// answer, short enough for the test command.
const RUN_S: u64 = 21;
/// Looks at the admin status once the site has run this long, then every
/// [`LOOK_EVERY`] until [`LAST_LOOK_S`]: at least three looks with
/// answers as slow as 2 s each.
const FIRST_LOOK_S: u64 = 8;
const LOOK_EVERY: Duration = Duration::from_secs(2);
const LAST_LOOK_S: u64 = 17;
/// The run: one robot on `lab`.
const ONE_ROBOT: &[&str] = &["--robots", "1", "--seed", "1"];

#[test]
fn one_robot_on_lab_every_cell_is_alive_and_misses_only_cycles_it_was_due_in() {
    let dir = tempfile::tempdir().unwrap();
    let runtime_dir = dir.path().join("run");
    std::fs::create_dir(&runtime_dir).unwrap();
    let sim = start_sim(dir.path(), &runtime_dir, RUN_S, ONE_ROBOT);
    let started = Instant::now();
    std::thread::sleep(Duration::from_secs(FIRST_LOOK_S));

    let mut idle_seen = 0;
    let mut looks = 0;
    while started.elapsed() < Duration::from_secs(LAST_LOOK_S) {
        let status = admin_status(&runtime_dir);
        let cells = status["cells"].as_array().expect("cells");
        assert_eq!(cells.len(), 4, "{status}");
        for c in cells {
            let state = c["state"].as_str().unwrap_or("");
            assert!(
                state == "up" || state == "idle",
                "cell {} is {state:?} in a healthy run:\n{status}",
                c["id"]
            );
            idle_seen += usize::from(state == "idle");
            // A cell misses a cycle it was due in only when its trigger
            // came too late to fire it, which the cell counts itself.
            let missed = c["cycles_missed"].as_u64().expect("missed");
            let skipped = c["slots_skipped"].as_u64().expect("skipped");
            assert!(
                missed <= skipped,
                "cell {}: {missed} cycles missed, {skipped} slots skipped:\n{status}",
                c["id"]
            );
        }
        looks += 1;
        std::thread::sleep(LOOK_EVERY);
    }
    assert!(looks >= 3, "{looks} looks");
    // The point of the test: one robot leaves cells unasked, and those are
    // idle, not down.
    assert!(idle_seen > 0, "no cell was ever idle with one robot on lab");

    let (log, doc) = finish(sim, RUN_S);
    assert!(
        !log.contains('\u{1b}'),
        "colour codes in a log that is not a terminal:\n{log}"
    );
    for c in doc["cells"].as_array().expect("cells") {
        let fired = c["cycles_fired"].as_f64().unwrap_or(0.0);
        let missed = c["cycles_missed"].as_f64().unwrap_or(f64::INFINITY);
        // The launcher counts from the first trigger it sees, which may
        // come before a cell's clock is synchronised (it cannot fire then):
        // two such, or 2 % of the cycles it was due in.
        let due = fired + missed;
        assert!(
            missed <= (0.02 * due).max(2.0),
            "cell {}: {missed} missed of {due} due:\n{doc}",
            c["id"]
        );
    }
}

#[test]
fn a_flood_of_garbage_is_counted_whole_and_logged_a_few_times() {
    const PUTS: usize = 80_000;
    let run_s = 12;
    let dir = tempfile::tempdir().unwrap();
    let runtime_dir = dir.path().join("run");
    std::fs::create_dir(&runtime_dir).unwrap();
    let sim = start_sim(dir.path(), &runtime_dir, run_s, ONE_ROBOT);
    let run: Value =
        serde_json::from_slice(&std::fs::read(runtime_dir.join("ickon").join("lab.json")).unwrap())
            .unwrap();
    let endpoint = run["central"][0].as_str().expect("endpoint").to_string();
    let outsider = Observer::open(&[endpoint]).expect("an outside client connects");
    let publisher = outsider
        .session()
        .declare_publisher("ickon/lab/robot/r1/fix")
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .wait()
        .unwrap();
    for k in 0..PUTS {
        publisher
            .put((k as u64).to_le_bytes().to_vec())
            .wait()
            .unwrap();
    }
    drop(publisher);
    drop(outsider);
    let (log, doc) = finish(sim, run_s);
    let counted = doc["bad_messages"].as_u64().expect("bad_messages");
    // Every put reached the launcher's observer (the router blocks rather
    // than drop), all counted...
    assert_eq!(counted, PUTS as u64, "{doc}");
    // ... and logged by it and by the nodes a few times: once per kind of
    // message and node, then once per 10 s window.
    let lines = log.lines().filter(|l| l.contains("undecodable")).count();
    eprintln!("{counted} undecodable messages counted, {lines} log lines about them");
    assert!(
        (1..=10).contains(&lines),
        "{lines} log lines for {PUTS} undecodable messages:\n{log}"
    );
}
