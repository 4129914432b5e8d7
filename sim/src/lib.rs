//! # ickon-sim
//!
//! The simulated world that stands in for hardware, and the virtual-time
//! engine that runs the node cores against it (docs/simulation.md; the scoring in docs/architecture.md).
//!
//! - [`profile`]: named noise profiles (`ideal`, `paper`, `harsh`).
//! - [`robot`]: a differential drive following a route by pure pursuit.
//! - [`air`]: the hall's temperature and drafts, and a burst's travel time through them.
//! - [`acoustic`]: sound flight, line of sight, reflections, receiver choice.
//! - [`collision`]: bursts on one carrier channel colliding, reverberation tails masking.
//! - [`sensors`]: gyro, encoders, obstacle rangers.
//! - [`clock`]: device clocks with offset and drift.
//! - [`world`]: one robot's world, producing the messages its MSU receives.
//! - [`engine`]: the discrete-event loop, one MSU core per estimator.
//! - [`fleet`]: the first N robots of a site at once, their poses fed to the central unit.
//! - [`recording`]: a run's arrivals, truth and odometry kept for export.
//! - [`schedule_audit`]: whether a schedule lets every burst through everywhere.
//! - [`score`]: the papers' metrics.
//! - [`tx_faults`]: transmitters dying, growing weak or knocked out of place.
//!
//! The same world as a node of a live mesh, driven by the system clock,
//! is the `ickon-world` crate (`world-node/`).
//!
//! Every random draw comes from a `ChaCha8Rng` stream derived from the run
//! seed and a label ([`rng::stream`]): the same seed gives the same numbers.

pub mod acoustic;
pub mod air;
pub mod air_sensor;
pub mod clock;
pub mod collision;
pub mod control;
pub mod engine;
pub mod fleet;
pub mod profile;
pub mod profile_file;
pub mod recording;
pub mod rng;
pub mod robot;
pub mod schedule_audit;
pub mod score;
pub mod sensors;
pub mod tx_faults;
pub mod world;

pub use engine::{RunConfig, RunError, RunOutput, run};
pub use profile::{NoiseProfile, UnknownProfile};
pub use score::{Row, Score, score};

#[cfg(test)]
mod engine_tests;
