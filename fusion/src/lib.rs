//! # ickon-fusion
//!
//! The positioning math of ICKON-rs as a pure library: no I/O, no async, no
//! clock reads. Every function that depends on time takes the time or the step.
//!
//! Conventions: SI units inside (metres, seconds, radians); angles are wrapped
//! to `(-pi, pi]` with [`angle::wrap_pi`] wherever they are compared.

pub mod angle;
pub mod estimator;
pub mod ranging;
pub mod tdoa;
