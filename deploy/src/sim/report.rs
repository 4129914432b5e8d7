//! What `ickon sim` prints: the live status line and the final report.

use std::time::{Duration, Instant};

use super::SimReport;
use super::metrics::RunStats;

pub(super) fn status_line(
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

pub(super) fn render_report(r: &SimReport) -> String {
    use std::fmt::Write;
    let mm = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    let us = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0}"));
    let mut out = String::new();
    let _ = writeln!(
        out,
        "ickon sim: site {}, estimator {}, profile {}, seed {}, {:.0} s, {:.2} cycles/s",
        r.site, r.estimator, r.profile, r.seed, r.duration_s, r.update_rate_hz
    );
    let _ = writeln!(
        out,
        "{:<6} {:>6} {:>6} {:>8} {:>8} {:>8} {:>12} {:>12} {:>14}",
        "robot",
        "fixes",
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
            "{:<6} {:>6} {:>6} {:>8} {:>8} {:>8} {:>12} {:>12} {:>14}",
            x.id,
            x.fixes,
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
