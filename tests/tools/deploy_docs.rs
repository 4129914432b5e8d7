//! The deployment guide, run as written: the shell blocks of
//! `docs/deployment.md` marked ```` ```sh deploy-test HOSTS ```` are
//! extracted and run in their order on the hosts they name, each host a
//! Linux network namespace on one bridge (`netns_lan`): `server` (router,
//! central unit), `cells` (two cell controllers, each on a transmitter
//! board on the network), `robot` (an MSU agent on a receiver board) and
//! `outsider` (no credential). The systemd units are started as systemd
//! would start them, from the same unit files and environment files, by
//! the stand-ins in `tests/tools/deploy_docs/` (`systemctl`, `sudo`,
//! `chown`, `useradd`, `usermod`), since a namespace runs no systemd and
//! the test has no `ickon` user: the nodes run as root.
//!
//! What the test adds to the guide, and only that: the air and the
//! boards. A simulated world (`ickon-world`) on a fifth host `air` plays
//! the transmitter boards at the guide's addresses (10.0.10.21 and .22,
//! port 4001) and the robot's receiver board (10.0.10.31), and drives the
//! robot `r1` along a route the test adds to the site file. It needs the
//! simulation's credential, so the guide's `ickon site secure` runs with
//! `--sim` here, and the copying of each machine's files (step 4 of the
//! checklist, `scp` on a real site) is done by the test.
//!
//! It checks that every cell fires on its board (`ready`), the robot is
//! posed from its receiver board, `ickon admin status` answers over mutual
//! TLS, and a plain-TCP client and a TLS client without the site's
//! certificates are refused within seconds by a router the outsider
//! reaches. It runs where it can make the hosts (root, `ip`, `unshare`, a
//! network namespace made) and otherwise skips, saying why; with
//! `ICKON_DEPLOY_TEST=1` (`.ci/run` sets it) it fails instead. It runs
//! alone (`.config/nextest.toml`).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use ickon_testkit::ChildGuard;
use serde_json::Value;

use crate::netns_lan::Lan;

/// The hosts and their addresses on 10.0.10.0/24.
const HOSTS: [(&str, &[&str]); 5] = [
    ("server", &["10.0.10.1"]),
    ("cells", &["10.0.10.2"]),
    ("robot", &["10.0.10.3"]),
    ("outsider", &["10.0.10.4"]),
    (
        "air",
        &["10.0.10.9", "10.0.10.21", "10.0.10.22", "10.0.10.31"],
    ),
];

/// Every host's `/etc/hosts`: the name the guide's certificates carry.
const HOSTS_FILE: &str = "127.0.0.1 localhost\n10.0.10.1 server.site.lan\n";

/// The simulation's part of the site file: a route for the world's robot,
/// given to the guide's `r1` (which has none, as on a real site).
const ROBOT_ROUTE: &str = r#"
# Appended by the deployment test: the simulated world drives r1 here.
[[routes]]
name = "corridor"
closed = true
points = [[1.0, 0.9], [15.0, 0.9], [15.0, 1.6], [1.0, 1.6]]
"#;

/// The guide's robot entry, and the same with the test's route.
const ROBOT_ENTRY: (&str, &str) = ("id = \"r1\"\n", "id = \"r1\"\nroute = \"corridor\"\n");

/// Each machine's files of `ickon site secure`'s output (step 4).
const COPIES: [(&str, &[&str]); 3] = [
    (
        "cells",
        &[
            "clients/cell-c1.json5",
            "clients/cell-c2.json5",
            "tls/cell-c1.crt",
            "tls/cell-c1.key",
            "tls/cell-c2.crt",
            "tls/cell-c2.key",
            "tls/ca.crt",
        ],
    ),
    (
        "robot",
        &[
            "clients/robot-r1.json5",
            "tls/robot-r1.crt",
            "tls/robot-r1.key",
            "tls/ca.crt",
        ],
    ),
    (
        "air",
        &[
            "clients/world.json5",
            "tls/world.crt",
            "tls/world.key",
            "tls/ca.crt",
        ],
    ),
];

/// A block of the guide: the hosts it runs on and its text.
#[derive(Debug)]
struct Block {
    hosts: Vec<String>,
    script: String,
}

/// The guide's ```` ```sh deploy-test HOSTS ```` blocks in order, each
/// unindented by its fence's indentation (blocks inside list items).
fn doc_blocks(markdown: &str) -> Vec<Block> {
    let mut blocks = Vec::new();
    let mut lines = markdown.lines();
    while let Some(line) = lines.next() {
        let trimmed = line.trim_start();
        let Some(hosts) = trimmed.strip_prefix("```sh deploy-test") else {
            continue;
        };
        let indent = line.len() - trimmed.len();
        let mut script = String::new();
        for body in lines.by_ref() {
            if body.trim() == "```" {
                break;
            }
            let cut = body.len() - body.trim_start().len();
            script.push_str(&body[cut.min(indent)..]);
            script.push('\n');
        }
        blocks.push(Block {
            hosts: hosts.trim().split(',').map(str::to_string).collect(),
            script,
        });
    }
    blocks
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the workspace")
        .to_path_buf()
}

/// The hosts' `/usr/local/bin`: `ickon` and the node binaries, each
/// `ickon node <role>` (the same code as the standalone binaries).
fn install_binaries(bin: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::create_dir_all(bin).expect("bin");
    let ickon = std::fs::canonicalize(support::ickon::path()).expect("ickon");
    std::os::unix::fs::symlink(ickon, bin.join("ickon")).expect("ickon link");
    for role in ["central", "cell", "msu", "world"] {
        let path = bin.join(format!("ickon-{role}"));
        let script = format!("#!/bin/sh\nexec /usr/local/bin/ickon node {role} \"$@\"\n");
        std::fs::write(&path, script).expect("wrapper");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).expect("mode");
    }
}

/// The environment of a block on `host`: the stand-ins first on PATH.
fn block_env(lan: &Lan, host: &str) -> Vec<(&'static str, String)> {
    let standins = repo_root().join("tests/tools/deploy_docs");
    vec![
        (
            "PATH",
            format!(
                "{}:/usr/local/bin:/usr/local/sbin:/usr/sbin:/usr/bin:/sbin:/bin",
                standins.display()
            ),
        ),
        (
            "ICKON_DEPLOY_LOGS",
            lan.host(host).dir.join("logs").display().to_string(),
        ),
    ]
}

/// Runs one block on one host from the repository's root (where the
/// guide's `deploy/...` paths are); its output, or a panic saying why.
fn run_block(lan: &Lan, host: &str, script: &str, expect_success: bool) -> String {
    let file = lan.host(host).dir.join("block.sh");
    let cd = format!("cd '{}'\n", repo_root().display());
    std::fs::write(&file, format!("set -eu\n{cd}{script}")).expect("block file");
    let file = file.display().to_string();
    let started = Instant::now();
    let out = lan
        .run(
            host,
            &block_env(lan, host),
            &["sh", &file],
            Duration::from_secs(90),
        )
        .unwrap_or_else(|| panic!("on {host}, this block of the guide hung:\n{script}"));
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    eprintln!(
        "--- {host} ({:.1} s, {}):\n{script}{text}",
        started.elapsed().as_secs_f64(),
        out.status
    );
    if expect_success {
        assert!(
            out.status.success(),
            "on {host}, this block of the guide failed ({}):\n{script}\n{text}",
            out.status
        );
    }
    text
}

/// Copies each machine's files from the server's output (step 4),
/// keeping the paths and modes.
fn distribute_credentials(lan: &Lan) {
    let from = lan.host("server").dir.join("etc-ickon/secure");
    for (host, files) in COPIES {
        let to = lan.host(host).dir.join("etc-ickon/secure");
        for f in files {
            let dest = to.join(f);
            std::fs::create_dir_all(dest.parent().expect("dir")).expect("mkdir");
            std::fs::copy(from.join(f), &dest)
                .unwrap_or_else(|e| panic!("{f} for {host} ({e}): not written by the guide"));
        }
    }
}

/// The world on `air`: the boards at the guide's addresses, robot r1.
fn start_world(lan: &Lan, log_dir: &Path) -> ChildGuard {
    let cmd = lan.command(
        "air",
        &[("RUST_LOG", "info".to_string())],
        &[
            "/usr/local/bin/ickon-world",
            "--zenoh-config",
            "/etc/ickon/secure/clients/world.json5",
            "--site-name",
            "hall",
            "--robots",
            "r1",
            "--device",
            "cell/c1=transmitter-board@10.0.10.21:4001",
            "--device",
            "cell/c2=transmitter-board@10.0.10.22:4001",
            "--device",
            "robot/r1=receiver-board@10.0.10.31:4001",
        ],
    );
    ChildGuard::spawn("world", cmd, log_dir).expect("start the world")
}

/// What is still missing for a working site in `ickon admin status
/// --json`, or `None` when every cell fires on a ready board and the
/// robot is posed from its receiver board.
fn missing(status: &Value) -> Option<String> {
    let mut missing = Vec::new();
    for id in ["c1", "c2"] {
        let cell = status["cells"]
            .as_array()
            .and_then(|cs| cs.iter().find(|c| c["id"] == id));
        let ok = cell.is_some_and(|c| {
            c["cycles_fired"].as_u64().unwrap_or(0) > 0
                && c["device"].as_str().is_some_and(|d| d.contains("ready"))
        });
        if !ok {
            missing.push(format!("cell {id} firing on a ready board: {cell:?}"));
        }
    }
    let robot = status["robots"]
        .as_array()
        .and_then(|rs| rs.iter().find(|r| r["id"] == "r1"));
    let ok = robot.is_some_and(|r| {
        r["pose"].is_object()
            && r["fixes_per_s"].as_f64().unwrap_or(0.0) > 0.0
            && r["receivers"].as_str().is_some_and(|d| d.contains("ready"))
    });
    if !ok {
        missing.push(format!("robot r1 posed from its board: {robot:?}"));
    }
    (!missing.is_empty()).then(|| missing.join("; "))
}

/// Asks the central unit over mutual TLS until the site works, for at
/// most `timeout`; panics with the nodes' logs if it does not.
fn wait_for_site(lan: &Lan, timeout: Duration) {
    let start = Instant::now();
    let mut last = String::from("no answer yet");
    while start.elapsed() < timeout {
        let out = lan.run(
            "server",
            &[],
            &[
                "/usr/local/bin/ickon",
                "admin",
                "status",
                "--site-name",
                "hall",
                "--zenoh-config",
                "/etc/ickon/secure/clients/admin.json5",
                "--json",
            ],
            Duration::from_secs(30),
        );
        let text = out.map(|o| String::from_utf8_lossy(&o.stdout).into_owned());
        let json = text.as_deref().and_then(|t| {
            let start = t.find('{')?;
            serde_json::from_str::<Value>(&t[start..]).ok()
        });
        match json.as_ref().map(missing) {
            Some(None) => return,
            Some(Some(m)) => last = m,
            None => last = text.unwrap_or_else(|| "admin hung".into()),
        }
        std::thread::sleep(Duration::from_secs(2));
    }
    panic!(
        "the site did not come up in {} s: {last}\n{}",
        timeout.as_secs(),
        node_logs(lan)
    );
}

/// The last lines of every unit's log on every host.
fn node_logs(lan: &Lan) -> String {
    let mut all = String::new();
    for (host, _) in HOSTS {
        let logs = lan.host(host).dir.join("logs");
        let Ok(entries) = std::fs::read_dir(&logs) else {
            continue;
        };
        for e in entries.flatten() {
            let text = std::fs::read_to_string(e.path()).unwrap_or_default();
            let tail: Vec<&str> = text.lines().rev().take(15).collect();
            all.push_str(&format!("== {host}: {}\n", e.file_name().to_string_lossy()));
            for l in tail.into_iter().rev() {
                all.push_str(l);
                all.push('\n');
            }
        }
    }
    all
}

/// Whether this machine can make the test's hosts: root, iproute2's `ip`
/// and util-linux's `unshare`, and a network namespace actually made
/// (a container without the right to do so refuses it); why not if not.
fn can_make_hosts() -> Result<(), String> {
    use std::process::Command;
    if std::env::var("ICKON_DEPLOY_TEST").as_deref() == Ok("0") {
        return Err("ICKON_DEPLOY_TEST=0".into());
    }
    let uid = Command::new("id")
        .arg("-u")
        .output()
        .map_err(|e| format!("id -u: {e}"))?;
    if String::from_utf8_lossy(&uid.stdout).trim() != "0" {
        return Err("it needs root (network namespaces, bind mounts)".into());
    }
    for (tool, package) in [("ip", "iproute2"), ("unshare", "util-linux")] {
        if Command::new(tool).arg("-V").output().is_err() {
            return Err(format!("no `{tool}` ({package})"));
        }
    }
    let probe = format!("ick{}-probe", std::process::id());
    let made = Command::new("ip")
        .args(["netns", "add", &probe])
        .output()
        .map_err(|e| format!("ip netns add: {e}"))?;
    let _ = Command::new("ip").args(["netns", "del", &probe]).output();
    if !made.status.success() {
        return Err(format!(
            "`ip netns add` failed: {}",
            String::from_utf8_lossy(&made.stderr).trim()
        ));
    }
    Ok(())
}

/// Whether the outsider reaches the router's port at all: else its
/// refusals would prove nothing about the access control.
fn outsider_reaches_router(lan: &Lan) -> bool {
    let out = lan.run(
        "outsider",
        &[],
        &["bash", "-c", "exec 3<>/dev/tcp/10.0.10.1/7447"],
        Duration::from_secs(10),
    );
    out.is_some_and(|o| o.status.success())
}

#[test]
fn the_deployment_guide_builds_a_secured_site_on_separate_hosts() {
    if let Err(why) = can_make_hosts() {
        assert!(
            std::env::var("ICKON_DEPLOY_TEST").as_deref() != Ok("1"),
            "ICKON_DEPLOY_TEST=1 asks for the deployment test, which cannot run here: {why}"
        );
        eprintln!("skipped: the deployment guide's test cannot run here: {why}");
        return;
    }
    let guide = std::fs::read_to_string(repo_root().join("docs/deployment.md")).expect("guide");
    let blocks = doc_blocks(&guide);
    assert!(
        blocks.len() >= 7,
        "the guide's deploy-test blocks: {blocks:?}"
    );
    let root = tempfile::tempdir().expect("tempdir");
    install_binaries(&root.path().join("bin"));
    let lan = Lan::new(root.path(), &root.path().join("bin"), HOSTS_FILE, &HOSTS);
    let mut world = None;
    let mut site_checked = false;
    let mut refusals = 0;
    for block in &blocks {
        let mut script = block.script.clone();
        let secures = script.contains("ickon site secure");
        if secures {
            let site = lan.host("server").dir.join("etc-ickon/site.toml");
            let text = std::fs::read_to_string(&site).expect("the guide wrote no site file");
            assert!(
                text.contains(ROBOT_ENTRY.0),
                "the guide's site file lists no r1"
            );
            let mut text = text.replacen(ROBOT_ENTRY.0, ROBOT_ENTRY.1, 1);
            text.push_str(ROBOT_ROUTE);
            std::fs::write(&site, text).expect("site file");
            script = script.replace("ickon site secure ", "ickon site secure --sim ");
        }
        if script.contains("ickon admin status") && block.hosts == ["server"] {
            wait_for_site(&lan, Duration::from_secs(180));
            site_checked = true;
        }
        for host in &block.hosts {
            let expect_success = host != "outsider";
            let started = Instant::now();
            let out = run_block(&lan, host, &script, expect_success);
            if host == "outsider" {
                assert!(
                    site_checked && outsider_reaches_router(&lan),
                    "the outsider's block must run against a working router it can reach"
                );
                // Each refusal is `ickon admin`'s own error, not a shell's.
                assert_eq!(
                    out.matches("no central unit of site \"hall\" answered")
                        .count(),
                    out.matches("refused, as it should be").count(),
                    "the outsider's commands failed otherwise than refused:\n{out}"
                );
                refusals += out.matches("refused, as it should be").count();
                assert!(
                    started.elapsed() < Duration::from_secs(60),
                    "refusing the outsider took {:.0} s",
                    started.elapsed().as_secs_f64()
                );
            }
        }
        if secures {
            distribute_credentials(&lan);
            world = Some(start_world(&lan, &lan.host("air").dir.join("logs")));
        }
    }
    assert!(world.is_some(), "the guide never ran `ickon site secure`");
    assert!(
        site_checked,
        "the guide never runs `ickon admin status` on server"
    );
    assert_eq!(
        refusals, 2,
        "the plain-TCP and the certificate-less clients must both be refused"
    );
}

#[test]
fn the_guide_marks_its_blocks_for_every_host() {
    let guide = std::fs::read_to_string(repo_root().join("docs/deployment.md")).expect("guide");
    let blocks = doc_blocks(&guide);
    let hosts: std::collections::BTreeSet<&str> = blocks
        .iter()
        .flat_map(|b| b.hosts.iter().map(String::as_str))
        .collect();
    for h in ["server", "cells", "robot", "outsider"] {
        assert!(hosts.contains(h), "no deploy-test block for {h}: {hosts:?}");
    }
    let all: String = blocks.iter().map(|b| b.script.as_str()).collect();
    for step in [
        "ickon site secure",
        "ickon-cell@c1",
        "ickon-msu@r1",
        "ICKON_DRIVER=tcp:",
        "ICKON_RECEIVERS=tcp:",
        "ickon admin status",
    ] {
        assert!(all.contains(step), "the tested blocks never do {step}");
    }
}
