//! The table of `ickon bench scale`: one row per fleet size, then the CPU
//! and memory of each kind of process, what each router carried, then
//! each side's CPU and one robot's agent while watched.

use std::fmt::Write;

use crate::report::SimReport;

/// The smallest of some values, `None` when there are none.
fn min(values: impl Iterator<Item = f64>) -> Option<f64> {
    values.reduce(f64::min)
}

/// The largest of some values, `None` when there are none.
fn max(values: impl Iterator<Item = f64>) -> Option<f64> {
    values.reduce(f64::max)
}

/// The mean of some values, `None` when there are none.
fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = values.collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn show(v: Option<f64>, scale: f64, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{:.*}", digits, v * scale))
}

/// The summary rows of each size and the per-process table.
pub fn render(reports: &[&SimReport]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "robots  cycles/s  cells fired min %  sync p99 / max us  arrivals min %  fix min / mean %  pose lat p50 / p99 ms  hop p50 / p99 ms  mean err mm"
    );
    for r in reports {
        let cells_min = min(r.cells.iter().filter_map(|c| c.fired_share));
        let sync_p99 = max(r.cells.iter().filter_map(|c| c.sync_error_us));
        let sync_max = max(r.cells.iter().filter_map(|c| c.sync_error_max_us));
        let arrivals_min = min(r.robots.iter().filter_map(|x| x.arrivals_share));
        let fix_min = min(r.robots.iter().filter_map(|x| x.fix_share));
        let fix_mean = mean(r.robots.iter().filter_map(|x| x.fix_share));
        // Per robot percentiles: the median robot's p50, the worst robot's p99.
        let mut p50s: Vec<f64> = r.robots.iter().filter_map(|x| x.latency_p50_us).collect();
        p50s.sort_by(f64::total_cmp);
        let lat_p50 = p50s.get(p50s.len() / 2).copied();
        let lat_p99 = max(r.robots.iter().filter_map(|x| x.latency_p99_us));
        let err = mean(r.robots.iter().filter_map(|x| x.mean_mm));
        let _ = writeln!(
            out,
            "{:>6}  {:>8.2}  {:>17}  {:>17}  {:>14}  {:>16}  {:>21}  {:>16}  {:>11}",
            r.robots.len(),
            r.cycles_per_s,
            show(cells_min, 100.0, 1),
            format!("{} / {}", show(sync_p99, 1.0, 0), show(sync_max, 1.0, 0)),
            show(arrivals_min, 100.0, 1),
            format!("{} / {}", show(fix_min, 100.0, 1), show(fix_mean, 100.0, 1)),
            format!("{} / {}", show(lat_p50, 1e-3, 1), show(lat_p99, 1e-3, 1)),
            format!(
                "{} / {}",
                show(r.zenoh_hop_p50_us, 1e-3, 2),
                show(r.zenoh_hop_p99_us, 1e-3, 2)
            ),
            show(err, 1.0, 1),
        );
    }
    let _ = writeln!(
        out,
        "\nCPU seconds (all processes of the kind / the busiest one) and peak memory (MiB, largest process)"
    );
    for r in reports {
        let kinds: Vec<String> = r
            .processes
            .iter()
            .map(|k| {
                format!(
                    "{} x{}: {:.1} / {:.1} s, {:.0} MiB",
                    k.kind, k.processes, k.cpu_s, k.cpu_max_s, k.peak_rss_max_mib
                )
            })
            .collect();
        let _ = writeln!(out, "{:>6}  {}", r.robots.len(), kinds.join("; "));
    }
    if reports.iter().any(|r| !r.routers.is_empty()) {
        let _ = writeln!(
            out,
            "\nEach router: its zone's cells and robots, CPU seconds, peak memory"
        );
        for r in reports {
            for router in &r.routers {
                let _ = writeln!(out, "{:>6}  {}", r.robots.len(), router.render());
            }
        }
    }
    let _ = writeln!(
        out,
        "\nWhile watched: the servers' and the simulation's CPU (cores), one robot's agent (CPU ms per s, peak MiB)"
    );
    for r in reports {
        let c = &r.cost;
        let agent = c.agent.as_ref().map_or("-".to_string(), |a| {
            format!(
                "{:.1} ms/s, {:.1} MiB ({:.0} per process)",
                a.cpu_ms_per_s, a.peak_rss_mib, a.robots_per_process
            )
        });
        let cpus = |s: &crate::cost::SideCost| {
            s.cpus
                .as_ref()
                .map_or(String::new(), |c| format!(" on {c}"))
        };
        let _ = writeln!(
            out,
            "{:>6}  servers {:.2}{}, simulation {:.2}{}, agent {agent}",
            r.robots.len(),
            c.servers.cores,
            cpus(&c.servers),
            c.simulation.cores,
            cpus(&c.simulation),
        );
    }
    out
}
