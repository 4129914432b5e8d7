//! # ickon-central
//!
//! The central unit of ICKON (the ICKON paper, section 3.1.1, "CentCU"): it holds the
//! site model, computes the emission schedule ([`schedule`]), triggers every
//! cycle and is the time master of the cell controllers, tracks the health
//! of cells and robots ([`health`]), and evaluates the coverage of the floor
//! ([`coverage`]). The core ([`core`]) is a sans-IO state machine; the Zenoh
//! node (feature `zenoh`) only moves its inputs and outputs, and with
//! `--http` serves the live web map and JSON API (`http`) beside it. The
//! admin answers' JSON documents ([`admin_json`]) are shared by the web map
//! and `ickon admin --json`.
//!
//! Dependencies: besides `proto` and `runtime` this crate uses
//! `ickon-fusion` (docs/architecture.md, "Crates"): the HDOP
//! of the coverage grid is the same dilution of precision the MSU's TDOA
//! solver works with ([`ickon_fusion::tdoa::dop`]), and `fusion` is pure math
//! with no I/O, so the core stays sans-IO.

pub mod admin_json;
pub mod air_temperature;
mod audibility;
pub mod core;
pub mod coverage;
#[cfg(feature = "zenoh")]
pub mod foxglove;
pub mod health;
#[cfg(feature = "zenoh")]
pub mod http;
pub mod learnt_speed;
#[cfg(feature = "zenoh")]
pub mod node;
pub mod occupancy;
pub mod point_index;
pub mod robot_pages;
pub mod router_links;
pub mod schedule;
pub mod selection;
pub mod spacing;
pub mod summary_gate;
pub mod survey_calibration;
pub mod transmitter_health;
pub mod velocity;

pub use schedule::{ScheduleError, compute_schedule, update_rate_hz};

#[cfg(test)]
mod fuzz_core_tests;
