//! `cda`: the CDA paper, sections 3-4, the curvature-based decision approach with
//! obstacle-avoidance fusion (the paper's CDA-O), encoders + gyro only.
//!
//! Per encoder sample (distance `dist = (l + r)/2`, encoder turn
//! `alpha = (r - l)/W`):
//! 1. Gyroscope controller (section 4.2): the curvature `D_c` of the past
//!    trajectory selects the heading source. In encoder mode, when
//!    `D_c > mu1` the gyro takes over; in gyro mode, when `D_c <= mu2` the
//!    encoders take over again (`mu2 << mu1`, `mu1` checked first).
//! 2. Encoder mode: arc kinematics, eq. 1-3 (turning) and eq. 4-6 (straight).
//!    Gyro mode: `theta_g(t) = theta_g(t-1) + sum(omega_i dt)` over the gyro
//!    samples of the step (eq. 9), then `x += dist cos(theta_g)`,
//!    `y += dist sin(theta_g)` (eq. 10-11).
//! 3. Curvature (section 4.1, eq. 16-17): from the last two points `P1, P2`
//!    and the centre `C` of the encoder arc between them (eq. 2-3), the
//!    tangents at `P1, P2` are perpendicular to `C P1`, `C P2` and
//!    `D_c = atan((m1 - m2)/(1 + m1 m2))`, computed in the equivalent form
//!    `atan(tan(angle(C P1, C P2)))`, which has no infinite slopes.
//!
//! Per gyro sample: offset and noise calibration at rest (eq. 7-8) over the
//! first `calibration_samples` readings taken while the encoders report no
//! motion (a reading counts once the encoder step covering it and the next
//! one show no tick), then `omega - offset`, zeroed inside the dead band
//! `[-noise, noise]`.
//!
//! Per range sample: the obstacle-avoidance heading `theta_oa` (eq. 12-15,
//! see [`super::obstacle_angle`]) and, while a manoeuvre is in progress, the
//! complementary filter `theta = a theta_g + (1 - a) theta_oa` (eq. 18).
//!
//! Choices where the seed is ambiguous:
//! - `D_c` is measured per encoder step, so `mu1, mu2` are in degrees per
//!   step (defaults 0.5 deg and 0.05 deg at ~10 Hz odometry). Eq. 16 as
//!   printed mixes `P2(y)` and `P1(x)`; we read it as the slope of `C P1`.
//!   A turn in place (arc radius under 1 mm) has `D_c = |alpha|` folded to
//!   90 deg.
//! - The decision for a step uses `D_c` of the previous step (the "past
//!   trajectory"); the first step of a turn is thus encoder-based.
//! - A gyro-mode step without any gyro sample falls back to `alpha`.
//! - If the robot moves before calibration is complete, the calibration is
//!   closed with the samples collected so far (offset 0, noise 0 if none);
//!   the readings of that first moving step are not integrated.
//! - The complementary filter is applied at each range sample, with the gyro
//!   chain's heading as `theta_g` and `a = 0.95`; eq. 12-15 restart from
//!   the current heading when a manoeuvre begins.
//! - The CDA paper has no absolute positioning: MSU fixes are ignored here (see
//!   `cda-msu`). Odometry poses may replace encoder ticks (then `alpha` is
//!   their heading difference).
//! - Late inputs (a gyro reading delivered after the encoder step that
//!   covers it, a late range sample) are inserted at their time and the
//!   later inputs replayed ([`super::replay`]).
//! - The covariance grows by first-order propagation of
//!   [`super::DeadReckoningNoise`] (not from the seed).

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Matrix3, Vector3};

use super::dead_reckoning::{
    DeadReckoningNoise, Increment, IncrementTracker, arc_step, propagate_covariance,
};
use super::gyro_calibration::GyroCalibration;
use super::history::InOrderFilter;
use super::obstacle_angle::{ObstacleAngle, ObstacleAngleParams, next_angle};
use super::{InitialPose, Input, PoseEstimate};
use crate::angle;

/// Parameters of `cda` (and of the heading chain of `cda-msu`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CdaParams {
    /// Number of gyro samples at rest for the offset/noise calibration `N`.
    pub calibration_samples: u32,
    /// Start threshold `mu1` on the curvature, degrees per encoder step.
    pub mu_start_deg: f64,
    /// Stop threshold `mu2` on the curvature, degrees per encoder step.
    pub mu_stop_deg: f64,
    /// Weight `a` of the gyro heading in the complementary filter (eq. 18).
    pub complementary_alpha: f64,
    /// Constants of the obstacle-avoidance angle (eq. 12-15).
    pub obstacle: ObstacleAngleParams,
    /// Longest gyro interval that is integrated, seconds.
    pub max_gyro_gap_s: f64,
    /// Noise model that grows the covariance.
    pub noise: DeadReckoningNoise,
    /// Start pose in the world frame.
    pub initial_pose: InitialPose,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for CdaParams {
    fn default() -> Self {
        Self {
            calibration_samples: 100,
            mu_start_deg: 0.5,
            mu_stop_deg: 0.05,
            complementary_alpha: 0.95,
            obstacle: ObstacleAngleParams::default(),
            max_gyro_gap_s: 0.5,
            noise: DeadReckoningNoise::default(),
            initial_pose: InitialPose::default(),
            history_s: super::history::default_history_s(),
        }
    }
}

/// Which sensor drives the heading (section 4.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadingSource {
    /// Encoder heading, eq. 1-6.
    Encoders,
    /// Gyro heading, eq. 9-11.
    Gyro,
}

/// The CDA paper's heading chain with its own dead-reckoned pose.
#[derive(Debug, Clone)]
pub struct CdaChain {
    params: CdaParams,
    increments: IncrementTracker,
    calibration: GyroCalibration,
    source: HeadingSource,
    curvature_rad: f64,
    gyro_sum_rad: f64,
    gyro_count: u32,
    last_gyro_s: Option<f64>,
    obstacle_rad: Option<f64>,
    theta_reported_rad: f64,
    t_s: f64,
    x_m: f64,
    y_m: f64,
    theta_rad: f64,
    covariance: Matrix3<f64>,
}

impl CdaChain {
    /// Starts at `params.initial_pose`, at rest, in encoder mode.
    pub fn new(params: &CdaParams) -> Self {
        let p = params.initial_pose;
        let v = p.sigma_xy_m * p.sigma_xy_m;
        Self {
            params: *params,
            increments: IncrementTracker::default(),
            calibration: GyroCalibration::new(),
            source: HeadingSource::Encoders,
            curvature_rad: 0.0,
            gyro_sum_rad: 0.0,
            gyro_count: 0,
            last_gyro_s: None,
            obstacle_rad: None,
            theta_reported_rad: p.theta_rad,
            t_s: 0.0,
            x_m: p.x_m,
            y_m: p.y_m,
            theta_rad: p.theta_rad,
            covariance: Matrix3::from_diagonal(&Vector3::new(
                v,
                v,
                p.sigma_theta_rad * p.sigma_theta_rad,
            )),
        }
    }

    /// The heading source in use.
    pub fn source(&self) -> HeadingSource {
        self.source
    }

    /// The gyro `(offset, noise)` once calibrated, rad/s.
    pub fn gyro_calibration(&self) -> Option<(f64, f64)> {
        self.calibration.result
    }

    /// The chain's continuous heading, radians.
    pub fn heading_rad(&self) -> f64 {
        self.theta_rad
    }

    /// Shifts the chain's heading to `theta_rad` without producing an
    /// increment (used by `cda-msu` to keep the chain in the world frame).
    pub fn rebase_heading(&mut self, theta_rad: f64) {
        let shift = theta_rad - self.theta_rad;
        self.theta_rad += shift;
        self.theta_reported_rad += shift;
        if let Some(oa) = &mut self.obstacle_rad {
            *oa += shift;
        }
    }

    /// Consumes one input; for a relative-positioning input returns the
    /// step's distance and the heading change of the chain since the
    /// previous step (including complementary-filter corrections).
    pub fn step(&mut self, input: &Input) -> Option<Increment> {
        match input {
            Input::Gyro(g) => {
                self.gyro(g.t_s, g.rate_rad_s);
                None
            }
            Input::Range(r) => {
                self.range(r);
                None
            }
            Input::Odometry(_) | Input::Encoders(_) => {
                let inc = self.increments.step(input)?;
                Some(self.relative(inc))
            }
            // cda has no absolute positioning: fixes and range differences are ignored.
            Input::Fix(_) | Input::RangeDifference(_) | Input::BeaconRange(_) => None,
        }
    }

    fn gyro(&mut self, t_s: f64, rate_rad_s: f64) {
        let prev = self.last_gyro_s.replace(t_s);
        if self.calibration.result.is_none() {
            self.calibration.add(rate_rad_s);
            return;
        }
        let Some(dt) = prev.map(|p| t_s - p) else {
            return;
        };
        if dt <= 0.0 || dt > self.params.max_gyro_gap_s {
            return;
        }
        let (offset, noise) = self.calibration.close();
        let rate = rate_rad_s - offset;
        // Dead band (section 3.2): readings within the noise are ignored.
        if rate.abs() > noise {
            self.gyro_sum_rad += rate * dt;
        }
        self.gyro_count += 1;
    }

    fn range(&mut self, sample: &super::RangeSample) {
        let previous = self.obstacle_rad.unwrap_or(self.theta_rad);
        match next_angle(&self.params.obstacle, previous, sample) {
            ObstacleAngle::Clear => self.obstacle_rad = None,
            ObstacleAngle::Planned(oa) => {
                let oa = angle::unwrap_towards(oa, self.theta_rad);
                self.obstacle_rad = Some(oa);
                let a = self.params.complementary_alpha;
                self.theta_rad = a * self.theta_rad + (1.0 - a) * oa;
            }
        }
        self.t_s = self.t_s.max(sample.t_s);
    }

    fn relative(&mut self, inc: Increment) -> Increment {
        let still = inc.distance_m == 0.0 && inc.dtheta_rad == 0.0;
        self.calibration
            .encoder_step(still, self.params.calibration_samples);
        let mu1 = self.params.mu_start_deg.to_radians();
        let mu2 = self.params.mu_stop_deg.to_radians();
        self.source = match self.source {
            HeadingSource::Encoders if self.curvature_rad > mu1 => HeadingSource::Gyro,
            HeadingSource::Gyro if self.curvature_rad <= mu2 => HeadingSource::Encoders,
            s => s,
        };
        let (x1, y1, theta1) = (self.x_m, self.y_m, self.theta_rad);
        let dtheta = match self.source {
            HeadingSource::Gyro if self.gyro_count > 0 => {
                self.theta_rad += self.gyro_sum_rad;
                self.x_m += inc.distance_m * self.theta_rad.cos();
                self.y_m += inc.distance_m * self.theta_rad.sin();
                self.gyro_sum_rad
            }
            _ => {
                (self.x_m, self.y_m, self.theta_rad) =
                    arc_step(x1, y1, theta1, inc.distance_m, inc.dtheta_rad);
                inc.dtheta_rad
            }
        };
        self.curvature_rad = curvature(x1, y1, theta1, self.x_m, self.y_m, &inc);
        self.gyro_sum_rad = 0.0;
        self.gyro_count = 0;
        let (vd, vt) = self.params.noise.variances(inc.distance_m, dtheta);
        let mid = theta1 + 0.5 * dtheta;
        self.covariance = propagate_covariance(&self.covariance, mid, inc.distance_m, vd, vt);
        self.t_s = self.t_s.max(inc.t_s);
        let out = Increment {
            dtheta_rad: self.theta_rad - self.theta_reported_rad,
            ..inc
        };
        self.theta_reported_rad = self.theta_rad;
        out
    }

    /// The chain's dead-reckoned pose.
    pub fn pose(&self) -> PoseEstimate {
        PoseEstimate {
            t_s: self.t_s,
            x_m: self.x_m,
            y_m: self.y_m,
            theta_rad: self.theta_rad,
            covariance: self.covariance,
        }
    }
}

/// Eq. 16-17: degree of curvature between `P1 = (x1, y1)` (heading
/// `theta1`) and `P2 = (x2, y2)`, with the centre of the encoder arc of the
/// step (eq. 2-3). Zero on a straight step.
fn curvature(x1: f64, y1: f64, theta1: f64, x2: f64, y2: f64, inc: &Increment) -> f64 {
    const TURN_IN_PLACE_M: f64 = 1e-3;
    if inc.dtheta_rad.abs() < 1e-12 {
        return 0.0;
    }
    let rho = inc.distance_m / inc.dtheta_rad;
    let between = if rho.abs() < TURN_IN_PLACE_M {
        inc.dtheta_rad
    } else {
        let cx = x1 - rho * theta1.sin();
        let cy = y1 + rho * theta1.cos();
        let (n1x, n1y, n2x, n2y) = (x1 - cx, y1 - cy, x2 - cx, y2 - cy);
        (n1x * n2y - n1y * n2x).atan2(n1x * n2x + n1y * n2y)
    };
    // atan((m1 - m2)/(1 + m1 m2)) is the angle between the tangents folded
    // into (-90, 90] deg.
    let folded = between - PI * (between / PI).round();
    folded.abs().min(FRAC_PI_2)
}

/// The `cda` state machine.
#[derive(Debug, Clone)]
pub struct Cda {
    chain: CdaChain,
}

impl Cda {
    /// Starts at `params.initial_pose`.
    pub fn new(params: &CdaParams) -> Self {
        Self {
            chain: CdaChain::new(params),
        }
    }

    /// The heading chain (for inspection).
    pub fn chain(&self) -> &CdaChain {
        &self.chain
    }
}

impl InOrderFilter for Cda {
    fn name(&self) -> &'static str {
        "cda"
    }

    fn step(&mut self, input: &Input) {
        self.chain.step(input);
    }

    fn pose(&self) -> Option<PoseEstimate> {
        Some(self.chain.pose())
    }
}
