//! `odometry`: relative positioning alone, the baseline every fusion is
//! compared with.
//!
//! - Odometry poses (`x_b, y_b, gamma_b`) are passed through, expressed in
//!   the world frame: the first pose received is anchored at the start pose
//!   and later poses keep their offset from it (rigid transform), so the
//!   robot's own odometry frame may start anywhere.
//! - Encoder ticks are integrated with the arc kinematics of the CDA paper
//!   eq. 1-6 (`dist = (l + r) / 2`, heading change `(r - l) / W`).
//! - The first relative source seen is used; the other is then ignored.
//! - The covariance grows by first-order propagation of
//!   [`super::DeadReckoningNoise`]; it is a documented model, not calibrated.
//! - The heading is kept continuous internally and wrapped on output.
//! - Late samples are inserted at their time and the later ones replayed
//!   ([`super::replay`]); fixes, gyro and range inputs are ignored.

use nalgebra::Matrix3;

use super::dead_reckoning::{DeadReckoningNoise, IncrementTracker, arc_step, propagate_covariance};
use super::history::InOrderFilter;
use super::{InitialPose, Input, OdometrySample, PoseEstimate};

/// Parameters of `odometry`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdometryParams {
    /// Start pose of the robot in the world frame.
    pub initial_pose: InitialPose,
    /// Noise model that grows the covariance.
    pub noise: DeadReckoningNoise,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for OdometryParams {
    fn default() -> Self {
        Self {
            initial_pose: InitialPose::default(),
            noise: DeadReckoningNoise::default(),
            history_s: super::history::default_history_s(),
        }
    }
}

/// The `odometry` state machine.
#[derive(Debug, Clone)]
pub struct Odometry {
    params: OdometryParams,
    increments: IncrementTracker,
    anchor: Option<OdometrySample>,
    t_s: f64,
    x_m: f64,
    y_m: f64,
    theta_rad: f64,
    covariance: Matrix3<f64>,
}

impl Odometry {
    /// Starts at `params.initial_pose`.
    pub fn new(params: &OdometryParams) -> Self {
        let p = params.initial_pose;
        let v = p.sigma_xy_m * p.sigma_xy_m;
        Self {
            params: *params,
            increments: IncrementTracker::default(),
            anchor: None,
            t_s: 0.0,
            x_m: p.x_m,
            y_m: p.y_m,
            theta_rad: p.theta_rad,
            covariance: Matrix3::from_diagonal(&nalgebra::Vector3::new(
                v,
                v,
                p.sigma_theta_rad * p.sigma_theta_rad,
            )),
        }
    }

    fn pass_through(&mut self, s: &OdometrySample) {
        let anchor = *self.anchor.get_or_insert(*s);
        let start = self.params.initial_pose;
        // Offset of `s` from the anchor, in the anchor's body frame.
        let (sa, ca) = anchor.theta_rad.sin_cos();
        let dx = s.x_m - anchor.x_m;
        let dy = s.y_m - anchor.y_m;
        let fwd = ca * dx + sa * dy;
        let left = -sa * dx + ca * dy;
        let (ss, cs) = start.theta_rad.sin_cos();
        self.x_m = start.x_m + cs * fwd - ss * left;
        self.y_m = start.y_m + ss * fwd + cs * left;
        self.theta_rad = crate::angle::unwrap_towards(
            start.theta_rad + (s.theta_rad - anchor.theta_rad),
            self.theta_rad,
        );
    }
}

impl InOrderFilter for Odometry {
    fn name(&self) -> &'static str {
        "odometry"
    }

    fn step(&mut self, input: &Input) {
        let inc = self.increments.step(input);
        let encoders = self.increments.uses_encoders();
        let theta_before = self.theta_rad;
        match input {
            Input::Odometry(s) if !encoders => self.pass_through(s),
            Input::Encoders(_) if encoders => {
                if let Some(inc) = inc {
                    (self.x_m, self.y_m, self.theta_rad) = arc_step(
                        self.x_m,
                        self.y_m,
                        self.theta_rad,
                        inc.distance_m,
                        inc.dtheta_rad,
                    );
                }
            }
            _ => return,
        }
        if let Some(inc) = inc {
            let (vd, vt) = self.params.noise.variances(inc.distance_m, inc.dtheta_rad);
            let mid = theta_before + 0.5 * inc.dtheta_rad;
            self.covariance = propagate_covariance(&self.covariance, mid, inc.distance_m, vd, vt);
        }
        self.t_s = input.t_s();
    }

    fn pose(&self) -> Option<PoseEstimate> {
        Some(PoseEstimate {
            t_s: self.t_s,
            x_m: self.x_m,
            y_m: self.y_m,
            theta_rad: self.theta_rad,
            covariance: self.covariance,
        })
    }
}
