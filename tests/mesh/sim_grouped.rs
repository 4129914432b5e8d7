//! Robots grouped in agent processes (`ickon sim --robots-per-process`)
//! and the site's servers on CPUs apart from the simulation
//! (`--split-cores`): every robot must track as a lone agent does, each
//! process must run on its side's CPUs, a fleet process that dies must
//! take down only its own robots, and grouped robots must work under
//! access control with their fleet's credential.

use std::collections::BTreeMap;
use std::process::Command;
use std::time::Duration;

use serde_json::Value;

use support::ICKON;
use support::sim_run::{finish, start_sim};

/// The CPU list of a `/proc/<pid>/status` (`Cpus_allowed_list`).
fn cpus_of(pid: &str) -> Option<String> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status
        .lines()
        .find(|l| l.starts_with("Cpus_allowed_list:"))?;
    Some(line.split_whitespace().nth(1)?.to_string())
}

/// Every CPU of a CPU list (`0-1,3`).
fn expand(list: &str) -> Vec<usize> {
    list.split(',')
        .flat_map(|part| {
            let (a, b) = part.split_once('-').unwrap_or((part, part));
            a.parse::<usize>().unwrap()..=b.parse::<usize>().unwrap()
        })
        .collect()
}

/// The children of `parent`: pid, the role (`router`, `central`, `cell`,
/// `world`, `fleet`, `msu`), its command line.
fn children(parent: u32) -> Vec<(String, String, Vec<String>)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let pid = entry.file_name().to_string_lossy().to_string();
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        let after = &stat[stat.rfind(')').unwrap() + 1..];
        let ppid: u32 = after.split_whitespace().nth(1).unwrap().parse().unwrap();
        if ppid != parent {
            continue;
        }
        let Ok(cmdline) = std::fs::read(format!("/proc/{pid}/cmdline")) else {
            continue;
        };
        let args: Vec<String> = cmdline
            .split(|&b| b == 0)
            .map(|a| String::from_utf8_lossy(a).to_string())
            .collect();
        let role = match args.iter().position(|a| a == "node") {
            Some(i) => args.get(i + 1).cloned().unwrap_or_default(),
            None if args.iter().any(|a| a == "router") => "router".into(),
            None => continue,
        };
        out.push((pid, role, args));
    }
    out
}

/// The report's robots by id.
fn robots(doc: &Value) -> BTreeMap<String, Value> {
    doc["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| (r["id"].as_str().unwrap().to_string(), r.clone()))
        .collect()
}

#[test]
fn grouped_agents_track_on_their_own_cpus_and_a_dead_fleet_takes_only_its_robots() {
    let available = cpus_of("self").unwrap();
    let all = expand(&available);
    if all.len() < 2 {
        // One CPU: the split is refused by name, exit 2.
        let out = Command::new(ICKON)
            .args(["sim", "--split-cores", "--duration", "1"])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&out.stderr).contains("splitting needs two or more"));
        return;
    }
    let (servers, simulation) = all.split_at(all.len() / 2);
    const RUN_S: u64 = 16;
    let dir = tempfile::tempdir().unwrap();
    let runtime_dir = dir.path().join("run");
    std::fs::create_dir_all(&runtime_dir).unwrap();
    let args = [
        "--robots",
        "5",
        "--robots-per-process",
        "2",
        "--split-cores",
        "--restart",
    ];
    let sim = start_sim(dir.path(), &runtime_dir, RUN_S, &args);
    let nodes = children(sim.pid());
    let fleets: Vec<String> = nodes
        .iter()
        .filter(|(_, role, _)| role == "fleet")
        .map(|(_, _, args)| {
            let i = args.iter().position(|a| a == "--robots").unwrap();
            args[i + 1].clone()
        })
        .collect();
    assert_eq!(fleets.len(), 3, "{nodes:?}");
    for group in ["r1,r2", "r3,r4", "r5"] {
        assert!(fleets.iter().any(|f| f == group), "{group}: {fleets:?}");
    }
    assert!(!nodes.iter().any(|(_, role, _)| role == "msu"), "{nodes:?}");
    for (pid, role, _) in &nodes {
        let Some(list) = cpus_of(pid) else { continue };
        let want = match role.as_str() {
            "router" | "central" | "cell" => servers,
            _ => simulation,
        };
        assert_eq!(expand(&list), want, "{role} (pid {pid}) runs on {list}");
    }
    // The launcher itself runs on the simulation's side.
    assert_eq!(
        expand(&cpus_of(&sim.pid().to_string()).unwrap()),
        simulation
    );
    std::thread::sleep(Duration::from_secs(3));
    let (victim, _, _) = nodes
        .iter()
        .find(|(_, role, args)| role == "fleet" && args.iter().any(|a| a == "r3,r4"))
        .unwrap();
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(victim.parse().unwrap()),
        nix::sys::signal::Signal::SIGKILL,
    )
    .unwrap();
    let (log, doc) = finish(sim, RUN_S);
    let tail = &log[log.len().saturating_sub(3_000)..];
    let restarts: Vec<&str> = doc["restarts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    assert_eq!(restarts, ["fleet r3..r4"], "{tail}");
    let robots = robots(&doc);
    for id in ["r1", "r2", "r5"] {
        let share = robots[id]["fix_share"].as_f64().unwrap_or(0.0);
        assert!(
            share >= 0.8,
            "{id} fixed {share} of cycles beside the dead fleet\n{tail}"
        );
    }
    for id in ["r3", "r4"] {
        let fixes = robots[id]["fixes"].as_u64().unwrap();
        assert!(
            fixes > 20,
            "{id}: {fixes} fixes; its fleet came back\n{tail}"
        );
    }
    let cost = &doc["cost"];
    assert_eq!(
        cost["servers"]["cpus"].as_str().map(expand).unwrap(),
        servers
    );
    assert_eq!(
        cost["simulation"]["cpus"].as_str().map(expand).unwrap(),
        simulation
    );
    assert!(cost["servers"]["cores"].as_f64().unwrap() > 0.0, "{cost}");
    let agent = &cost["agent"];
    assert!((agent["robots_per_process"].as_f64().unwrap() - 5.0 / 3.0).abs() < 1e-9);
    assert!(agent["cpu_ms_per_s"].as_f64().unwrap() > 0.0, "{cost}");
    assert!(agent["peak_rss_mib"].as_f64().unwrap() > 1.0, "{cost}");
}

#[test]
fn grouped_robots_track_under_access_control_with_their_fleets_credential() {
    const RUN_S: u64 = 10;
    let dir = tempfile::tempdir().unwrap();
    let runtime_dir = dir.path().join("run");
    std::fs::create_dir_all(&runtime_dir).unwrap();
    let args = ["--robots", "4", "--robots-per-process", "3", "--secure"];
    let sim = start_sim(dir.path(), &runtime_dir, RUN_S, &args);
    let fleets: Vec<Vec<String>> = children(sim.pid())
        .into_iter()
        .filter(|(_, role, _)| role == "fleet")
        .map(|(_, _, args)| args)
        .collect();
    assert_eq!(fleets.len(), 2);
    for args in &fleets {
        let config = args
            .iter()
            .position(|a| a == "--zenoh-config")
            .map(|i| args[i + 1].clone())
            .unwrap();
        assert!(
            config.ends_with("fleet-r1.json5") || config.ends_with("fleet-r4.json5"),
            "{config}"
        );
    }
    let (log, doc) = finish(sim, RUN_S);
    assert_eq!(doc["secure"], true);
    for (id, r) in robots(&doc) {
        let share = r["fix_share"].as_f64().unwrap_or(0.0);
        assert!(
            share >= 0.8,
            "{id} fixed {share} of cycles\n{}",
            &log[log.len().saturating_sub(3_000)..]
        );
    }
}

#[test]
fn impossible_groupings_are_refused_before_anything_starts() {
    let refused = |args: &[&str], env: Option<(&str, &str)>, says: &str| {
        let mut cmd = Command::new(ICKON);
        cmd.arg("sim").args(args);
        if let Some((k, v)) = env {
            cmd.env(k, v);
        }
        let out = cmd.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    };
    refused(&["--robots-per-process", "0"], None, "from 1 to 1024");
    refused(&["--robots-per-process", "-2"], None, "from 1 to 1024");
    refused(
        &["--robots-per-process", "99999999999"],
        None,
        "from 1 to 1024",
    );
    refused(&["--robots-per-process", "4", "--ros2"], None, "own");
    refused(
        &["--robots-per-process", "2", "--faults", "kill:msu/r1@2s"],
        None,
        "--faults aims at an agent",
    );
    // A launcher held to one CPU cannot split it.
    refused(
        &["--split-cores"],
        Some(("ICKON_CPUS", "0")),
        "splitting needs two or more",
    );
    refused(&[], Some(("ICKON_CPUS", "banana")), "is not a CPU list");
    // The fleet node itself refuses a robot named twice.
    let out = Command::new(ICKON)
        .args(["node", "fleet", "--robots", "r1,r1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("twice"));
}
