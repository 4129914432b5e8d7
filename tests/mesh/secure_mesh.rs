//! A secured site (`ickon site secure`): the router authenticates every
//! client and enforces the ACL, default deny. On a live router with the
//! central unit and four cells: a robot's forged cycle trigger and schedule
//! never reach a cell (while the central unit's do, and the robot's own keys
//! go through), a wrong password or an unknown user cannot connect, `ickon
//! admin` without the admin identity is refused with a clear message and
//! with it is answered (links in clear: `tcp/` endpoints). Two routers
//! linked over mutual TLS carry a floor's traffic to the other. And
//! `ickon sim --secure` gives fixes.
//!
//! Every wait polls with a deadline; every process is killed when its guard
//! drops, whatever happens.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_testkit::{ChildGuard, poll_until};
use support::ICKON;
use zenoh::Wait;
use zenoh::handlers::FifoChannel;

/// Generous but bounded: a loaded two-core machine starts a process slowly.
const START_TIMEOUT: Duration = Duration::from_secs(90);

/// `ickon site secure` of `site` into `out`, the router on `endpoint`.
fn secure(site: &Path, out: &Path, endpoint: &str, more: &[&str]) {
    let output = Command::new(ICKON)
        .args(["site", "secure"])
        .arg(site)
        .arg("--out")
        .arg(out)
        .args(["--listen", endpoint, "--connect", endpoint])
        .args(more)
        .output()
        .expect("ickon site secure runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A session authenticated as the client file `file` says, connecting to
/// `endpoint` and giving up at once if the router refuses it.
fn open_as(file: &Path, endpoint: &str) -> zenoh::Result<zenoh::Session> {
    let mut config = zenoh::Config::from_file(file)?;
    config.insert_json5("connect/endpoints", &format!("[{endpoint:?}]"))?;
    config.insert_json5("connect/timeout_ms", "2000")?;
    zenoh::open(config).wait()
}

/// The same with the password replaced.
fn open_with_password(
    file: &Path,
    endpoint: &str,
    password: &str,
) -> zenoh::Result<zenoh::Session> {
    let mut config = zenoh::Config::from_file(file)?;
    config.insert_json5("connect/endpoints", &format!("[{endpoint:?}]"))?;
    config.insert_json5("connect/timeout_ms", "2000")?;
    config.insert_json5("transport/auth/usrpwd/password", &format!("{password:?}"))?;
    zenoh::open(config).wait()
}

fn client_file(dir: &Path, user: &str) -> PathBuf {
    dir.join("clients").join(format!("{user}.json5"))
}

/// `ickon node <role>` as a client of the secured router, as `user`.
fn node(role: &str, site: &str, endpoint: &str, dir: &Path, user: &str) -> Command {
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", role, "--zenoh-config"])
        .arg(client_file(dir, user))
        .args(["--connect", endpoint, "--site-name", site]);
    cmd
}

/// `ickon router` with the secured configuration `config`, on `endpoint`.
fn spawn_router(config: &Path, endpoint: &str, name: &str, log_dir: &Path) -> ChildGuard {
    let mut cmd = Command::new(ICKON);
    cmd.args(["router", "--zenoh-config"])
        .arg(config)
        .args(["--listen", endpoint]);
    let mut router = ChildGuard::spawn(name, cmd, log_dir).expect("router");
    let port: u16 = endpoint.rsplit(':').next().unwrap().parse().unwrap();
    poll_until(START_TIMEOUT, "the router to listen", || {
        if let Some(status) = router.exit_status() {
            panic!("{name} {status}:\n{}", router.log());
        }
        ickon_testkit::port::accepts(port).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", router.log()));
    router
}

type Sub = zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// Every payload `sub` received so far.
fn drain(sub: &Sub) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    while let Ok(Some(s)) = sub.try_recv() {
        out.push(s.payload().to_bytes().to_vec());
    }
    out
}

#[test]
fn the_router_keeps_forgers_out_and_admin_needs_the_admin_identity() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let site = format!("secure-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(tmp.path(), &site);
    let keys = Keys::new(&site).unwrap();
    let endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let dir = tmp.path().join("secure");
    secure(&file, &dir, &endpoint, &[]);

    let _router = spawn_router(&dir.join("router.json5"), &endpoint, "router", tmp.path());

    let mut nodes = Vec::new();
    let mut central = node("central", &site, &endpoint, &dir, "central");
    central.arg("--site").arg(&file);
    nodes.push(ChildGuard::spawn("central", central, tmp.path()).expect("central"));
    for cell in ["c1", "c2", "c3", "c4"] {
        let mut cmd = node("cell", &site, &endpoint, &dir, &format!("cell-{cell}"));
        cmd.args(["--cell", cell]);
        nodes.push(ChildGuard::spawn(&format!("cell-{cell}"), cmd, tmp.path()).expect("cell"));
    }

    // What a cell receives: a session with cell c1's credential.
    let cell_view = open_as(&client_file(&dir, "cell-c1"), &endpoint).expect("cell c1 connects");
    let cycles = cell_view
        .declare_subscriber(keys.central_cycle())
        .with(FifoChannel::new(100_000))
        .wait()
        .unwrap();
    let schedules = cell_view
        .declare_subscriber(keys.central_schedule())
        .with(FifoChannel::new(100_000))
        .wait()
        .unwrap();
    // What the recorder hears of robot r1's own keys.
    let recorder = open_as(&client_file(&dir, "recorder"), &endpoint).expect("recorder");
    let r1_odom = recorder
        .declare_subscriber(keys.robot("r1", RobotTopic::Odom).unwrap())
        .with(FifoChannel::new(100_000))
        .wait()
        .unwrap();

    // Robot r1 forges a cycle trigger and a schedule, and publishes its own odometry.
    let robot = open_as(&client_file(&dir, "robot-r1"), &endpoint).expect("robot r1 connects");
    const FORGED: &[u8] = b"forged by robot r1";
    let started = Instant::now();
    let mut genuine_cycles = 0;
    let mut own_odometry = 0;
    while started.elapsed() < Duration::from_secs(60) && (genuine_cycles < 5 || own_odometry < 5) {
        for n in nodes.iter_mut() {
            if let Some(status) = n.exit_status() {
                panic!("{} {status}:\n{}", n.name(), n.log_tail(30));
            }
        }
        robot.put(keys.central_cycle(), FORGED).wait().unwrap();
        robot.put(keys.central_schedule(), FORGED).wait().unwrap();
        robot
            .put(keys.robot("r1", RobotTopic::Odom).unwrap(), FORGED)
            .wait()
            .unwrap();
        let got = drain(&cycles);
        assert!(
            got.iter().all(|p| p != FORGED),
            "a forged cycle trigger reached a cell"
        );
        genuine_cycles += got.len();
        assert!(
            drain(&schedules).iter().all(|p| p != FORGED),
            "a forged schedule reached a cell"
        );
        own_odometry += drain(&r1_odom).len();
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        genuine_cycles >= 5,
        "the central unit's triggers reach a cell ({genuine_cycles}):\n{}",
        nodes[0].log_tail(30)
    );
    assert!(
        own_odometry >= 5,
        "the robot's own keys go through ({own_odometry})"
    );

    // Wrong password, unknown user, no credential: the router refuses.
    let r1 = client_file(&dir, "robot-r1");
    assert!(open_with_password(&r1, &endpoint, "guessed").is_err());
    let stranger = tmp.path().join("stranger.json5");
    std::fs::write(
        &stranger,
        r#"{ mode: "client", transport: { auth: { usrpwd: { user: "robot-r99", password: "x" } } } }"#,
    )
    .unwrap();
    assert!(open_as(&stranger, &endpoint).is_err());
    let anonymous = tmp.path().join("anonymous.json5");
    std::fs::write(&anonymous, r#"{ mode: "client" }"#).unwrap();
    assert!(open_as(&anonymous, &endpoint).is_err());

    // `ickon admin` as a robot: refused, and says why; as the admin: answered.
    let admin = |user: &str| {
        Command::new(ICKON)
            .args([
                "admin",
                "status",
                "--site-name",
                &site,
                "--connect",
                &endpoint,
            ])
            .args(["--timeout-ms", "8000", "--zenoh-config"])
            .arg(client_file(&dir, user))
            .output()
            .expect("ickon admin runs")
    };
    let as_robot = admin("robot-r1");
    let said = String::from_utf8_lossy(&as_robot.stderr);
    assert_eq!(as_robot.status.code(), Some(1), "{said}");
    assert!(
        said.contains("refused") && said.contains("admin identity") && said.contains("robot-r1"),
        "{said}"
    );
    let as_admin = admin("admin");
    assert!(
        as_admin.status.success(),
        "{}",
        String::from_utf8_lossy(&as_admin.stderr)
    );
    assert!(String::from_utf8_lossy(&as_admin.stdout).contains("c4"));
    let _ = (
        cell_view.close().wait(),
        recorder.close().wait(),
        robot.close().wait(),
    );
}

#[test]
fn ickon_sim_secure_gives_fixes() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let out = Command::new(ICKON)
        .args([
            "sim",
            "--secure",
            "--robots",
            "2",
            "--duration",
            "8",
            "--json",
        ])
        .current_dir(tmp.path())
        .output()
        .expect("ickon sim runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert_eq!(report["secure"], true);
    for robot in report["robots"].as_array().unwrap() {
        let fixes = robot["fixes"].as_u64().unwrap_or(0);
        assert!(fixes >= 3, "{robot}\n{stderr}");
    }
    for cell in report["cells"].as_array().unwrap() {
        assert!(cell["cycles_fired"].as_u64().unwrap_or(0) > 0, "{cell}");
    }
}

#[test]
fn two_secured_routers_carry_the_site_between_floors() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let site = format!("secure2-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(tmp.path(), &site);
    let keys = Keys::new(&site).unwrap();
    // Over mutual TLS: the routers know each other by their certificates.
    let tls = |e: String| e.replacen("tcp/", "tls/", 1);
    let floor_1 = tls(ickon_testkit::loopback_endpoint().expect("port"));
    let floor_2 = tls(ickon_testkit::loopback_endpoint().expect("port"));
    let dir = tmp.path().join("secure");
    // Router 2 links to router 1 (`--link` is `--connect` by default); the
    // world stands in for the second floor's robots' sensors (`--sim`).
    secure(&file, &dir, &floor_1, &["--routers", "2", "--sim"]);
    let _router_1 = spawn_router(&dir.join("router.json5"), &floor_1, "router-1", tmp.path());
    let mut router_2 = spawn_router(
        &dir.join("router-2.json5"),
        &floor_2,
        "router-2",
        tmp.path(),
    );

    let mut nodes = Vec::new();
    let mut central = node("central", &site, &floor_1, &dir, "central");
    central.arg("--site").arg(&file);
    nodes.push(ChildGuard::spawn("central", central, tmp.path()).expect("central"));
    for cell in ["c1", "c2", "c3", "c4"] {
        let mut cmd = node("cell", &site, &floor_1, &dir, &format!("cell-{cell}"));
        cmd.args(["--cell", cell]);
        nodes.push(ChildGuard::spawn(&format!("cell-{cell}"), cmd, tmp.path()).expect("cell"));
    }
    let mut world = node("world", &site, &floor_2, &dir, "world");
    world.args(["--robots", "r1,r2", "--seed", "3"]);
    nodes.push(ChildGuard::spawn("world", world, tmp.path()).expect("world"));
    for robot in ["r1", "r2"] {
        let mut cmd = node("msu", &site, &floor_2, &dir, &format!("robot-{robot}"));
        cmd.args(["--robot", robot]);
        nodes.push(ChildGuard::spawn(&format!("msu-{robot}"), cmd, tmp.path()).expect("msu"));
    }

    // The recorder on the first floor hears the second floor's fixes and
    // poses: bursts crossed to the world, arrivals to the agents, and back.
    let recorder = open_as(&client_file(&dir, "recorder"), &floor_1).expect("recorder");
    let robots = recorder
        .declare_subscriber(format!("{}/robot/**", keys.prefix()))
        .with(FifoChannel::new(100_000))
        .wait()
        .unwrap();
    let flows = |nodes: &mut Vec<ChildGuard>, what: &str| {
        let mut seen = std::collections::HashMap::<(String, RobotTopic), usize>::new();
        poll_until(START_TIMEOUT, what, || {
            for n in nodes.iter_mut() {
                if let Some(status) = n.exit_status() {
                    panic!("{} {status}:\n{}", n.name(), n.log_tail(30));
                }
            }
            while let Ok(Some(s)) = robots.try_recv() {
                if let Ok(ickon_proto::keys::Key::Robot(id, topic)) =
                    keys.parse(s.key_expr().as_str())
                {
                    *seen.entry((id, topic)).or_default() += 1;
                }
            }
            let has = |r: &str, t: RobotTopic, n: usize| {
                seen.get(&(r.to_string(), t)).copied().unwrap_or(0) >= n
            };
            ["r1", "r2"]
                .iter()
                .all(|r| has(r, RobotTopic::Fix, 3) && has(r, RobotTopic::Pose, 20))
                .then_some(())
        })
        .unwrap_or_else(|e| {
            let logs: Vec<String> = nodes
                .iter()
                .map(|n| format!("--- {}:\n{}", n.name(), n.log_tail(10)))
                .collect();
            panic!("{e} (seen {seen:?})\n{}", logs.join("\n"))
        });
    };
    flows(&mut nodes, "fixes and poses through two secured routers");
    let pids: Vec<u32> = nodes.iter().map(ChildGuard::pid).collect();

    // The second floor's router dies and comes back: its clients
    // authenticate again by themselves, nothing else restarts.
    router_2.kill().expect("SIGKILL");
    std::thread::sleep(Duration::from_millis(500));
    while let Ok(Some(_)) = robots.try_recv() {}
    let _router_2 = spawn_router(
        &dir.join("router-2.json5"),
        &floor_2,
        "router-2b",
        tmp.path(),
    );
    flows(&mut nodes, "fixes and poses after the router came back");
    let after: Vec<u32> = nodes.iter().map(ChildGuard::pid).collect();
    assert_eq!(pids, after, "no node was restarted");
    let _ = recorder.close().wait();
}
