//! The fleet checks each robot, on the live mesh: a secured `ickon sim` on
//! `lab` with robots r1 and r2, and a forger holding robot r3's credential
//! that publishes fixes placing every transmitter it uses 20 cm off its
//! place (heights up and down in turn), as an MSU publishes them: good
//! quality, residuals orthogonal to the fix's own unknowns, in summaries
//! twice a second that the central unit's gate takes (a robot standing
//! still, stamps that follow the time). The central
//! unit must quarantine r3 within a minute of its first fix, keep every
//! forged fix out of the survey calibration (all counted, but for one
//! window held for judging), keep r1 and r2 agreeing, and publish a
//! calibration that did not move toward the forged displacements; the
//! honest robots' mean error is compared with the same run without the
//! forger.
//!
//! Every wait polls with a deadline; the run is killed when its guard
//! drops, whatever happens.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use ickon_proto::codec::encode;
use ickon_proto::keys::Keys;
use ickon_proto::msg::control::SurveyCalibration;
use ickon_proto::msg::robot::{Fix, FixQuality, PoseStatus, RobotSummary, SUMMARY_PERIOD};
use ickon_proto::site::Site;
use ickon_proto::time::Time;
use ickon_testkit::{ChildGuard, poll_until};
use nalgebra::{DMatrix, DVector, Vector3};
use serde_json::Value;
use support::ICKON;
use zenoh::Wait;
use zenoh::handlers::FifoChannel;

/// From `ickon sim` to its run file (the nodes built, started and live).
const START_TIMEOUT: Duration = Duration::from_secs(90);
/// Each run, once every node is live, seconds: time for the robots to
/// settle and the forger to be judged, short for the test command.
const RUN_S: u64 = 20;
/// How many fixes each of the forger's summaries carries: six a second
/// at an agent's two summaries a second, an MSU's rate on `lab` (about 7
/// fixes a second), within the central unit's share of 1.25 a cycle.
const FIXES_PER_SUMMARY: usize = 3;
/// The fixes the central unit holds of a robot for its check.
const WINDOW_FIXES: u64 = 20;
/// Where the forger claims to be: the corridor, where the honest robots
/// drive, so that what it forges is of the transmitters they use.
const PLACES: [[f64; 2]; 4] = [[3.0, 1.25], [6.0, 1.0], [10.0, 1.5], [13.0, 1.25]];

/// The site's secured files for the simulation, its router at `endpoint`.
fn secure_dir(out: &Path, endpoint: &str) {
    let output = Command::new(ICKON)
        .args(["site", "secure", "lab", "--sim", "--out"])
        .arg(out)
        .args(["--listen", endpoint, "--connect", endpoint])
        .output()
        .expect("ickon site secure runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn client_file(dir: &Path, user: &str) -> PathBuf {
    dir.join("clients").join(format!("{user}.json5"))
}

/// `ickon sim --secure DIR` on `lab` with two robots for [`RUN_S`], its
/// run file in `runtime_dir`; returns once the run file is there.
fn start_sim(dir: &Path, secure: &Path, runtime_dir: &Path) -> ChildGuard {
    let mut sim = Command::new(ICKON);
    sim.args(["sim", "--robots", "2", "--seed", "2", "--json"])
        .args(["--duration", &RUN_S.to_string()])
        .arg("--secure")
        .arg(secure)
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

/// Waits for the run to end well; its JSON report (the last document of
/// its output).
fn finish(mut sim: ChildGuard) -> Value {
    let status = poll_until(Duration::from_secs(RUN_S + 60), "ickon sim to end", || {
        sim.exit_status()
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    let log = sim.log();
    assert!(status.success(), "ickon sim {status}:\n{log}");
    let report_at = log.rfind("\n{").map_or(0, |i| i + 1);
    serde_json::from_str(&log[report_at..]).unwrap_or_else(|e| panic!("{e}:\n{log}"))
}

/// `ickon admin robots --json` as the site's admin, through the run's
/// router at `endpoint` (the admin's file names the router's usual one).
fn admin_robots(runtime_dir: &Path, secure: &Path, endpoint: &str) -> Value {
    let out = Command::new(ICKON)
        .args(["admin", "robots", "--json", "--timeout-ms", "10000"])
        .args(["--connect", endpoint])
        .arg("--zenoh-config")
        .arg(client_file(secure, "admin"))
        .env("XDG_RUNTIME_DIR", runtime_dir)
        .output()
        .expect("ickon admin runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("robots JSON")
}

/// A session with `user`'s credential through the run's router at
/// `endpoint`.
fn open_as(secure: &Path, user: &str, endpoint: &str) -> zenoh::Session {
    let mut config = zenoh::Config::from_file(client_file(secure, user)).unwrap();
    config
        .insert_json5("connect/endpoints", &format!("[{endpoint:?}]"))
        .unwrap();
    config.insert_json5("connect/timeout_ms", "10000").unwrap();
    zenoh::open(config)
        .wait()
        .unwrap_or_else(|e| panic!("{user}'s credential lets it in: {e}"))
}

/// The run's endpoint, from its run file in `runtime_dir`.
fn run_endpoint(runtime_dir: &Path) -> String {
    let run: Value =
        serde_json::from_slice(&std::fs::read(runtime_dir.join("ickon").join("lab.json")).unwrap())
            .unwrap();
    run["central"][0].as_str().expect("endpoint").to_string()
}

type Sub = zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// The last survey calibration `sub` received.
fn last_survey(sub: &Sub) -> SurveyCalibration {
    let mut last = None;
    while let Ok(Some(s)) = sub.try_recv() {
        last = SurveyCalibration::decode(&s.payload().to_bytes())
            .ok()
            .or(last);
    }
    last.expect("the central unit published its survey calibration")
}

/// How far `survey` moved the transmitters toward the forged heights, m:
/// the mean of each transmitter's height offset times the forged
/// direction of its height, over the transmitters the forger used.
fn toward_forgery_m(site: &Site, survey: &SurveyCalibration) -> f64 {
    let used: std::collections::BTreeSet<u32> = PLACES
        .iter()
        .flat_map(|&at| forged_fix(site, at).used)
        .collect();
    let moves: Vec<f64> = site
        .transmitters
        .iter()
        .enumerate()
        .filter(|(_, t)| used.contains(&t.id))
        .map(|(i, t)| {
            let z = survey
                .offsets
                .iter()
                .find(|o| o.tx_id == t.id)
                .map_or(0.0, |o| o.offset_m[2]);
            z * lift_of(i).signum()
        })
        .collect();
    moves.iter().sum::<f64>() / moves.len() as f64
}

/// The forged height error of the site's `i`-th transmitter, m.
fn lift_of(i: usize) -> f64 {
    if i.is_multiple_of(2) { 0.2 } else { -0.2 }
}

fn robot<'a>(robots: &'a Value, id: &str) -> Option<&'a Value> {
    robots["robots"].as_array()?.iter().find(|r| r["id"] == id)
}

/// Each robot's mean error in a run's report, mm.
fn mean_errors(report: &Value) -> Vec<(String, f64)> {
    report["robots"]
        .as_array()
        .expect("robots")
        .iter()
        .map(|r| {
            (
                r["id"].as_str().unwrap_or("?").to_string(),
                r["mean_mm"].as_f64().unwrap_or(f64::INFINITY),
            )
        })
        .collect()
}

/// The fix an MSU at `at` would publish if every transmitter really hung
/// 20 cm above or below its surveyed place (by its order on the site):
/// every transmitter in sight within 8 m, the residuals what such
/// displacements leave once the fix's position and offset absorbed what
/// they can.
/// The forger's summary number `seq`, `since` its start: a robot
/// standing still at the first place, carrying `fixes`.
fn forged_summary(seq: u64, since: Duration, fixes: Vec<Fix>) -> RobotSummary {
    RobotSummary {
        seq,
        stamp: Time(since.as_nanos() as i64),
        x_m: PLACES[0][0],
        y_m: PLACES[0][1],
        theta_rad: 0.0,
        covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
        estimator: "tdoa-ekf".into(),
        fix_seq: seq,
        status: PoseStatus::Tracking,
        vx_m_s: 0.0,
        vy_m_s: 0.0,
        velocity_span_s: 0.0,
        fixes_solved: fixes.len() as u32,
        fixes,
    }
}

fn forged_fix(site: &Site, at: [f64; 2]) -> Fix {
    let receiver = Vector3::new(at[0], at[1], site.msu.height_m);
    let mut used = Vec::new();
    let mut toward = Vec::new();
    let mut lift = Vec::new();
    for (i, t) in site.transmitters.iter().enumerate() {
        let to_tx = Vector3::from(t.position_m) - receiver;
        let around = [[0.0, 0.0], [0.3, 0.0], [-0.3, 0.0], [0.0, 0.3], [0.0, -0.3]];
        let in_sight = around.iter().all(|[dx, dy]| {
            site.line_of_sight([receiver.x + dx, receiver.y + dy, receiver.z], t.position_m)
        });
        if in_sight && to_tx.norm() < 8.0 {
            used.push(t.id);
            toward.push(to_tx.normalize());
            lift.push(lift_of(i));
        }
    }
    assert!(used.len() >= 5, "a forged fix needs signals: {used:?}");
    let n = used.len();
    let a = DMatrix::from_fn(n, 3, |i, k| [-toward[i].x, -toward[i].y, 1.0][k]);
    let ata_inv = (a.transpose() * &a)
        .try_inverse()
        .expect("a fix's geometry");
    let projector = DMatrix::identity(n, n) - &a * ata_inv * a.transpose();
    let displaced = DVector::from_fn(n, |i, _| toward[i].z * lift[i]);
    let residuals = projector * displaced;
    Fix {
        stamp: Time(0),
        arrivals_seq: 0,
        x_m: at[0],
        y_m: at[1],
        z_m: site.msu.height_m,
        covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 0.0],
        heading_rad: 0.0,
        heading_valid: false,
        used,
        rejected: Vec::new(),
        residuals_m: residuals.iter().copied().collect(),
        quality: FixQuality::Good,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    }
}

#[test]
fn a_robot_forging_the_survey_is_quarantined_and_the_fleet_keeps_its_accuracy() {
    let tmp = tempfile::tempdir().unwrap();
    let secure = tmp.path().join("secure");
    secure_dir(&secure, &ickon_testkit::loopback_endpoint().expect("port"));

    let site = Site::default_site();
    let keys = Keys::new("lab").unwrap();

    // The same run without the forger.
    let clean_run = tmp.path().join("clean");
    std::fs::create_dir(&clean_run).unwrap();
    let sim = start_sim(tmp.path(), &secure, &clean_run);
    let recorder = open_as(&secure, "recorder", &run_endpoint(&clean_run));
    let surveys = recorder
        .declare_subscriber(keys.central_survey())
        .with(FifoChannel::new(10_000))
        .wait()
        .unwrap();
    let clean = finish(sim);
    let clean_survey = last_survey(&surveys);
    drop(surveys);
    drop(recorder);

    let runtime_dir = tmp.path().join("forged");
    std::fs::create_dir(&runtime_dir).unwrap();
    let mut sim = start_sim(tmp.path(), &secure, &runtime_dir);
    let endpoint = run_endpoint(&runtime_dir);
    let recorder = open_as(&secure, "recorder", &endpoint);
    let surveys = recorder
        .declare_subscriber(keys.central_survey())
        .with(FifoChannel::new(10_000))
        .wait()
        .unwrap();
    let forger = open_as(&secure, "robot-r3", &endpoint);
    let summary_key = keys.robot_summary("r3").unwrap();
    let fixes: Vec<Fix> = PLACES.iter().map(|&at| forged_fix(&site, at)).collect();

    // Forge until quarantined (and a few seconds on), looking once a second.
    let started = Instant::now();
    let mut sent = 0usize;
    let mut quarantined_after = None;
    let mut last_look = Instant::now();
    let mut looked = Value::Null;
    while started.elapsed() < Duration::from_secs(60) {
        if let Some(status) = sim.exit_status() {
            panic!("ickon sim {status} while forging:\n{}", sim.log());
        }
        let carried: Vec<Fix> = (0..FIXES_PER_SUMMARY)
            .map(|k| fixes[(sent + k) % fixes.len()].clone())
            .collect();
        let seq = (sent / FIXES_PER_SUMMARY) as u64 + 1;
        let summary = forged_summary(seq, started.elapsed(), carried);
        forger
            .put(&summary_key, encode(&summary).unwrap())
            .wait()
            .unwrap();
        sent += FIXES_PER_SUMMARY;
        std::thread::sleep(SUMMARY_PERIOD.to_std());
        if last_look.elapsed() >= Duration::from_secs(1) {
            last_look = Instant::now();
            looked = admin_robots(&runtime_dir, &secure, &endpoint);
            let r3 = robot(&looked, "r3").map(|r| r["survey_check"].clone());
            if quarantined_after.is_none() && r3 == Some(Value::from("quarantined")) {
                quarantined_after = Some(started.elapsed());
            }
            if quarantined_after.is_some_and(|at| started.elapsed() > at + Duration::from_secs(3)) {
                break;
            }
        }
    }
    drop(forger);
    let quarantined_after = quarantined_after.unwrap_or_else(|| {
        panic!("r3 not quarantined within a minute of its first fix:\n{looked}")
    });
    // Once the last puts are in.
    std::thread::sleep(Duration::from_millis(500));
    let robots = admin_robots(&runtime_dir, &secure, &endpoint);
    let forged = finish(sim);
    let forged_survey = last_survey(&surveys);

    let r3 = robot(&robots, "r3").expect("r3 in the admin status");
    assert_eq!(r3["survey_check"], "quarantined", "{robots}");
    // Every forged fix is kept out: counted as quarantined or over its
    // rate, but for at most one window held for judging its release.
    let kept_out = r3["fixes_quarantined"].as_u64().unwrap_or(0);
    let over_rate = r3["fixes_over_rate"].as_u64().unwrap_or(0);
    assert!(
        kept_out + over_rate <= sent as u64 && kept_out + over_rate + WINDOW_FIXES >= sent as u64,
        "{sent} forged fixes sent, {kept_out} quarantined, {over_rate} over rate:\n{robots}"
    );
    for id in ["r1", "r2"] {
        let r = robot(&robots, id).expect("the honest robots in the admin status");
        assert_eq!(r["survey_check"], "agrees", "{robots}");
        assert_eq!(r["fixes_quarantined"], 0, "{robots}");
    }

    // What reaches the other robots of the forger is the calibration: it
    // moved toward the forged heights no more than an honest fleet's does
    // by chance (within 2 mm in the runs measured), far less than 10 % of
    // the forged 20 cm. The bound is 5 mm: without the check, the same
    // forger among three honest robots moved the heights 8.6 mm toward
    // its forgery (the unit test of `survey_calibration::consensus`).
    let (clean_toward, forged_toward) = (
        toward_forgery_m(&site, &clean_survey),
        toward_forgery_m(&site, &forged_survey),
    );
    let (before, after) = (mean_errors(&clean), mean_errors(&forged));
    eprintln!(
        "r3 quarantined {:.1} s after its first forged fix ({sent} sent, {kept_out} quarantined, \
         {over_rate} over rate); calibration toward the forged heights: {:.1} mm without the \
         forger ({} fixes), {:.1} mm with it ({} fixes); mean error without the forger \
         {before:?}, with it {after:?}",
        quarantined_after.as_secs_f64(),
        1e3 * clean_toward,
        clean_survey.fixes_taken,
        1e3 * forged_toward,
        forged_survey.fixes_taken,
    );
    assert!(
        forged_toward.abs() < 0.005,
        "the calibration moved {:.1} mm toward the forged heights",
        1e3 * forged_toward
    );
    assert_eq!(before.len(), 2, "{clean}");
    assert_eq!(after.len(), 2, "{forged}");
    // The robots' own accuracy differs from one live run to the next by
    // more than the forger could change it through a calibration that did
    // not move (measured: a robot's mean error 14-34 mm over runs of the
    // same seed); what is asserted of it is that it did not degrade by
    // half.
    let mean = |v: &[(String, f64)]| v.iter().map(|(_, m)| m).sum::<f64>() / v.len() as f64;
    assert!(
        mean(&after) < 1.5 * mean(&before),
        "the honest robots' mean error went from {before:?} to {after:?}"
    );
}
