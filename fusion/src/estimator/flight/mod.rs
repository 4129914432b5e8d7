//! Filters for a receiver flying in 3D, meant to run under the watch of
//! [`crate::estimator::guard::Guarded`]:
//! - [`CvFilter`]: constant velocity, TDOA only;
//! - [`ImuFilter`]: the IMU error-state filter, TDOA corrections.
//!
//! Both model the body shadow `s` (the extra path of a signal crossing the
//! body from a transmitter below the antenna, see `shadow.rs`): held at a
//! value known before the flight (from the body's geometry), or estimated
//! online from a prior (weakly observable: it looks like a height error).
//! Both may also carry each anchor's excess path as a state (`excess.rs`):
//! the errors of range differences come in runs, not as white noise.

mod cv;
mod excess;
#[cfg(test)]
mod excess_tests;
mod imu;
mod imu_params;
#[cfg(test)]
mod imu_robustness_tests;
mod shadow;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod vertical_tests;

pub use cv::{CvFilter, CvParams};
pub use excess::{EXCESS_SLOTS, ExcessParams};
pub use imu::{ImuFilter, ImuSample};
pub use imu_params::ImuParams;
