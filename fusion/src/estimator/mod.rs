//! Pose estimators: the papers' fusion pipelines behind one trait.
//!
//! Every estimator consumes timestamped [`Input`]s (odometry poses, encoder
//! ticks, gyro rates, MSU fixes, obstacle ranges, range differences) and answers the current
//! [`PoseEstimate`] (`x, y, theta` with a 3x3 covariance). Nothing here reads
//! a clock: time is the `t_s` carried by each input.
//!
//! | name | source | module |
//! |---|---|---|
//! | `odometry` | baseline: relative positioning alone | [`odometry`] |
//! | `msu-raw` | baseline: the MSU fixes alone, held | [`msu_raw`] |
//! | `ickon-akf` | the ICKON paper, s3.2, eq. 7-19 | [`ickon_akf`] |
//! | `gyro-ckf` | the iGPS paper, s7-10, eq. 1, 3-11 | [`gyro_ckf`] |
//! | `cda` | the CDA paper, s3-4, eq. 1-18 | [`cda`] |
//! | `cda-msu` | the CDA paper's heading chain + the ICKON paper's position AKF | [`cda_msu`] |
//! | `tdoa-ekf` | ours: each range difference fused on its own | [`tdoa_ekf`] |
//!
//! Build one by name with [`build_by_name`], or from an [`EstimatorConfig`]
//! (serde, tagged by `name`) with [`build`].
//!
//! # Late and out-of-order inputs
//! All estimators share one policy, implemented once in [`replay`]: each
//! keeps the inputs of the last `history_s` seconds (default 2 s) together
//! with its state before each of them. An input older than the newest one is
//! inserted at its own time: the state is rolled back to just before it and
//! the later inputs are replayed. So a late MSU fix (or late heading) is
//! applied against the pose and heading of its measurement time, and its
//! effect is carried forward exactly. An input older than the retained
//! history is rejected with [`EstimatorError::TooLate`] and leaves the state
//! untouched.
//!
//! # Bad numbers
//! A non-finite field is rejected with [`EstimatorError::NonFinite`]; an
//! input whose processing would produce a non-finite state or a covariance
//! that is not positive definite is rejected with
//! [`EstimatorError::Numerical`]. In both cases the state is unchanged, so
//! no estimator ever outputs NaN.

pub mod cda;
pub mod cda_msu;
mod config_check;
mod dead_reckoning;
pub mod flight;
pub mod guard;
mod gyro_calibration;
pub mod gyro_ckf;
pub mod heading_kf;
pub mod history;
pub mod ickon_akf;
mod input;
mod kf;
pub mod msu_raw;
pub mod obstacle_angle;
pub mod odometry;
pub mod position_akf;
mod registry;
mod start_check;
pub mod tdoa_ekf;

#[cfg(test)]
mod tests;

pub use config_check::InvalidParameter;
pub use dead_reckoning::{DeadReckoningNoise, Increment, IncrementTracker, arc_step};
pub use input::{
    BeaconRangeSample, EncoderSample, GyroSample, Input, OdometrySample, RangeDifferenceSample,
    RangeSample, TransmitterClock, WheelGeometry,
};
pub use registry::{
    EstimatorConfig, UnknownEstimator, build, build_by_name, names, two_sensor_heading,
};

use nalgebra::Matrix3;

/// A pose estimate at a time: position in metres, heading in radians wrapped
/// to `(-pi, pi]`, and the covariance of `(x, y, theta)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimate {
    /// Time the estimate refers to, in seconds.
    pub t_s: f64,
    /// East coordinate in metres.
    pub x_m: f64,
    /// North coordinate in metres.
    pub y_m: f64,
    /// Heading from the x axis, counter-clockwise, in `(-pi, pi]`.
    pub theta_rad: f64,
    /// Covariance of `(x_m, y_m, theta_rad)`, symmetric positive definite.
    pub covariance: Matrix3<f64>,
}

/// Why an input was rejected. The estimator's state is unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimatorError {
    /// A field of the input is NaN or infinite.
    #[error("input field `{field}` is not finite")]
    NonFinite {
        /// Name of the offending field.
        field: &'static str,
    },
    /// The input is older than the history the estimator keeps.
    #[error("input at t = {t_s} s is older than the kept history (starts at {oldest_s} s)")]
    TooLate {
        /// Time of the rejected input.
        t_s: f64,
        /// Oldest time the estimator can still insert an input at.
        oldest_s: f64,
    },
    /// A field is outside its domain (for example a non-positive wheel base).
    #[error("input field `{field}` is out of range: {reason}")]
    OutOfRange {
        /// Name of the offending field.
        field: &'static str,
        /// What the field must satisfy.
        reason: &'static str,
    },
    /// Processing the input would have produced a non-finite state or a
    /// covariance that is not positive definite (extreme magnitudes).
    #[error("input at t = {t_s} s would make the estimate numerically invalid")]
    Numerical {
        /// Time of the rejected input.
        t_s: f64,
    },
}

/// A pose estimator fed with timestamped inputs (mostly in time order).
pub trait Estimator: Send {
    /// The registry name (`"ickon-akf"`, ...).
    fn name(&self) -> &'static str;
    /// Consumes one input. On `Err` the state is unchanged.
    fn handle(&mut self, input: &Input) -> Result<(), EstimatorError>;
    /// The current estimate, or `None` until the estimator is initialised.
    fn pose(&self) -> Option<PoseEstimate>;
    /// Returns to the state right after construction.
    fn reset(&mut self);
}

/// Pose to start from when the estimator is not initialised by a fix.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialPose {
    /// Start x in metres.
    pub x_m: f64,
    /// Start y in metres.
    pub y_m: f64,
    /// Start heading in radians.
    pub theta_rad: f64,
    /// Standard deviation of the start position, per axis, in metres.
    #[serde(default = "default_initial_sigma_xy_m")]
    pub sigma_xy_m: f64,
    /// Standard deviation of the start heading in radians.
    #[serde(default = "default_initial_sigma_theta_rad")]
    pub sigma_theta_rad: f64,
}

fn default_initial_sigma_xy_m() -> f64 {
    0.01
}

fn default_initial_sigma_theta_rad() -> f64 {
    1.0_f64.to_radians()
}

impl Default for InitialPose {
    fn default() -> Self {
        Self {
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            sigma_xy_m: default_initial_sigma_xy_m(),
            sigma_theta_rad: default_initial_sigma_theta_rad(),
        }
    }
}

/// Smallest variance any estimator reports, per component: keeps the
/// covariance positive definite when a filter has converged hard (a
/// variance of exactly zero would make the matrix singular).
pub(crate) const MIN_VARIANCE: f64 = 1e-12;

/// Symmetrises `p` and lifts its diagonal to [`MIN_VARIANCE`]; returns
/// `None` unless the result is finite and positive definite.
pub(crate) fn checked_covariance(p: Matrix3<f64>) -> Option<Matrix3<f64>> {
    let mut s = (p + p.transpose()) * 0.5;
    for i in 0..3 {
        s[(i, i)] = s[(i, i)].max(MIN_VARIANCE);
    }
    if s.iter().all(|v| v.is_finite()) && s.cholesky().is_some() {
        Some(s)
    } else {
        None
    }
}
