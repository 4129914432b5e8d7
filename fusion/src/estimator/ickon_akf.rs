//! `ickon-akf`: the ICKON paper, section 3.2, the tightly coupled heading and
//! position system, exactly as Figure 5 chains it.
//!
//! 1. Heading fusion (eq. 7-8, [`HeadingKf`]): predicted with the backward
//!    difference `d_gamma_b` of the relative unit's heading, corrected with
//!    the MSU heading from the receiver id (re-expressed by +-360 deg towards
//!    the prediction), `sigma_w = 2 deg`, `sigma_v = 30 deg`.
//! 2. Relative position correction (eq. 9-11): `dd = sqrt(dx_b^2 + dy_b^2)`,
//!    `dx_hat_b = dd cos(gamma)`, `dy_hat_b = dd sin(gamma)`, with `gamma`
//!    the combined heading.
//! 3. Position fusion (eq. 12-19, [`PositionAkf`]): the adaptive filter fed
//!    with `(dx_hat_b, dy_hat_b)` and corrected with the MSU position.
//!
//! Inputs: odometry poses (`x_b, y_b, gamma_b`) or encoder ticks (whichever
//! comes first, see [`super::IncrementTracker`]), and MSU fixes. Gyro and
//! range inputs are ignored.
//!
//! Choices where the seed is silent:
//! - `gamma` in eq. 10-11 is the combined heading after the prediction with
//!   the step's `d_gamma_b`, i.e. the heading at the end of the step.
//! - `dd` is signed by the direction of travel (see [`super::Increment`]).
//! - Start: the position filter starts at the first fix; the heading filter
//!   starts at 0 deg with a 180 deg standard deviation so the first MSU
//!   heading takes over; with [`InitialPose`] both start there instead,
//!   until two fixes that agree with each other but not with it replace it
//!   (position at the fix, heading unknown: [`super::start_check`]). No
//!   pose is reported before the position is known.
//! - A fix without a heading updates only the position.
//! - Late fixes are applied at their measurement time and the later
//!   odometry replayed (see [`super::replay`]).

use nalgebra::{Matrix2, Matrix3};

use super::dead_reckoning::IncrementTracker;
use super::heading_kf::{HeadingKf, HeadingKfParams};
use super::history::InOrderFilter;
use super::position_akf::{PositionAkf, PositionAkfParams};
use super::start_check::{StartCheck, StartVerdict};
use super::{InitialPose, Input, PoseEstimate};

/// Parameters of `ickon-akf` (the ICKON paper's values by default).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IckonAkfParams {
    /// Heading fusion unit (eq. 7-8).
    pub heading: HeadingKfParams,
    /// Position fusion unit (eq. 12-19).
    pub position: PositionAkfParams,
    /// Known start pose; `None` starts from the first fix.
    pub initial_pose: Option<InitialPose>,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for IckonAkfParams {
    fn default() -> Self {
        Self {
            heading: HeadingKfParams::default(),
            position: PositionAkfParams::default(),
            initial_pose: None,
            history_s: super::history::default_history_s(),
        }
    }
}

/// The fused heading and position filters of the ICKON paper driven by relative
/// increments; shared by `ickon-akf` and `cda-msu`.
#[derive(Debug, Clone)]
pub(crate) struct HeadingPositionFusion {
    pub(crate) heading: HeadingKf,
    pub(crate) position: PositionAkf,
    pub(crate) t_s: f64,
    heading_params: HeadingKfParams,
    start: StartCheck,
}

impl HeadingPositionFusion {
    pub(crate) fn new(
        heading: HeadingKfParams,
        position: PositionAkfParams,
        initial: Option<InitialPose>,
    ) -> Self {
        let mut out = Self {
            heading: HeadingKf::uninformed(heading),
            position: PositionAkf::new(position),
            t_s: f64::NEG_INFINITY,
            heading_params: heading,
            start: StartCheck::new(initial.is_some()),
        };
        if let Some(p) = initial {
            out.heading = HeadingKf::new(heading, p.theta_rad, p.sigma_theta_rad);
            let var = p.sigma_xy_m * p.sigma_xy_m;
            out.position
                .initialise(p.x_m, p.y_m, Matrix2::from_diagonal_element(var), 0.0);
        }
        out
    }

    /// Eq. 7 then eq. 9-13 for one relative step.
    pub(crate) fn relative_step(&mut self, t_s: f64, distance_m: f64, d_gamma_rad: f64) {
        self.heading.predict(d_gamma_rad);
        let gamma = self.heading.heading_rad();
        self.position
            .predict(distance_m * gamma.cos(), distance_m * gamma.sin());
        self.t_s = self.t_s.max(t_s);
    }

    /// Eq. 8 (if the fix has a heading) and eq. 16-19.
    /// A start pose is checked against the first fixes first.
    pub(crate) fn fix(&mut self, fix: &crate::tdoa::Fix) {
        let own = self.position.state().map(|(s, p)| ([s.x, s.y], p));
        match self.start.judge(fix, own) {
            StartVerdict::Fuse => {}
            StartVerdict::Hold => return,
            StartVerdict::Replace => {
                self.heading = HeadingKf::uninformed(self.heading_params);
                self.position
                    .initialise(fix.x_m(), fix.y_m(), fix.covariance_xy_m2(), fix.t_s);
                if let Some(h) = fix.heading_rad {
                    self.heading.correct(h);
                }
                self.t_s = self.t_s.max(fix.t_s);
                return;
            }
        }
        if let Some(h) = fix.heading_rad {
            self.heading.correct(h);
        }
        self.position.correct(fix);
        self.t_s = self.t_s.max(fix.t_s);
    }

    pub(crate) fn pose(&self) -> Option<PoseEstimate> {
        let (s, p) = self.position.state()?;
        let mut covariance = Matrix3::zeros();
        covariance.fixed_view_mut::<2, 2>(0, 0).copy_from(&p);
        covariance[(2, 2)] = self.heading.variance_rad2();
        Some(PoseEstimate {
            t_s: if self.t_s.is_finite() { self.t_s } else { 0.0 },
            x_m: s.x,
            y_m: s.y,
            theta_rad: self.heading.heading_rad(),
            covariance,
        })
    }
}

/// The `ickon-akf` state machine (wrap in [`super::history::LateInputHistory`]).
#[derive(Debug, Clone)]
pub struct IckonAkf {
    increments: IncrementTracker,
    fusion: HeadingPositionFusion,
}

impl IckonAkf {
    /// A filter with the given parameters.
    pub fn new(params: &IckonAkfParams) -> Self {
        Self {
            increments: IncrementTracker::default(),
            fusion: HeadingPositionFusion::new(
                params.heading,
                params.position,
                params.initial_pose,
            ),
        }
    }
}

impl InOrderFilter for IckonAkf {
    fn name(&self) -> &'static str {
        "ickon-akf"
    }

    fn step(&mut self, input: &Input) {
        match input {
            Input::Odometry(_) | Input::Encoders(_) => {
                if let Some(inc) = self.increments.step(input) {
                    self.fusion
                        .relative_step(inc.t_s, inc.distance_m, inc.dtheta_rad);
                }
            }
            Input::Fix(fix) => self.fusion.fix(fix),
            Input::Gyro(_)
            | Input::Range(_)
            | Input::RangeDifference(_)
            | Input::BeaconRange(_) => {}
        }
    }

    fn pose(&self) -> Option<PoseEstimate> {
        self.fusion.pose()
    }
}
