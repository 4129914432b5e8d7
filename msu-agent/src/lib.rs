//! # ickon-msu
//!
//! The mobile sensory unit's software as a sans-IO core: the arrivals of one
//! cycle are assembled against the schedule ([`assembly`]), solved into a fix
//! (TDOA, the ICKON paper, eq. 1-3, with the heading from the first receiver, eq.
//! 4-6), and fed with the robot's odometry, gyro and obstacle ranges into one
//! estimator ([`core::MsuCore`]). Nothing here reads a clock or touches the
//! network: the Zenoh adapter (feature `zenoh`) and the virtual-time engine
//! of `ickon-sim` drive the same core.

pub mod assembly;
pub mod beacons;
#[cfg(feature = "zenoh")]
pub mod board_receivers;
mod config;
pub mod config_file;
pub mod control_timing;
pub mod core;
pub mod cycle_match;
mod driver;
mod error;
pub mod events;
#[cfg(feature = "zenoh")]
pub mod fleet;
pub mod fusion_clock;
pub mod hedgehog;
pub mod host;
#[cfg(feature = "zenoh")]
pub mod marvelmind_receivers;
pub mod motion;
#[cfg(feature = "zenoh")]
pub mod node;
pub mod pose_track;
#[cfg(feature = "zenoh")]
pub mod receiver_input;
#[cfg(feature = "zenoh")]
pub mod receivers;
#[cfg(feature = "zenoh")]
pub mod ros2;
pub mod solver;
pub mod summary;
pub mod time_gate;
mod unused_residuals;

pub use assembly::{AssemblyError, CycleSignals, Signal, assemble};
pub use config::{DEFAULT_MAX_FIX_SIGMA_M, estimator_for_site};
pub use config_file::{MissingStart, MsuConfigError, MsuTuning};
pub use core::{MsuConfig, MsuCore, MsuError};
pub use driver::{Fed, MsuDriver};
pub use events::{Event, InputKind, Output};
pub use host::FusionHost;
pub use solver::{FixSolver, SolvedCycle};

// The ROS 2 decoders it fuzzes live in the Zenoh adapter.
#[cfg(all(test, feature = "zenoh"))]
mod fuzz_core_tests;
