//! `tdoa-ekf`: a tightly-coupled extended Kalman filter that fuses each
//! time difference of arrival on its own, as a scalar range-difference
//! update (the approach of the Crazyflie's LPS TDoA, docs/architecture.md), so
//! that it needs no complete set of signals for a fix.
//!
//! Every measurement goes through, cheapest first:
//! 1. the physical check: `|d|` cannot exceed the distance between its two
//!    transmitters ([`Rejection::Physical`]);
//! 2. the innovation (Mahalanobis) gate ([`Rejection::Gate`]);
//! 3. the scalar Joseph-form update.
//!
//! When most recent measurements fail the gate the filter counts as lost
//! and widens its position variance ([`RecoveryParams`]), so that a filter
//! pushed off by a burst of outliers (or left alone through a gap) comes
//! back instead of refusing every good measurement for ever.
//!
//! Two state and motion models, chosen per use:
//! - [`TdoaEkf3d`]: 3D constant velocity for a free-flying tag, a plain
//!   struct driven directly (`predict_to`, `update_range_difference`);
//!   `ickon replay util` runs it as the plain baseline beside the guarded
//!   filters of [`crate::estimator::flight`];
//! - [`TdoaEkf`]: a ground robot's `(x, y, theta)` predicted by encoders or
//!   odometry and the gyro, behind the [`crate::estimator::Estimator`]
//!   trait, registered as `tdoa-ekf`, fed with
//!   [`crate::estimator::Input::RangeDifference`].
//!
//! Measurements are range differences in metres
//! ([`crate::estimator::RangeDifferenceSample`], B minus A); time
//! differences are converted at the propagation speed, a parameter (speed
//! of sound for ultrasound, of light for radio).

mod clock_slots;
mod cv3d;
mod ground;
mod ground_chain;
mod ground_noise;
mod ground_state;
#[cfg(test)]
mod ground_tests;
mod observation;
mod recovery;
mod standstill;
mod systematic;
#[cfg(test)]
mod tests;

pub use cv3d::{TdoaEkf3d, TdoaEkf3dParams};
pub use ground::{Floor, Reinitialisation, TdoaEkf, TdoaEkfParams};
pub use ground_noise::GroundNoise;
pub use observation::{Outcome, Rejection};
pub(crate) use observation::{check, gated_update};
pub use recovery::RecoveryParams;
