//! What `ickon sim` reports: the live status line, and the report at the
//! end (a table, or one JSON document with `--json`).

use std::time::{Duration, Instant};

use serde::Serialize;

use ickon_proto::site::Site;

use crate::args::Mesh;
use crate::args::SimArgs;
use crate::metrics::{self, CellSummary, RobotSummary, RunStats};
use crate::router_load::RouterLoad;
use crate::usage;

/// The JSON document of `ickon sim --json`.
#[derive(Debug, Serialize)]
pub struct SimReport {
    /// The site's name.
    pub site: String,
    /// The noise profile of the world.
    pub profile: String,
    /// The estimator every agent ran.
    pub estimator: String,
    /// The seed of every random draw.
    pub seed: u64,
    /// Whether odometry and gyro went over ROS 2 (`--ros2`).
    pub ros2: bool,
    /// How long the run was watched, seconds.
    pub duration_s: f64,
    /// Cycles per second of the schedule with every cell up: the fixes each
    /// robot can get per second at most.
    pub update_rate_hz: f64,
    /// How the nodes reached each other.
    pub mesh: Mesh,
    /// Whether the router enforced access control (`--secure`).
    pub secure: bool,
    /// The endpoint every node connected to: the router's (the central
    /// unit's with `--mesh peer`); it tells this run's processes apart.
    pub central_endpoint: String,
    /// Median one-hop Zenoh latency, microseconds.
    pub zenoh_hop_p50_us: Option<f64>,
    /// 99th percentile of the one-hop Zenoh latency, microseconds.
    pub zenoh_hop_p99_us: Option<f64>,
    /// Each robot's fixes, poses, errors and latencies.
    pub robots: Vec<RobotSummary>,
    /// Each cell's cycles fired and missed, and its sync error.
    pub cells: Vec<CellSummary>,
    /// Messages the observer could not decode.
    pub bad_messages: u64,
    /// Cycles the central unit triggered while the run was watched.
    pub cycles_triggered: u64,
    /// Of those, per second of the run.
    pub cycles_per_s: f64,
    /// What the cycles whose trigger named its transmitters fired (the
    /// firing plan; absent when every cycle fired the whole schedule).
    pub firing_plan: Option<metrics::PlanSummary>,
    /// CPU time and peak memory per kind of process, read just before they stopped.
    pub processes: Vec<usage::KindUsage>,
    /// While the run was watched: the CPU of the site's servers and of the
    /// simulation, and what one robot's agent needs.
    pub cost: crate::cost::Cost,
    /// Each router (one per zone with `--routers N`): its zone's cells and
    /// robots, CPU time and peak memory; none with `--mesh peer`.
    pub routers: Vec<RouterLoad>,
    /// The recording of `--record`: file, messages per topic, rates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recorded: Option<ickon_recording::RecordReport>,
    /// Faults injected (`--faults`) and when, seconds from the start.
    pub faults_done: Vec<(String, f64)>,
    /// Nodes restarted after they died (`--restart`).
    pub restarts: Vec<String>,
}

pub(crate) fn status_line(
    stats: &RunStats,
    last_burst: &std::collections::HashMap<String, Instant>,
    cells: usize,
    started: Instant,
) -> String {
    let firing = last_burst
        .values()
        .filter(|t| t.elapsed() < Duration::from_secs(2))
        .count();
    let robots: Vec<String> = stats
        .robots
        .iter()
        .map(|(id, r)| {
            let err = r
                .current_error_m
                .map(|e| format!("{:>4.0} mm", e * 1e3))
                .unwrap_or_else(|| "   - mm".into());
            format!("{id} {:>4.1} fix/s {err}", r.fixes_per_s())
        })
        .collect();
    // Under occupancy firing a trigger names its transmitters.
    let set = stats
        .last_firing
        .map_or("all tx".to_string(), |n| format!("{n} tx"));
    format!(
        "[{:>5.0} s] {} | cells firing {firing}/{cells}, {:.1} cycles/s, {set}   ",
        started.elapsed().as_secs_f64(),
        robots.join(" | "),
        stats.cycles_per_s()
    )
}

/// What the report takes from the run beside the observer's statistics.
pub(crate) struct RunFacts {
    /// Cycles per second of the schedule with every cell up.
    pub update_rate_hz: f64,
    /// Whether the router enforced access control.
    pub secure: bool,
    /// The endpoint every node connected to.
    pub central_endpoint: String,
    /// CPU time and peak memory per kind of process.
    pub processes: Vec<usage::KindUsage>,
    /// The servers' and the simulation's CPU while watched, and one robot's agent.
    pub cost: crate::cost::Cost,
    /// What each router carried.
    pub routers: Vec<RouterLoad>,
    /// The recording of `--record`, if it succeeded.
    pub recorded: Option<ickon_recording::RecordReport>,
}

impl SimReport {
    /// The report of a run from what the observer counted and `facts`.
    pub(crate) fn assemble(
        args: &SimArgs,
        site: &Site,
        robots: &[String],
        stats: &RunStats,
        facts: RunFacts,
    ) -> Self {
        let completed = metrics::completed_cycles(&stats.cycles_triggered);
        SimReport {
            site: site.name.clone(),
            profile: args.profile.clone(),
            estimator: args.estimator.clone(),
            seed: args.seed,
            ros2: args.ros2,
            duration_s: args.duration,
            update_rate_hz: facts.update_rate_hz,
            mesh: args.mesh,
            secure: facts.secure,
            central_endpoint: facts.central_endpoint,
            zenoh_hop_p50_us: metrics::percentile(&stats.hop_latencies_us, 50.0),
            zenoh_hop_p99_us: metrics::percentile(&stats.hop_latencies_us, 99.0),
            robots: robots
                .iter()
                .map(|r| {
                    stats
                        .robots
                        .get(r)
                        .map(|s| s.summary(r, completed.len(), args.duration))
                        .unwrap_or_else(|| {
                            metrics::RobotStats::default().summary(
                                r,
                                completed.len(),
                                args.duration,
                            )
                        })
                })
                .collect(),
            cells: site
                .cells
                .iter()
                .map(|c| {
                    let due = stats.cycles_for_cell(&c.id, &completed);
                    stats
                        .cells
                        .get(&c.id)
                        .map(|s| s.summary(&c.id, &due))
                        .unwrap_or_else(|| metrics::CellStats::default().summary(&c.id, &due))
                })
                .collect(),
            bad_messages: stats.bad_messages.values().sum(),
            cycles_triggered: stats.cycles_triggered.len() as u64,
            cycles_per_s: stats.cycles_triggered.len() as f64 / args.duration,
            firing_plan: stats.plan_summary(),
            processes: facts.processes,
            cost: facts.cost,
            routers: facts.routers,
            recorded: facts.recorded,
            faults_done: stats.faults_done.clone(),
            restarts: stats.restarts.clone(),
        }
    }
}

/// The report's first line: the run, and its cycle rate as measured
/// beside the schedule's nominal one (a cycle under occupancy firing fires
/// part of the schedule, and is shorter).
fn summary_line(r: &SimReport) -> String {
    format!(
        "ickon sim: site {}, estimator {}, profile {}, seed {}, {:.0} s, {} cycles triggered, {:.2} cycles/s \
         (nominal {:.2} cycles/s when a cycle fires the whole schedule)",
        r.site,
        r.estimator,
        r.profile,
        r.seed,
        r.duration_s,
        r.cycles_triggered,
        r.cycles_per_s,
        r.update_rate_hz
    )
}

pub(crate) fn render_report(r: &SimReport) -> String {
    use std::fmt::Write;
    let mm = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    let us = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0}"));
    let mut out = String::new();
    let _ = writeln!(out, "{}", summary_line(r));
    if let Some(p) = &r.firing_plan {
        let _ = writeln!(
            out,
            "firing plan: {:.1} transmitters per cycle in {:.1} slots of {:.1} ms",
            p.transmitters_per_cycle, p.slots_per_cycle, p.mean_slot_ms
        );
    }
    let _ = writeln!(
        out,
        "{:<6} {:>6} {:>7} {:>8} {:>6} {:>6} {:>8} {:>8} {:>8} {:>12} {:>12} {:>14}",
        "robot",
        "fixes",
        "fixes/s",
        "signals",
        "hdop",
        "poses",
        "mean mm",
        "rmse mm",
        "p95 mm",
        "lat p50 us",
        "lat p99 us",
        "max fix gap s"
    );
    for x in &r.robots {
        let _ = writeln!(
            out,
            "{:<6} {:>6} {:>7} {:>8} {:>6} {:>6} {:>8} {:>8} {:>8} {:>12} {:>12} {:>14}",
            x.id,
            x.fixes,
            x.fixes_per_s.map_or("-".to_string(), |v| format!("{v:.2}")),
            x.signals_per_fix
                .map_or("-".to_string(), |v| format!("{v:.1}")),
            x.fix_hdop.map_or("-".to_string(), |v| format!("{v:.2}")),
            x.poses,
            mm(x.mean_mm),
            mm(x.rmse_mm),
            mm(x.p95_mm),
            us(x.latency_p50_us),
            us(x.latency_p99_us),
            x.longest_fix_gap_s
                .map_or("-".to_string(), |g| format!("{g:.2}"))
        );
    }
    if r.robots.iter().any(|x| x.kit_positions > 0) {
        let _ = writeln!(
            out,
            "{:<6} {:>9} {:>8} {:>8} {:>8}   (the ranging kit's own positions)",
            "kit", "positions", "mean mm", "rmse mm", "p95 mm"
        );
        for x in &r.robots {
            let _ = writeln!(
                out,
                "{:<6} {:>9} {:>8} {:>8} {:>8}",
                x.id,
                x.kit_positions,
                mm(x.kit_mean_mm),
                mm(x.kit_rmse_mm),
                mm(x.kit_p95_mm)
            );
        }
    }
    for x in &r.robots {
        if let (Some(pct), Some(n)) = (x.inside_95_pct, x.nees) {
            let _ = writeln!(
                out,
                "{}: truth inside the 95 % ellipse on {pct:.0} % of poses, NEES {:.2} (95 % bounds {:.2}-{:.2} for {} poses{})",
                x.id,
                n.mean,
                n.low,
                n.high,
                n.samples,
                if n.consistent() { "" } else { ": inconsistent" }
            );
        }
    }
    for x in r.robots.iter().filter(|x| x.localising_poses > 0) {
        let _ = writeln!(
            out,
            "{}: {} poses published as localising (no fix had confirmed them), not scored",
            x.id, x.localising_poses
        );
    }
    let _ = writeln!(
        out,
        "zenoh one-hop latency: p50 {} us, p99 {} us",
        us(r.zenoh_hop_p50_us),
        us(r.zenoh_hop_p99_us)
    );
    let _ = writeln!(
        out,
        "{:<6} {:>12} {:>7} {:>8} {:>16} {:>16}",
        "cell", "cycles fired", "missed", "bursts", "sync err p99 us", "sync err max us"
    );
    for c in &r.cells {
        let _ = writeln!(
            out,
            "{:<6} {:>12} {:>7} {:>8} {:>16} {:>16}",
            c.id,
            c.cycles_fired,
            c.cycles_missed,
            c.bursts,
            us(c.sync_error_us),
            us(c.sync_error_max_us)
        );
    }
    out.push_str(&r.cost.render());
    for router in &r.routers {
        let _ = writeln!(out, "{}", router.render());
    }
    if r.bad_messages > 0 {
        let _ = writeln!(out, "undecodable messages: {}", r.bad_messages);
    }
    for (fault, at_s) in &r.faults_done {
        let _ = writeln!(out, "fault {fault} injected at {at_s:.1} s");
    }
    if !r.restarts.is_empty() {
        let _ = writeln!(out, "restarted: {}", r.restarts.join(", "));
    }
    out
}
