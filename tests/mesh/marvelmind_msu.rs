//! A robot carrying a Marvelmind hedgehog, as a user runs it: `ickon
//! emulate marvelmind` drives a robot of `marvelmind-lab` and streams the
//! kit's raw distances (with garbage and lost frames on the line), `ickon
//! node msu --receivers marvelmind:...` reads them on a loopback mesh with
//! the central unit and the robot's wheel odometry (played by the test from
//! the emulator's encoder counts, as the robot's base publishes it), and
//! its published pose follows the emulator's truth within what the range
//! noise explains.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::robot::{Odometry, RobotPose};
use ickon_proto::site::Site;
use ickon_proto::time::Time;
use ickon_testkit::{ChildGuard, Observer, poll_until};
use support::ICKON;
use zenoh::Wait;

const SITE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../deploy/sites/marvelmind-lab.toml"
);
const START_TIMEOUT: Duration = Duration::from_secs(90);
/// Range noise of the emulated kit, metres (its default, Marvelmind's ±2 cm).
const RANGE_SIGMA_M: f64 = 0.02;
/// The emulator's update rate, Hz (its default).
const RATE_HZ: f64 = 8.0;
/// Time given to the filter after the robot's first turn, seconds: its
/// heading, uncertain at the start, is pinned by the ranges only once the
/// robot has turned (it took under 4 s on this route; 6 s are given).
const TURN_S: f64 = 6.0;
/// How long poses are scored.
const SCORED: Duration = Duration::from_secs(20);

/// One line of `--truth`: the robot at a system-clock time.
#[derive(Debug, Clone, Copy)]
struct TruthLine {
    t_ns: i64,
    x_m: f64,
    y_m: f64,
    theta_rad: f64,
    ticks: [i64; 2],
}

/// The lines of `--truth` written so far.
fn truth(path: &Path) -> Vec<TruthLine> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |i: usize| f.get(i)?.parse::<f64>().ok();
            let int = |i: usize| f.get(i)?.parse::<i64>().ok();
            Some(TruthLine {
                t_ns: int(0)?,
                x_m: num(1)?,
                y_m: num(2)?,
                theta_rad: num(3)?,
                ticks: [int(4)?, int(5)?],
            })
        })
        .collect()
}

/// Plays the robot's base: publishes its wheel odometry from the
/// emulator's encoder counts as they are written, until `stop`.
fn play_odometry(
    session: zenoh::Session,
    key: String,
    truth_file: PathBuf,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let mut sent = 0;
        while !stop.load(Ordering::Relaxed) {
            let lines = truth(&truth_file);
            for l in lines.iter().skip(sent) {
                let odom = Odometry {
                    stamp: Time::from_nanos(l.t_ns),
                    x_m: l.x_m,
                    y_m: l.y_m,
                    theta_rad: l.theta_rad,
                    left_ticks: l.ticks[0],
                    right_ticks: l.ticks[1],
                };
                let _ = session
                    .put(&key, ickon_proto::encode(&odom).expect("encodes"))
                    .wait();
            }
            sent = sent.max(lines.len());
            std::thread::sleep(Duration::from_millis(20));
        }
    })
}

/// The true position at `t_ns`, between the two updates around it.
fn truth_at(truth: &[TruthLine], t_ns: i64) -> Option<[f64; 2]> {
    let i = truth.partition_point(|s| s.t_ns <= t_ns);
    let (a, b) = (truth.get(i.checked_sub(1)?)?, truth.get(i)?);
    let f = (t_ns - a.t_ns) as f64 / (b.t_ns - a.t_ns).max(1) as f64;
    Some([a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m)])
}

/// The horizontal dilution of precision of ranging the site's beacons from
/// `p` at the hedgehog's height: how much the ranges' noise grows in a
/// position solved from them (`sqrt(trace((H^T H)^-1))` over x and y, with
/// the height known).
fn hdop(site: &Site, p: [f64; 2]) -> f64 {
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for t in &site.transmitters {
        let d = [
            p[0] - t.position_m[0],
            p[1] - t.position_m[1],
            site.msu.height_m - t.position_m[2],
        ];
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let (ux, uy) = (d[0] / r, d[1] / r);
        a += ux * ux;
        b += ux * uy;
        c += uy * uy;
    }
    ((a + c) / (a * c - b * b)).sqrt()
}

/// The shipped site under a name of its own (`marvelmind-<tag>-<pid>`),
/// written in `dir`: each test's keys stay apart from the others'. Returns
/// the name and the file.
fn site_of_its_own(dir: &Path, tag: &str) -> (String, PathBuf) {
    let text = std::fs::read_to_string(SITE).expect("the shipped site");
    let name = if tag.is_empty() {
        format!("marvelmind-{}", std::process::id())
    } else {
        format!("marvelmind-{tag}-{}", std::process::id())
    };
    let site_file = dir.join("site.toml");
    std::fs::write(
        &site_file,
        text.replace("name = \"marvelmind-lab\"", &format!("name = \"{name}\"")),
    )
    .expect("site written");
    (name, site_file)
}

/// The address an emulator prints (its first line starting with `prefix`).
fn printed_address(emulator: &ChildGuard, prefix: &str) -> String {
    poll_until(START_TIMEOUT, "the emulator's address", || {
        emulator
            .log()
            .lines()
            .find(|l| l.starts_with(prefix))
            .map(str::to_string)
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", emulator.log()))
}

/// A central unit for `site_file` and robot r1's MSU reading its
/// hedgehog at `receivers`, on a loopback mesh; their log names end in
/// `tag`. Returns both and the central unit's endpoint.
fn central_and_msu(
    dir: &Path,
    name: &str,
    site_file: &Path,
    receivers: &str,
    tag: &str,
) -> (ChildGuard, ChildGuard, String) {
    let named = |what: &str| {
        if tag.is_empty() {
            what.to_string()
        } else {
            format!("{what}-{tag}")
        }
    };
    let central_endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", "central", "--no-multicast-scouting", "--listen"])
        .arg(&central_endpoint)
        .args(["--site-name", name])
        .arg("--site")
        .arg(site_file);
    let central = ChildGuard::spawn(&named("central"), cmd, dir).expect("central starts");
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", "msu", "--robot", "r1"])
        .args(["--receivers", receivers])
        .args(["--no-multicast-scouting", "--listen", "tcp/127.0.0.1:0"])
        .args(["--connect", &central_endpoint, "--site-name", name])
        .arg("--site")
        .arg(site_file)
        .env("RUST_LOG", "info");
    let msu = ChildGuard::spawn(&named("msu"), cmd, dir).expect("msu starts");
    (central, msu, central_endpoint)
}

#[test]
fn the_msu_tracks_a_robot_on_an_emulated_hedgehog_through_a_noisy_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (name, site_file) = site_of_its_own(dir.path(), "");
    let site = Site::from_file(&site_file).expect("valid site");
    let truth_file = dir.path().join("truth.csv");

    let mut cmd = Command::new(ICKON);
    cmd.args([
        "emulate",
        "marvelmind",
        "--listen",
        "127.0.0.1:0",
        "--wait-for-host",
    ])
    .args(["--garbage", "0.2", "--drop", "0.05", "--seed", "7"])
    .arg("--site")
    .arg(&site_file)
    .arg("--truth")
    .arg(&truth_file);
    let mut emulator = ChildGuard::spawn("hedgehog", cmd, dir.path()).expect("emulator starts");
    let address = printed_address(&emulator, "tcp:");

    let receivers = format!("marvelmind:{address}");
    let (_central, mut msu, central_endpoint) =
        central_and_msu(dir.path(), &name, &site_file, &receivers, "");

    let observer = Observer::open(std::slice::from_ref(&central_endpoint)).expect("observer");
    let keys = Keys::new(&name).expect("keys");
    let stop = Arc::new(AtomicBool::new(false));
    let odometry = play_odometry(
        observer.session().clone(),
        keys.robot("r1", RobotTopic::Odom).unwrap(),
        truth_file.clone(),
        stop.clone(),
    );
    let poses = observer
        .session()
        .declare_subscriber(keys.robot("r1", RobotTopic::Pose).unwrap())
        .wait()
        .expect("pose subscriber");
    // The filter starts from the site's start pose with an uncertain
    // heading, which ranges observe only once the robot turns: poses are
    // scored from the end of its first straight and turn (see `TURN_S`),
    // counted on the robot's clock from its start (the first truth line),
    // for `SCORED`.
    let route = &site.routes[0];
    let first_straight_m =
        (route.points[1][0] - route.points[0][0]).hypot(route.points[1][1] - route.points[0][1]);
    let settle_ns = ((first_straight_m / route.speed_m_s + TURN_S) * 1e9) as i64;
    let mut all = Vec::new();
    let mut robot_start_ns = None;
    poll_until(
        START_TIMEOUT + SCORED * 3,
        "poses to the end of the scored run",
        || {
            if let Some(status) = msu.exit_status() {
                panic!("msu {status}:\n{}", msu.log());
            }
            while let Ok(Some(s)) = poses.try_recv() {
                all.push(ickon_proto::decode::<RobotPose>(&s.payload().to_bytes()).expect("pose"));
            }
            if robot_start_ns.is_none() {
                robot_start_ns = truth(&truth_file).first().map(|l| l.t_ns);
            }
            let t0 = robot_start_ns?;
            let newest = all.last()?.stamp.as_nanos();
            (newest > t0 + settle_ns + SCORED.as_nanos() as i64).then_some(())
        },
    )
    .unwrap_or_else(|e| {
        panic!(
            "{e}: {} poses, from {:?} to {:?}, robot started at {robot_start_ns:?}\n{}",
            all.len(),
            all.first().map(|p| p.stamp),
            all.last().map(|p| p.stamp),
            msu.log_tail(30)
        )
    });
    // The truth is written just after each update: wait for the last.
    std::thread::sleep(Duration::from_millis(500));
    stop.store(true, Ordering::Relaxed);
    odometry.join().expect("odometry player");
    let truth = truth(&truth_file);
    assert!(emulator.exit_status().is_none(), "{}", emulator.log());
    assert!(msu.exit_status().is_none(), "{}", msu.log());
    let from_ns = truth[0].t_ns + settle_ns;
    let to_ns = from_ns + SCORED.as_nanos() as i64;
    let scored: Vec<&RobotPose> = all
        .iter()
        .filter(|p| (from_ns..to_ns).contains(&p.stamp.as_nanos()))
        .collect();

    // Poses come at the kit's rate all along, garbage or not: at least
    // half of the updates the emulator did not drop.
    let expected = SCORED.as_secs_f64() * RATE_HZ * 0.95;
    assert!(
        scored.len() as f64 > 0.5 * expected,
        "{} poses in {SCORED:?}\n{}",
        scored.len(),
        msu.log_tail(30)
    );
    let mut worst_ratio: f64 = 0.0;
    let mut errors = Vec::new();
    for p in &scored {
        let Some(at) = truth_at(&truth, p.stamp.as_nanos()) else {
            continue;
        };
        let err_m = (p.x_m - at[0]).hypot(p.y_m - at[1]);
        // Five sigma of one reading's position noise (a single update,
        // the least the filter has averaged), plus the distance the robot
        // covers in one update period at its top speed on the route (a
        // pose may be one update behind).
        let speed_m_s = site.routes[0].speed_m_s;
        let bound_m = 5.0 * RANGE_SIGMA_M * hdop(&site, at) + speed_m_s / RATE_HZ;
        worst_ratio = worst_ratio.max(err_m / bound_m);
        errors.push(err_m);
    }
    assert!(
        errors.len() > scored.len() / 2,
        "{} scored; poses {:?}..{:?}, truth {:?}..{:?}",
        errors.len(),
        scored.first(),
        scored.last(),
        truth.first(),
        truth.last()
    );
    errors.sort_by(f64::total_cmp);
    let median_m = errors[errors.len() / 2];
    eprintln!(
        "{} poses: median error {:.3} m, worst {:.3} m ({:.2} of its bound)",
        errors.len(),
        median_m,
        errors[errors.len() - 1],
        worst_ratio
    );
    assert!(
        worst_ratio <= 1.0,
        "a pose beyond its bound ({worst_ratio:.2} of it)\n{}",
        msu.log_tail(30)
    );
    // The garbage was seen, counted, and ended nothing.
    let log = msu.log();
    assert!(log.contains("garbage"), "{log}");
}

#[test]
fn a_hedgehog_on_a_pseudo_terminal_is_read_as_a_serial_port() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (name, site_file) = site_of_its_own(dir.path(), "pty");
    let mut cmd = Command::new(ICKON);
    cmd.args(["emulate", "marvelmind", "--garbage", "0.1"])
        .arg("--site")
        .arg(&site_file);
    let emulator = ChildGuard::spawn("hedgehog-pty", cmd, dir.path()).expect("emulator starts");
    let address = printed_address(&emulator, "serial:");

    let receivers = format!("marvelmind:{address}");
    let (_central, mut msu, central_endpoint) =
        central_and_msu(dir.path(), &name, &site_file, &receivers, "pty");
    let observer = Observer::open(std::slice::from_ref(&central_endpoint)).expect("observer");
    let keys = Keys::new(&name).expect("keys");
    let poses = observer
        .session()
        .declare_subscriber(keys.robot("r1", RobotTopic::Pose).unwrap())
        .wait()
        .expect("pose subscriber");
    // Two seconds of the kit's updates, each one pose at least.
    let mut n = 0;
    poll_until(START_TIMEOUT, "16 poses from the serial port", || {
        if let Some(status) = msu.exit_status() {
            panic!("msu {status}:\n{}", msu.log());
        }
        while let Ok(Some(s)) = poses.try_recv() {
            let p = ickon_proto::decode::<RobotPose>(&s.payload().to_bytes()).expect("pose");
            assert!(
                (0.0..=6.0).contains(&p.x_m) && (0.0..=5.0).contains(&p.y_m),
                "{p:?}"
            );
            n += 1;
        }
        (n >= 16).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", msu.log_tail(30)));
    let log = msu.log();
    assert!(log.contains(&format!("hedgehog on {address}")), "{log}");
}

#[test]
fn an_emulated_hedgehog_refuses_what_no_kit_can_be() {
    let run = |args: &[&str]| {
        let out = Command::new(ICKON)
            .args(["emulate", "marvelmind"])
            .args(args)
            .output()
            .expect("runs");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    // The warehouse's transmitter ids go beyond a kit's 254 addresses.
    let (code, err) = run(&["--site", "warehouse"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("addresses are 1-254"), "{err}");
    let (code, err) = run(&["--site", SITE, "--rate-hz", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--rate-hz"), "{err}");
    let (code, err) = run(&["--site", SITE, "--robot", "r9"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("r9"), "{err}");
}

#[test]
fn a_hedgehog_unplugged_and_plugged_back_is_read_again() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (name, site_file) = site_of_its_own(dir.path(), "replug");
    let port = ickon_testkit::free_tcp_port().expect("a free port");
    let listen = format!("127.0.0.1:{port}");
    let hedgehog = |n: &str| {
        let mut cmd = Command::new(ICKON);
        cmd.args(["emulate", "marvelmind", "--listen", &listen])
            .arg("--site")
            .arg(&site_file);
        ChildGuard::spawn(n, cmd, dir.path()).expect("emulator starts")
    };
    let mut first = hedgehog("hedgehog-1");

    let receivers = format!("marvelmind:tcp:{listen}");
    let (_central, mut msu, central_endpoint) =
        central_and_msu(dir.path(), &name, &site_file, &receivers, "replug");
    let observer = Observer::open(std::slice::from_ref(&central_endpoint)).expect("observer");
    let keys = Keys::new(&name).expect("keys");
    let poses = observer
        .session()
        .declare_subscriber(keys.robot("r1", RobotTopic::Pose).unwrap())
        .wait()
        .expect("pose subscriber");
    let count_poses = |msu: &mut ChildGuard, n: usize, what: &str| {
        let mut seen = 0;
        poll_until(START_TIMEOUT, what, || {
            if let Some(status) = msu.exit_status() {
                panic!("msu {status}:\n{}", msu.log());
            }
            while let Ok(Some(_)) = poses.try_recv() {
                seen += 1;
            }
            (seen >= n).then_some(())
        })
        .unwrap_or_else(|e| panic!("{e}\n{}", msu.log_tail(30)));
    };
    count_poses(&mut msu, 8, "poses from the first hedgehog");
    first.kill().expect("unplugged");
    std::thread::sleep(Duration::from_secs(1));
    assert!(msu.exit_status().is_none(), "{}", msu.log());
    let _second = hedgehog("hedgehog-2");
    // Drain what came before the hedgehog was back.
    while let Ok(Some(_)) = poses.try_recv() {}
    count_poses(&mut msu, 8, "poses from the hedgehog plugged back");
    let log = msu.log();
    assert!(log.contains("hedgehog lost"), "{log}");
    assert_eq!(
        log.matches(&format!("hedgehog on tcp:{listen} connected"))
            .count(),
        2,
        "{log}"
    );
}
