//! `gyro-ckf`: the iGPS paper, sections 7-10, heading from a rate gyro and a
//! delayed absolute heading fused by a complementary Kalman filter that
//! estimates the gyro bias; position as in `ickon-akf`.
//!
//! Heading (closed-loop error-state form of the paper's complementary KF):
//! - The navigation heading integrates the bias-corrected gyro,
//!   `theta += (omega - b_hat) dt`, at the gyro rate (the output rate).
//! - Error state `e = [d_theta, d_omega]` with `d_theta = theta_true - theta`
//!   and `d_omega = b - b_hat`; the error model of eq. 11,
//!   `d_theta_dot = -d_omega`, with the bias constant plus a random walk,
//!   gives `A = [[1, -dt], [0, 1]]`, `Q = diag(q_theta dt, q_b dt)`
//!   (eq. 3, 5-6).
//! - Measurement (eq. 4, 7-9): `z = theta_abs - theta = d_theta + v`,
//!   `C = [1, 0]`, `theta_abs` re-expressed by whole turns towards `theta`.
//!   After the update the estimated errors are fed back into `theta` and
//!   `b_hat`, and the error state returns to zero.
//! - `theta_abs` is the MSU heading from the receiver id, or the heading of
//!   two MSUs on one robot ([`two_sensor_heading`], the iGPS paper, eq. 1); it
//!   arrives late and is applied at its own measurement time, against the
//!   gyro-propagated heading of that time, and the later gyro samples are
//!   replayed on top (see [`super::replay`]): this is how the paper's 100 ms
//!   iGPS latency disappears from the output.
//!
//! Position: the relative increments `dd` (eq. 9 of the ICKON paper) projected on
//! this heading (eq. 10-11 of the ICKON paper) feed the shared
//! [`super::position_akf::PositionAkf`].
//!
//! Choices where the seed is silent (it gives no noise values):
//! - Gyro noise 0.05 deg/sqrt(s), bias random walk 0.005 deg/s/sqrt(s),
//!   initial bias uncertainty 1 deg/s, absolute heading noise 30 deg (the
//!   receiver-id quantisation of the ICKON paper; set ~1 deg for two MSUs).
//! - Each gyro rate is held over the interval that ends at its sample
//!   (rectangular integration, as in the CDA paper's eq. 9). A gap longer than
//!   `max_gyro_gap_s` is not integrated (the rate over it is unknown) but the
//!   covariance still grows over it.
//! - Before the first absolute heading the heading starts at 0 with a
//!   180 deg standard deviation (or at the configured initial pose).
//! - Position uses the heading at the odometry sample's time; the position
//!   itself advances at the odometry rate and is not extrapolated.

use nalgebra::{Matrix2, Matrix3, RowVector2, Vector1, Vector2};

use super::dead_reckoning::IncrementTracker;
use super::history::InOrderFilter;
use super::kf;
use super::position_akf::{PositionAkf, PositionAkfParams};
use super::{InitialPose, Input, PoseEstimate};
use crate::angle;

/// The iGPS paper, eq. 1, kept at this path; the implementation lives with the
/// other positioning headings in [`crate::tdoa`].
pub use crate::tdoa::two_sensor_heading;

/// Parameters of `gyro-ckf`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GyroCkfParams {
    /// Gyro white noise (angle random walk), deg/sqrt(s).
    pub gyro_noise_deg_sqrt_s: f64,
    /// Bias random walk, deg/s/sqrt(s).
    pub bias_walk_deg_s_sqrt_s: f64,
    /// Initial standard deviation of the bias, deg/s.
    pub initial_bias_sigma_deg_s: f64,
    /// Noise of the absolute heading, degrees.
    pub heading_sigma_deg: f64,
    /// Initial heading standard deviation without an initial pose, degrees.
    pub initial_heading_sigma_deg: f64,
    /// Longest gyro interval that is integrated, seconds.
    pub max_gyro_gap_s: f64,
    /// Position fusion unit (the ICKON paper, eq. 12-19).
    pub position: PositionAkfParams,
    /// Known start pose; `None` starts from the first fix.
    pub initial_pose: Option<InitialPose>,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for GyroCkfParams {
    fn default() -> Self {
        Self {
            gyro_noise_deg_sqrt_s: 0.05,
            bias_walk_deg_s_sqrt_s: 0.005,
            initial_bias_sigma_deg_s: 1.0,
            heading_sigma_deg: 30.0,
            initial_heading_sigma_deg: 180.0,
            max_gyro_gap_s: 0.5,
            position: PositionAkfParams::default(),
            initial_pose: None,
            history_s: super::history::default_history_s(),
        }
    }
}

/// The complementary heading filter alone (the iGPS paper, eq. 11).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroCkfHeading {
    params: GyroCkfParams,
    /// Continuous heading, radians.
    theta_rad: f64,
    /// Estimated gyro bias, rad/s.
    bias_rad_s: f64,
    /// Covariance of the error state `[d_theta, d_omega]`.
    p: Matrix2<f64>,
    last_gyro_s: Option<f64>,
}

impl GyroCkfHeading {
    /// Starts at `theta_rad` with standard deviation `sigma_rad`.
    pub fn new(params: GyroCkfParams, theta_rad: f64, sigma_rad: f64) -> Self {
        let sb = params.initial_bias_sigma_deg_s.to_radians();
        Self {
            params,
            theta_rad,
            bias_rad_s: 0.0,
            p: Matrix2::new(sigma_rad * sigma_rad, 0.0, 0.0, sb * sb),
            last_gyro_s: None,
        }
    }

    /// Continuous heading, radians.
    pub fn heading_rad(&self) -> f64 {
        self.theta_rad
    }

    /// Estimated gyro bias, rad/s.
    pub fn bias_rad_s(&self) -> f64 {
        self.bias_rad_s
    }

    /// Heading variance, rad^2.
    pub fn heading_variance_rad2(&self) -> f64 {
        self.p[(0, 0)]
    }

    /// Propagation with one gyro sample (eq. 5-6 on the error model).
    pub fn gyro(&mut self, t_s: f64, rate_rad_s: f64) {
        let Some(prev) = self.last_gyro_s.replace(t_s) else {
            return;
        };
        let dt = t_s - prev;
        if dt <= 0.0 {
            return;
        }
        if dt <= self.params.max_gyro_gap_s {
            self.theta_rad += (rate_rad_s - self.bias_rad_s) * dt;
        }
        let qt = self.params.gyro_noise_deg_sqrt_s.to_radians().powi(2) * dt;
        let qb = self.params.bias_walk_deg_s_sqrt_s.to_radians().powi(2) * dt;
        let a = Matrix2::new(1.0, -dt, 0.0, 1.0);
        self.p = kf::predict(&self.p, &a, &Matrix2::new(qt, 0.0, 0.0, qb));
    }

    /// Correction with an absolute heading (eq. 7-9), fed back into the
    /// heading and the bias. Returns `false` if numerically refused.
    pub fn absolute(&mut self, theta_abs_rad: f64) -> bool {
        let z = angle::unwrap_towards(theta_abs_rad, self.theta_rad) - self.theta_rad;
        let r = self.params.heading_sigma_deg.to_radians().powi(2);
        let h = RowVector2::new(1.0, 0.0);
        match kf::update(
            &Vector2::zeros(),
            &self.p,
            &h,
            &nalgebra::Matrix1::new(r),
            &Vector1::new(z),
        ) {
            Some((e, p)) => {
                self.theta_rad += e[0];
                // d_omega = b - b_hat, so the bias estimate moves by +d_omega.
                self.bias_rad_s += e[1];
                self.p = p;
                true
            }
            None => false,
        }
    }
}

/// The `gyro-ckf` state machine.
#[derive(Debug, Clone)]
pub struct GyroCkf {
    increments: IncrementTracker,
    heading: GyroCkfHeading,
    position: PositionAkf,
    t_s: f64,
}

impl GyroCkf {
    /// A filter with the given parameters.
    pub fn new(params: &GyroCkfParams) -> Self {
        let mut position = PositionAkf::new(params.position);
        let heading = match params.initial_pose {
            Some(p) => {
                let v = p.sigma_xy_m * p.sigma_xy_m;
                position.initialise(p.x_m, p.y_m, Matrix2::from_diagonal_element(v), 0.0);
                GyroCkfHeading::new(*params, p.theta_rad, p.sigma_theta_rad)
            }
            None => {
                GyroCkfHeading::new(*params, 0.0, params.initial_heading_sigma_deg.to_radians())
            }
        };
        Self {
            increments: IncrementTracker::default(),
            heading,
            position,
            t_s: f64::NEG_INFINITY,
        }
    }

    /// The heading filter (for inspection).
    pub fn heading(&self) -> &GyroCkfHeading {
        &self.heading
    }
}

impl InOrderFilter for GyroCkf {
    fn name(&self) -> &'static str {
        "gyro-ckf"
    }

    fn step(&mut self, input: &Input) {
        match input {
            Input::Gyro(g) => self.heading.gyro(g.t_s, g.rate_rad_s),
            Input::Odometry(_) | Input::Encoders(_) => {
                if let Some(inc) = self.increments.step(input) {
                    let th = self.heading.heading_rad();
                    self.position
                        .predict(inc.distance_m * th.cos(), inc.distance_m * th.sin());
                }
            }
            Input::Fix(fix) => {
                if let Some(h) = fix.heading_rad {
                    self.heading.absolute(h);
                }
                self.position.correct(fix);
            }
            Input::Range(_) | Input::RangeDifference(_) | Input::BeaconRange(_) => return,
        }
        self.t_s = self.t_s.max(input.t_s());
    }

    fn pose(&self) -> Option<PoseEstimate> {
        let (s, p) = self.position.state()?;
        let mut covariance = Matrix3::zeros();
        covariance.fixed_view_mut::<2, 2>(0, 0).copy_from(&p);
        covariance[(2, 2)] = self.heading.heading_variance_rad2();
        Some(PoseEstimate {
            t_s: if self.t_s.is_finite() { self.t_s } else { 0.0 },
            x_m: s.x,
            y_m: s.y,
            theta_rad: self.heading.heading_rad(),
            covariance,
        })
    }
}
