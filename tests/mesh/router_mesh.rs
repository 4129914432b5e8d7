//! The site as deployed: two linked Zenoh routers (`ickon router`, one per
//! floor), the central unit and the cells clients of the first, the world
//! and two MSU agents clients of the second. Poses must flow across the
//! link; when the second router dies and comes back on the same port, its
//! clients reconnect on their own (nothing else restarts), each says in its
//! log that its router went and came back, poses flow again, and `ickon
//! admin status` lists each of them as back, and no other.
//!
//! Every wait polls with a deadline; every process is killed when its guard
//! drops, whatever happens.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_testkit::{ChildGuard, Observer, poll_until};
use support::ICKON;
use zenoh::Wait;
use zenoh::handlers::FifoChannel;

/// Generous but bounded: a loaded two-core machine starts a process slowly.
const START_TIMEOUT: Duration = Duration::from_secs(90);
const ROBOTS: [&str; 2] = ["r1", "r2"];

/// `ickon router` listening on `listen`, linked to the routers `link`.
fn spawn_router(dir: &Path, name: &str, listen: &str, link: &[&str]) -> ChildGuard {
    let mut cmd = Command::new(ICKON);
    cmd.args(["router", "--no-multicast-scouting", "--listen", listen]);
    for l in link {
        cmd.args(["--connect", l]);
    }
    let mut router = ChildGuard::spawn(name, cmd, dir).expect("router starts");
    let port: u16 = listen.rsplit(':').next().unwrap().parse().unwrap();
    poll_until(START_TIMEOUT, "the router to listen", || {
        if let Some(status) = router.exit_status() {
            panic!("{name} {status}:\n{}", router.log());
        }
        ickon_testkit::port::accepts(port).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", router.log()));
    router
}

/// `ickon node <role>` as a client of the router at `router`.
fn client(role: &str, site: &str, router: &str) -> Command {
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", role, "--mode", "client", "--no-multicast-scouting"])
        .args(["--connect", router, "--site-name", site]);
    // `ickon node` logs at WARN unless told; the router watch's returns are
    // INFO, as a deployed node (RUST_LOG=info) writes them.
    cmd.env("RUST_LOG", "warn,ickon_runtime::router_watch=info");
    cmd
}

type Sub = zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// Waits until `count` poses and three fixes of each robot arrive on `sub`
/// (a fix needs the cells' bursts to have crossed from one router to the
/// other, and the arrivals back).
fn poses_flow(sub: &Sub, keys: &Keys, count: usize, nodes: &mut [ChildGuard], what: &str) {
    let mut seen = std::collections::BTreeMap::<(String, bool), usize>::new();
    poll_until(START_TIMEOUT, what, || {
        for n in nodes.iter_mut() {
            if let Some(status) = n.exit_status() {
                panic!("{} {status}:\n{}", n.name(), n.log_tail(40));
            }
        }
        while let Ok(Some(s)) = sub.try_recv() {
            match keys.parse(s.key_expr().as_str()) {
                Ok(ickon_proto::keys::Key::Robot(id, RobotTopic::Pose)) => {
                    *seen.entry((id, false)).or_default() += 1;
                }
                Ok(ickon_proto::keys::Key::Robot(id, RobotTopic::Fix)) => {
                    *seen.entry((id, true)).or_default() += 1;
                }
                _ => {}
            }
        }
        let has = |r: &str, fix: bool, n: usize| {
            seen.get(&(r.to_string(), fix)).copied().unwrap_or(0) >= n
        };
        ROBOTS
            .iter()
            .all(|r| has(r, false, count) && has(r, true, 3))
            .then_some(())
    })
    .unwrap_or_else(|e| {
        let logs: Vec<String> = nodes
            .iter()
            .map(|n| format!("--- {}:\n{}", n.name(), n.log_tail(15)))
            .collect();
        panic!("{e} (seen {seen:?})\n{}", logs.join("\n"))
    });
}

#[test]
fn two_linked_routers_carry_the_site_and_clients_reconnect_to_a_router_that_returns() {
    let dir = tempfile::tempdir().expect("temp dir");
    let site = format!("routers-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(dir.path(), &site);
    let keys = Keys::new(&site).unwrap();
    let floor_1 = ickon_testkit::loopback_endpoint().expect("port");
    let floor_2 = ickon_testkit::loopback_endpoint().expect("port");
    let _router_1 = spawn_router(dir.path(), "router-1", &floor_1, &[]);
    let mut router_2 = spawn_router(dir.path(), "router-2", &floor_2, &[&floor_1]);

    let mut nodes = Vec::new();
    let mut central = client("central", &site, &floor_1);
    central.arg("--site").arg(&file);
    nodes.push(ChildGuard::spawn("central", central, dir.path()).expect("central"));
    for cell in ["c1", "c2", "c3", "c4"] {
        let mut cmd = client("cell", &site, &floor_1);
        cmd.args(["--cell", cell]);
        nodes.push(ChildGuard::spawn(&format!("cell-{cell}"), cmd, dir.path()).expect("cell"));
    }
    let mut world = client("world", &site, &floor_2);
    world.args(["--robots", &ROBOTS.join(","), "--seed", "3"]);
    nodes.push(ChildGuard::spawn("world", world, dir.path()).expect("world"));
    for robot in ROBOTS {
        let mut cmd = client("msu", &site, &floor_2);
        cmd.args(["--robot", robot]);
        nodes.push(ChildGuard::spawn(&format!("msu-{robot}"), cmd, dir.path()).expect("msu"));
    }
    let pids: Vec<u32> = nodes.iter().map(ChildGuard::pid).collect();

    // The test watches from the first floor: the poses cross the link.
    let observer = Observer::open(std::slice::from_ref(&floor_1)).expect("observer");
    let poses = observer
        .session()
        .declare_subscriber(format!("{}/robot/**", keys.prefix()))
        .with(FifoChannel::new(100_000))
        .wait()
        .expect("subscriber");
    poses_flow(&poses, &keys, 20, &mut nodes, "poses through two routers");

    // The second floor's router dies: its clients lose the site.
    router_2.kill().expect("SIGKILL");
    std::thread::sleep(Duration::from_millis(500));
    while let Ok(Some(_)) = poses.try_recv() {}
    // ... and comes back on the same port: they reconnect by themselves.
    let _router_2 = spawn_router(dir.path(), "router-2b", &floor_2, &[&floor_1]);
    poses_flow(
        &poses,
        &keys,
        20,
        &mut nodes,
        "poses after the router came back",
    );
    let after: Vec<u32> = nodes.iter().map(ChildGuard::pid).collect();
    assert_eq!(pids, after, "no node was restarted");
    // Each client of the lost router said so, at WARN, and said when it
    // was back, at INFO (within a second of its return: the watch's
    // period); the first floor's clients lost nothing.
    let said_back = |n: &ChildGuard| n.log().contains("link to the Zenoh router back after");
    let second_floor = |n: &ChildGuard| n.name() == "world" || n.name().starts_with("msu-");
    let _ = poll_until(Duration::from_secs(10), "every return said", || {
        nodes
            .iter()
            .filter(|n| second_floor(n))
            .all(said_back)
            .then_some(())
    });
    for n in &nodes {
        let log = n.log();
        let second_floor = second_floor(n);
        let lost = log
            .lines()
            .any(|l| l.contains("WARN") && l.contains("lost the link to the Zenoh router"));
        let back = log
            .lines()
            .any(|l| l.contains("INFO") && l.contains("link to the Zenoh router back after"));
        assert_eq!(
            (lost, back),
            (second_floor, second_floor),
            "{}:\n{}",
            n.name(),
            n.log_tail(30)
        );
    }
    // `ickon admin status` says which nodes came back, and when: the
    // robots (second floor) once each, the cells (first floor) never.
    let links = poll_until(
        Duration::from_secs(30),
        "the robots' returns in the admin",
        || {
            let links = admin_links(&site, &floor_1)?;
            ROBOTS
                .iter()
                .all(|r| link_of(&links["robots"], r).is_some_and(|l| l.0.is_some() && l.1 == 1))
                .then_some(links)
        },
    )
    .unwrap_or_else(|e| panic!("{e}: {:?}", admin_links(&site, &floor_1)));
    for cell in ["c1", "c2", "c3", "c4"] {
        assert_eq!(link_of(&links["cells"], cell), Some((None, 0)), "{links}");
    }
}

/// `ickon admin status --json`'s `router_links`, or `None` while it fails.
fn admin_links(site: &str, router: &str) -> Option<serde_json::Value> {
    let out = Command::new(ICKON)
        .args(["admin", "status", "--json", "--timeout-ms", "10000"])
        .args(["-e", router, "--no-multicast-scouting", "--site-name", site])
        .output()
        .ok()?;
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).ok()?;
    Some(doc["router_links"].clone()).filter(|l| !l.is_null())
}

/// A node's (`back_unix_ms`, `losses`) in a `router_links` list.
fn link_of(list: &serde_json::Value, id: &str) -> Option<(Option<u64>, u64)> {
    let l = list.as_array()?.iter().find(|l| l["id"] == id)?;
    Some((l["back_unix_ms"].as_u64(), l["losses"].as_u64()?))
}

/// The children of `parent` whose command line holds `word` as an argument.
fn children_running(parent: u32, word: &str) -> Vec<u32> {
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    dir.filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
            let ppid = stat
                .rsplit(')')
                .next()
                .and_then(|rest| rest.split_whitespace().nth(1))
                .and_then(|p| p.parse::<u32>().ok());
            let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
            ppid == Some(parent) && cmdline.split(|b| *b == 0).any(|arg| arg == word.as_bytes())
        })
        .collect()
}

#[test]
fn ickon_sim_reports_a_router_that_dies_like_any_node() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut sim = Command::new(ICKON);
    sim.args(["sim", "--robots", "1", "--duration", "120"]);
    let mut sim = ChildGuard::spawn("sim", sim, dir.path()).expect("ickon sim starts");
    // Wait until the run is up (its status line), then kill its router.
    poll_until(START_TIMEOUT, "the sim to run", || {
        if let Some(status) = sim.exit_status() {
            panic!("ickon sim {status}:\n{}", sim.log());
        }
        sim.log().contains("nodes live").then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    let routers = children_running(sim.pid(), "router");
    assert_eq!(routers.len(), 1, "one router child: {routers:?}");
    nix_kill(routers[0]);
    let status = poll_until(START_TIMEOUT, "the sim to stop", || sim.exit_status())
        .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    assert_eq!(status.code(), Some(1), "{}", sim.log());
    assert!(sim.log().contains("node router"), "{}", sim.log());
}

/// SIGKILL to `pid` (the `kill` command: no unsafe code in tests either).
fn nix_kill(pid: u32) {
    let ok = Command::new("kill")
        .args(["-KILL", &pid.to_string()])
        .status()
        .expect("kill runs")
        .success();
    assert!(ok, "kill -KILL {pid}");
}
