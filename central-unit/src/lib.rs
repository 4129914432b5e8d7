//! # ickon-central
//!
//! The central unit of ICKON (seed 000 section 3.1.1, "CentCU"): it holds the
//! site model, computes the emission schedule ([`schedule`]), triggers every
//! cycle and is the time master of the cell controllers, and tracks the health
//! of cells and robots ([`core`]). The core is a sans-IO state machine; the
//! Zenoh node (feature `zenoh`) only moves its inputs and outputs.

pub mod core;
#[cfg(feature = "zenoh")]
pub mod node;
pub mod schedule;

pub use schedule::{ScheduleError, compute_schedule, update_rate_hz};
