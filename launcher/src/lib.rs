//! `ickon sim`: the whole system as separate OS processes over a loopback
//! Zenoh mesh, started with one command and ended with Ctrl-C (or at
//! the end of `--duration`).
//!
//! The launcher spawns itself as `ickon node <role>` for the central unit, one
//! cell controller per cell, the world, and one MSU agent per robot: the same
//! library code as the standalone `ickon-central`, `ickon-cell`, `ickon-world`
//! and `ickon-msu` binaries, so that `cargo run -p ickon -- sim` needs no other
//! build step. As on a site, a Zenoh router (`ickon router`, its own
//! supervised process) listens on a loopback port and every node is its
//! client (`--mesh peer` lays out the old full mesh of peers instead, to
//! compare; `--routers N` one router per zone of the site, linked to the
//! first, each cell and robot a client of its zone's); multicast scouting is off so that two runs on one machine never
//! meet, and Zenoh's thread pools are kept small in every node. The launcher watches the mesh with its own
//! session (liveliness, bursts, arrivals, fixes, poses, truth), prints a live
//! status line, and a summary at the end.
//!
//! `ickon bench scale` runs the same mesh at several fleet sizes
//! ([`BenchCommand`]); `ickon bench central` runs the site's servers
//! against a synthetic fleet standing in for many robots' agents
//! (`ickon node synthetic-fleet`, of the `ickon-world` crate).

mod args;
mod bench;
mod core_split;
mod cost;
mod device_plan;
mod error;
mod faults;
mod fleet_site;
mod launch;
mod metrics;
mod msu_file;
mod nodes;
mod observe;
mod ports;
mod report;
mod router_load;
mod run;
mod secure;
mod supervisor;
mod usage;
mod zones;

pub use args::Mesh;
pub use args::SimArgs;
pub use bench::{BenchCommand, run as run_bench};
pub use metrics::{CellSummary, RobotSummary};
pub use report::SimReport;
pub use run::run as run_sim;
