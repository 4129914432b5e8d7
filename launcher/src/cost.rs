//! What a run costs while it is watched: the CPU of the site's servers
//! (router, central unit, cells) and of the simulation (world, agents, the
//! launcher), and what one robot's agent needs, the figure a robot builder
//! sizes a robot's computer by.

use std::fmt::Write;

use serde::Serialize;

use crate::core_split::{CoreSplit, Side};
use crate::usage::{ProcUsage, kind_of};

/// The CPU one side of the run used while it was watched.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SideCost {
    /// The CPUs it was pinned to (`--split-cores`), as a CPU list.
    pub cpus: Option<String>,
    /// Its processes.
    pub processes: usize,
    /// CPU seconds of them all.
    pub cpu_s: f64,
    /// Of one core: CPU seconds per second watched.
    pub cores: f64,
}

/// One robot's agent while the run was watched.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct AgentCost {
    /// Robots per agent process.
    pub robots_per_process: f64,
    /// CPU milliseconds per second of driving, per robot (a grouped
    /// process's CPU shared among its robots).
    pub cpu_ms_per_s: f64,
    /// Peak resident memory per robot, MiB: a lone agent's own (the
    /// largest), or a grouped process's divided among its robots (their
    /// shared runtime and session counted once).
    pub peak_rss_mib: f64,
}

/// The run's cost while watched.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Cost {
    /// Seconds watched.
    pub watched_s: f64,
    /// The router, the central unit and the cells.
    pub servers: SideCost,
    /// The world, the agents and the launcher.
    pub simulation: SideCost,
    /// One robot's agent; `None` with no agent measured.
    pub agent: Option<AgentCost>,
}

impl Cost {
    /// The cost between two readings of every process (`before` when the
    /// run started to be watched, `after` `watched_s` later) for `robots`
    /// robots. A process missing from `before` (restarted) counts from its
    /// start.
    pub fn over_window(
        before: &[(String, ProcUsage)],
        after: &[(String, ProcUsage)],
        watched_s: f64,
        robots: usize,
        split: Option<&CoreSplit>,
    ) -> Self {
        let used = |name: &str, u: &ProcUsage| {
            let start = before
                .iter()
                .find(|(n, _)| n == name)
                .map_or(0.0, |(_, b)| b.cpu_s);
            (u.cpu_s - start).max(0.0)
        };
        let side = |which: Side| {
            let mine: Vec<f64> = after
                .iter()
                .filter(|(n, _)| Side::of_kind(kind_of(n)) == which)
                .map(|(n, u)| used(n, u))
                .collect();
            let cpu_s: f64 = mine.iter().sum();
            SideCost {
                cpus: split.map(|s| s.cpus(which).to_string()),
                processes: mine.len(),
                cpu_s,
                cores: if watched_s > 0.0 {
                    cpu_s / watched_s
                } else {
                    0.0
                },
            }
        };
        let agents: Vec<(&String, &ProcUsage)> = after
            .iter()
            .filter(|(n, _)| matches!(kind_of(n), "msu" | "fleet"))
            .map(|(n, u)| (n, u))
            .collect();
        let agent = (!agents.is_empty() && robots > 0 && watched_s > 0.0).then(|| {
            let cpu_s: f64 = agents.iter().map(|(n, u)| used(n, u)).sum();
            let per_process = robots as f64 / agents.len() as f64;
            let rss_mib = agents
                .iter()
                .map(|(_, u)| u.peak_rss_bytes as f64 / (1024.0 * 1024.0))
                .fold(0.0, f64::max);
            AgentCost {
                robots_per_process: per_process,
                cpu_ms_per_s: cpu_s / robots as f64 / watched_s * 1e3,
                peak_rss_mib: rss_mib / per_process.max(1.0),
            }
        });
        Self {
            watched_s,
            servers: side(Side::Servers),
            simulation: side(Side::Simulation),
            agent,
        }
    }

    /// Two lines of the report.
    pub fn render(&self) -> String {
        let mut out = String::new();
        let pinned = |s: &SideCost| {
            s.cpus
                .as_ref()
                .map_or(String::new(), |c| format!(" on CPUs {c}"))
        };
        let _ = writeln!(
            out,
            "CPU while watched: servers {:.2} cores ({} processes{}), simulation {:.2} cores ({} processes{})",
            self.servers.cores,
            self.servers.processes,
            pinned(&self.servers),
            self.simulation.cores,
            self.simulation.processes,
            pinned(&self.simulation),
        );
        if let Some(a) = &self.agent {
            let _ = writeln!(
                out,
                "one robot's agent: {:.1} ms CPU per second, {:.1} MiB peak memory ({:.1} robots per process)",
                a.cpu_ms_per_s, a.peak_rss_mib, a.robots_per_process
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn u(cpu_s: f64, mib: u64) -> ProcUsage {
        ProcUsage {
            cpu_s,
            peak_rss_bytes: mib * 1024 * 1024,
        }
    }

    fn named(list: &[(&str, ProcUsage)]) -> Vec<(String, ProcUsage)> {
        list.iter().map(|(n, u)| (n.to_string(), *u)).collect()
    }

    #[test]
    fn sides_and_agents_over_the_watched_window() {
        let before = named(&[
            ("router", u(1.0, 10)),
            ("central", u(2.0, 20)),
            ("cell c1", u(0.5, 5)),
            ("world", u(3.0, 30)),
            ("fleet r1..r4", u(4.0, 60)),
            ("launcher", u(1.0, 40)),
        ]);
        let after = named(&[
            ("router", u(3.0, 10)),
            ("central", u(4.0, 20)),
            ("cell c1", u(1.5, 5)),
            ("world", u(5.0, 30)),
            ("fleet r1..r4", u(12.0, 80)),
            // Restarted: all of it counts.
            ("fleet r5..r8", u(8.0, 80)),
            ("launcher", u(2.0, 40)),
        ]);
        let c = Cost::over_window(&before, &after, 10.0, 8, None);
        assert_eq!(c.servers.processes, 3);
        assert!((c.servers.cpu_s - 5.0).abs() < 1e-9);
        assert!((c.servers.cores - 0.5).abs() < 1e-9);
        assert_eq!(c.simulation.processes, 4);
        assert!((c.simulation.cpu_s - 19.0).abs() < 1e-9);
        assert_eq!(c.servers.cpus, None);
        let a = c.agent.clone().unwrap();
        assert!((a.robots_per_process - 4.0).abs() < 1e-9);
        // 16 CPU s over 8 robots and 10 s.
        assert!((a.cpu_ms_per_s - 200.0).abs() < 1e-9);
        assert!((a.peak_rss_mib - 20.0).abs() < 1e-9);
        let text = c.render();
        assert!(text.contains("servers 0.50 cores (3 processes)"), "{text}");
        assert!(text.contains("200.0 ms CPU per second"), "{text}");
    }

    #[test]
    fn lone_agents_and_a_split_machine() {
        let split = CoreSplit {
            servers: ickon_runtime::cpus::Cpus::parse("0").unwrap(),
            simulation: ickon_runtime::cpus::Cpus::parse("1").unwrap(),
        };
        let after = named(&[
            ("msu r1", u(2.0, 30)),
            ("msu r2", u(4.0, 35)),
            ("router", u(1.0, 9)),
        ]);
        let c = Cost::over_window(&[], &after, 2.0, 2, Some(&split));
        let a = c.agent.clone().unwrap();
        assert!((a.cpu_ms_per_s - 1500.0).abs() < 1e-9);
        assert!((a.peak_rss_mib - 35.0).abs() < 1e-9);
        assert_eq!(c.servers.cpus.as_deref(), Some("0"));
        assert!(c.render().contains("on CPUs 1"));
        // Nothing watched, no agent: no division by zero.
        let empty = Cost::over_window(&[], &named(&[("router", u(1.0, 9))]), 0.0, 0, None);
        assert_eq!(empty.agent, None);
        assert_eq!(empty.servers.cores, 0.0);
    }
}
