//! # ickon-cell
//!
//! The cell controller of ICKON (the ICKON paper, section 3.1.1, "CCU"): it keeps its
//! clock synchronised with the central unit ([`sync`]) and fires its
//! transmitters at `cycle start + offset` on the master time base
//! ([`timer`]), taking only the triggers [`trigger_gate`] admits. [`core`] is the whole controller as a sans-IO state
//! machine; the Zenoh node (feature `zenoh`) and the virtual-time engine
//! drive it, and [`driver`] reaches the transmitters (the simulated ones, or
//! a transmitter board of the device protocol: `device`, feature `zenoh`).

pub mod core;
#[cfg(feature = "zenoh")]
pub mod device;
pub mod driver;
#[cfg(test)]
mod fixtures;
#[cfg(feature = "zenoh")]
pub mod node;
pub mod sync;
pub mod timer;
pub mod trigger_gate;

pub use crate::core::{CellConfig, CellCore, CellCounters, Event, Output};
pub use driver::{DriverError, SimulatedDriver, TransmitterDriver};

#[cfg(test)]
mod fuzz_core_tests;
