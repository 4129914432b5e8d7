//! `ickon sim --routers 2` on `lab`: the site as a site with one router per
//! zone runs it, the corridor's cells on one router and the room's on the
//! other, linked. Every robot gets its fixes, every cell fires, and the
//! report lists both routers with what each carried. With `--secure` every
//! node comes up through its zone's router (each router with its own
//! certificate and the site's access control, the second linked to the
//! first as the user `router`); a zone's router that dies is named like any
//! node; and bad `--routers` values are refused before anything starts.

use std::process::Command;
use std::time::Duration;

use ickon_testkit::{ChildGuard, poll_until};
use serde_json::Value;
use support::ICKON;

/// Watched seconds: enough cycles for the fix shares to mean something
/// (about 6 cycles a second on `lab`).
const DURATION_S: u64 = 12;
/// From `ickon sim` to every node live (or to its end after a kill).
const START_TIMEOUT: Duration = Duration::from_secs(90);

/// The share of its cycles a robot must get a fix from, and a cell must
/// fire, in a healthy run: what `sim_mesh` asks of one router.
const MIN_FIX_SHARE: f64 = 0.8;
const MIN_FIRED_SHARE: f64 = 0.95;

#[test]
fn two_zones_on_two_linked_routers_carry_lab_and_the_report_shows_each_router() {
    let out = Command::new(ICKON)
        .args(["sim", "--site", "lab", "--robots", "3", "--routers", "2"])
        .args([
            "--seed",
            "4",
            "--json",
            "--duration",
            &DURATION_S.to_string(),
        ])
        .output()
        .expect("ickon sim starts");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "ickon sim failed:\n{stderr}");
    let doc: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document ({e}):\n{stderr}"));

    let robots = doc["robots"].as_array().expect("robots");
    assert_eq!(robots.len(), 3, "{doc}");
    for r in robots {
        let share = r["fix_share"].as_f64().unwrap_or(0.0);
        assert!(
            share >= MIN_FIX_SHARE,
            "robot {}: fixes from {share} of its cycles\n{doc}",
            r["id"]
        );
        assert!(r["latency_p50_us"].as_f64().is_some(), "{doc}");
    }
    let cells = doc["cells"].as_array().expect("cells");
    assert_eq!(cells.len(), 4, "{doc}");
    for c in cells {
        let share = c["fired_share"].as_f64().unwrap_or(0.0);
        assert!(
            share >= MIN_FIRED_SHARE && c["cycles_fired"].as_u64().unwrap_or(0) > 0,
            "cell {} fired {share} of its cycles\n{doc}",
            c["id"]
        );
    }

    let routers = doc["routers"].as_array().expect("routers");
    let names: Vec<&str> = routers.iter().filter_map(|r| r["name"].as_str()).collect();
    assert_eq!(names, ["router z1", "router z2"], "{doc}");
    assert_eq!(
        routers[0]["cells"],
        serde_json::json!(["c1", "c2"]),
        "{doc}"
    );
    assert_eq!(
        routers[1]["cells"],
        serde_json::json!(["c3", "c4"]),
        "{doc}"
    );
    assert_eq!(routers[0]["hub"], true, "{doc}");
    assert_eq!(routers[1]["hub"], false, "{doc}");
    let mut placed: Vec<&str> = routers
        .iter()
        .flat_map(|r| r["robots"].as_array().into_iter().flatten())
        .filter_map(Value::as_str)
        .collect();
    placed.sort_unstable();
    assert_eq!(placed, ["r1", "r2", "r3"], "{doc}");
    for r in routers {
        // Each router relayed a zone's bursts, statuses and poses for
        // the whole run: measurable CPU time and memory.
        for (field, least) in [("cpu_s", 0.05), ("peak_rss_mib", 1.0)] {
            let v = r[field].as_f64().unwrap_or(0.0);
            assert!(v >= least, "{} {field} {v}\n{doc}", r["name"]);
        }
    }
    // The table says the same, one line per router.
    assert!(
        doc["processes"]
            .as_array()
            .expect("processes")
            .iter()
            .any(|k| k["kind"] == "router" && k["processes"] == 2),
        "{doc}"
    );
}

#[test]
fn secured_zones_come_up_and_a_zone_router_that_dies_is_named() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut sim = Command::new(ICKON);
    // Every node live (the launcher waits for each one's token, seen
    // through the hub) means every cell's and agent's credential was
    // accepted by its zone's router and the link between the routers by
    // the hub's access control.
    sim.args(["sim", "--site", "lab", "--robots", "3", "--routers", "2"])
        .args(["--secure", "--duration", "120"]);
    let mut sim = ChildGuard::spawn("sim", sim, dir.path()).expect("ickon sim starts");
    poll_until(START_TIMEOUT, "the sim to run", || {
        if let Some(status) = sim.exit_status() {
            panic!("ickon sim {status}:\n{}", sim.log());
        }
        sim.log().contains("nodes live").then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    // The second zone's router: the one linked (`--connect`) to the hub.
    let linked = children_with_args(sim.pid(), &["router", "--connect"]);
    assert_eq!(linked.len(), 1, "one linked router child: {linked:?}");
    let killed = Command::new("kill")
        .args(["-KILL", &linked[0].to_string()])
        .status()
        .expect("kill runs");
    assert!(killed.success());
    let status = poll_until(START_TIMEOUT, "the sim to stop", || sim.exit_status())
        .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));
    assert_eq!(status.code(), Some(1), "{}", sim.log());
    assert!(sim.log().contains("node router z2"), "{}", sim.log());
}

#[test]
fn impossible_router_counts_are_refused_before_anything_starts() {
    for (routers, says) in [
        ("0", "at least one router"),
        ("5", "more than the 4 cells"),
        ("1000000", "more than the 4 cells"),
        ("-1", "invalid value '-1' for '--routers"),
        ("two", "--routers"),
        ("99999999999999999999999", "--routers"),
    ] {
        let out = Command::new(ICKON)
            .args([
                "sim",
                "--site",
                "lab",
                "--routers",
                routers,
                "--duration",
                "1",
            ])
            .output()
            .expect("ickon sim runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "--routers {routers}: {stderr}");
        assert!(stderr.contains(says), "--routers {routers}: {stderr}");
    }
    let out = Command::new(ICKON)
        .args(["sim", "--mesh", "peer", "--routers", "2", "--duration", "1"])
        .output()
        .expect("ickon sim runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("needs --mesh router"), "{stderr}");
}

/// The children of `parent` whose command line holds every one of `words`
/// as an argument.
fn children_with_args(parent: u32, words: &[&str]) -> Vec<u32> {
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
            let args: Vec<&[u8]> = cmdline.split(|b| *b == 0).collect();
            ppid == Some(parent) && words.iter().all(|w| args.contains(&w.as_bytes()))
        })
        .collect()
}
