//! What each router of a run carried: its zone, its clients, and the CPU
//! time and peak memory of its process.
//!
//! Not the messages or bytes through it: Zenoh counts them per link only
//! when built with its `stats` feature, which this build leaves out (a
//! counter update on every message of every node), and the kernel's
//! per-process write counters (`/proc/<pid>/io`) miss what a socket sends
//! with `send(2)`, which is how Zenoh's links send.

use serde::Serialize;

use crate::args::Mesh;
use crate::usage::ProcUsage;
use crate::zones::ZonedMesh;

/// The load of one router of a run.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RouterLoad {
    /// The router's process name (`router`, or `router z2` with zones).
    pub name: String,
    /// Its zone (`z1` ...).
    pub zone: String,
    /// Whether it is the hub: the router the others link to, where the
    /// central unit, the world and the launcher connect.
    pub hub: bool,
    /// Where it listened.
    pub endpoint: String,
    /// The cells of its zone, its clients.
    pub cells: Vec<String>,
    /// The robots whose agents were its clients.
    pub robots: Vec<String>,
    /// CPU seconds (user plus system) it used, from its start; `None` when
    /// it could not be read (it had died).
    pub cpu_s: Option<f64>,
    /// Its peak resident memory, MiB.
    pub peak_rss_mib: Option<f64>,
}

impl RouterLoad {
    /// The load of each router of a run, in zone order, from the usage of
    /// its processes (`used`, by process name); none in a full mesh of peers.
    pub fn of_run(mesh: Mesh, zoned: &ZonedMesh, used: &[(String, ProcUsage)]) -> Vec<Self> {
        if mesh != Mesh::Router {
            return Vec::new();
        }
        const MIB: f64 = 1024.0 * 1024.0;
        zoned
            .zones()
            .iter()
            .zip(zoned.listeners())
            .enumerate()
            .map(|(k, (zone, (endpoint, _)))| {
                let name = zoned.router_name(k);
                let usage = used.iter().find(|(n, _)| *n == name).map(|(_, u)| u);
                RouterLoad {
                    zone: zone.name.clone(),
                    hub: k == 0,
                    endpoint: endpoint.clone(),
                    cells: zone.cells.clone(),
                    robots: zone.robots.clone(),
                    cpu_s: usage.map(|u| u.cpu_s),
                    peak_rss_mib: usage.map(|u| u.peak_rss_bytes as f64 / MIB),
                    name,
                }
            })
            .collect()
    }

    /// One line of the report: `router z2 (cells c3 c4, 1 robot): CPU 1.2 s, peak memory 20.0 MiB`.
    pub fn render(&self) -> String {
        let robots = match self.robots.len() {
            1 => "1 robot".to_string(),
            n => format!("{n} robots"),
        };
        let hub = if self.hub { ", hub" } else { "" };
        let show =
            |v: Option<f64>, unit: &str| v.map_or("-".to_string(), |v| format!("{v:.1} {unit}"));
        format!(
            "{} (cells {}, {robots}{hub}): CPU {}, peak memory {}",
            self.name,
            self.cells.join(" "),
            show(self.cpu_s, "s"),
            show(self.peak_rss_mib, "MiB"),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zones::split;

    #[test]
    fn each_router_gets_its_own_process_usage() {
        let site = ickon_proto::site::Site::load_or_default(None).unwrap().0;
        let robots: Vec<String> = site.robots.iter().map(|r| r.id.clone()).collect();
        let zones = split(&site, &robots, 2).unwrap();
        let listeners = vec![
            ("tcp/127.0.0.1:1".to_string(), 1),
            ("tcp/127.0.0.1:2".to_string(), 2),
        ];
        let zoned = ZonedMesh::new(zones, listeners).unwrap();
        let used = vec![
            (
                "router z1".to_string(),
                ProcUsage {
                    cpu_s: 2.0,
                    peak_rss_bytes: 8 << 20,
                },
            ),
            ("cell c1".to_string(), ProcUsage::default()),
        ];
        let loads = RouterLoad::of_run(Mesh::Router, &zoned, &used);
        assert_eq!(loads.len(), 2);
        assert_eq!(loads[0].name, "router z1");
        assert!(loads[0].hub && !loads[1].hub);
        assert_eq!(loads[0].cpu_s, Some(2.0));
        assert_eq!(loads[0].peak_rss_mib, Some(8.0));
        assert_eq!(loads[0].cells, ["c1", "c2"]);
        // Router z2 had died: nothing measured, still listed.
        assert_eq!(loads[1].name, "router z2");
        assert_eq!(loads[1].cpu_s, None);
        let line = loads[1].render();
        assert!(line.starts_with("router z2 (cells c3 c4"), "{line}");
        assert!(line.contains("CPU -"), "{line}");
        assert!(loads[0].render().contains("CPU 2.0 s, peak memory 8.0 MiB"));
        assert!(RouterLoad::of_run(Mesh::Peer, &zoned, &used).is_empty());
    }
}
