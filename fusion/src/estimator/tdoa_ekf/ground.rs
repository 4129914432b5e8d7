//! The ground-robot variant behind [`crate::estimator::Estimator`]: state
//! `(x, y, theta)`, predicted by dead reckoning (encoder ticks or odometry
//! poses for the distance, the gyro or the wheels for the turn), corrected
//! by each range difference on its own with the receiver at the known
//! height `receiver_height_m`.
//!
//! - Prediction: the arc step of seed 003 (eq. 1-6) with the distance of
//!   the relative unit; the heading change is the gyro's integral over the
//!   step when a gyro sample arrived within `max_gyro_gap_s` (the gyro
//!   does not slip), else the wheels'. The gyro bias is not estimated: the
//!   heading is corrected through its correlation with the position, which
//!   the arc step builds up as the robot drives.
//! - Correction: physical check, innovation gate, scalar Joseph update,
//!   recovery of a lost filter (as in [`super::TdoaEkf3d`]).
//! - Start: at `initial_pose` when given; otherwise at the centroid of the
//!   first `start_transmitters` distinct transmitters heard, with
//!   `start_sigma_xy_m` per axis and an unknown heading. While the heading
//!   is unknown, an arc step along a guessed heading would move the
//!   position the wrong way with a covariance that pretends otherwise (the
//!   linearisation fails for errors of tens of degrees); so the position
//!   only diffuses by the distance driven, and the heading is taken from
//!   the track once the robot has moved `heading_chord_m` with a settled
//!   position: the chord's direction plus half the turn driven along it
//!   (exact on an arc).
//! - MSU fixes are not fused (the filter consumes the arrivals themselves)
//!   but watched, to re-localise a lost filter: when `relocalise_after`
//!   fixes in a row lie beyond `relocalise_gate_sigma` of the estimate
//!   (Mahalanobis distance with both covariances), the position restarts
//!   at the last fix with the fix's covariance and the heading variance
//!   grows by `relocalise_heading_sigma_deg`. Without this, a filter that
//!   lost the track in a corridor (poor geometry, reflections off the
//!   walls, a gyro bias it does not estimate) widened its variance and
//!   wandered off the floor; a run of fixes that agree with each other and
//!   not with the filter is the stronger evidence.

use std::f64::consts::PI;

use nalgebra::{Matrix3, RowVector3, Vector2, Vector3};

use super::observation::{self, Outcome, Rejection};
use super::recovery::{RecoveryParams, RejectionWatch};
use crate::estimator::dead_reckoning::{
    DeadReckoningNoise, IncrementTracker, arc_step, propagate_covariance,
};
use crate::estimator::replay::Core;
use crate::estimator::{FixSample, InitialPose, Input, PoseEstimate, RangeDifferenceSample};

/// Parameters of `tdoa-ekf` (ground robot).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TdoaEkfParams {
    /// Start pose; `None` starts at the centroid of the first transmitters.
    pub initial_pose: Option<InitialPose>,
    /// Height of the receiver above the floor, metres (the lab site's MSU:
    /// 0.5).
    pub receiver_height_m: f64,
    /// Dead-reckoning noise growing the covariance.
    pub noise: DeadReckoningNoise,
    /// Whether the gyro gives the heading change when it is running.
    pub use_gyro: bool,
    /// Longest time without a gyro sample for the gyro to count as
    /// running, seconds.
    pub max_gyro_gap_s: f64,
    /// Innovation gate in standard deviations.
    pub gate_sigma: f64,
    /// When the filter counts as lost, and how it widens.
    pub recovery: RecoveryParams,
    /// Distinct transmitters heard before starting without a start pose.
    pub start_transmitters: usize,
    /// Standard deviation per axis of a start at the transmitters'
    /// centroid, metres.
    pub start_sigma_xy_m: f64,
    /// Distance driven with a settled position after which an unknown
    /// heading is taken from the track, metres.
    pub heading_chord_m: f64,
    /// Position standard deviation under which the track counts as
    /// settled, metres.
    pub settled_sigma_m: f64,
    /// Standard deviation of a heading taken from the track, degrees.
    pub track_heading_sigma_deg: f64,
    /// Fixes in a row beyond the gate after which the filter re-localises
    /// at the fix (0: never).
    pub relocalise_after: u32,
    /// Mahalanobis gate between a fix and the estimate, standard deviations.
    pub relocalise_gate_sigma: f64,
    /// Standard deviation added to the heading on re-localisation, degrees.
    pub relocalise_heading_sigma_deg: f64,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for TdoaEkfParams {
    fn default() -> Self {
        Self {
            initial_pose: None,
            receiver_height_m: 0.5,
            noise: DeadReckoningNoise::default(),
            use_gyro: true,
            max_gyro_gap_s: 0.5,
            gate_sigma: 3.0,
            recovery: RecoveryParams::default(),
            start_transmitters: 3,
            start_sigma_xy_m: 3.0,
            heading_chord_m: 0.5,
            settled_sigma_m: 0.1,
            track_heading_sigma_deg: 10.0,
            relocalise_after: 3,
            relocalise_gate_sigma: 5.0,
            relocalise_heading_sigma_deg: 20.0,
            history_s: crate::estimator::registry::default_history_s(),
        }
    }
}

/// The `tdoa-ekf` state machine (ground robot).
#[derive(Debug, Clone)]
pub struct TdoaEkf {
    params: TdoaEkfParams,
    increments: IncrementTracker,
    /// `(x, y, theta)` and its covariance, once started.
    state: Option<(Vector3<f64>, Matrix3<f64>)>,
    t_s: f64,
    /// Transmitters heard before the start (no start pose).
    heard: Vec<[f64; 3]>,
    /// Last gyro sample `(t_s, rate)` and the turn integrated since the
    /// last relative step.
    gyro: Option<(f64, f64)>,
    gyro_turn_rad: f64,
    /// While the heading is unknown: where the settled track started and
    /// the turn driven since (`None` inside until the position settles).
    heading_from_track: Option<Option<TrackStart>>,
    watch: RejectionWatch,
    last_outcome: Option<Outcome>,
    /// Fixes in a row that disagreed with the estimate.
    fixes_disagreeing: u32,
}

/// Start of the chord an unknown heading is taken from.
#[derive(Debug, Clone, Copy)]
struct TrackStart {
    x_m: f64,
    y_m: f64,
    turn_rad: f64,
}

impl TdoaEkf {
    /// Starts at `params.initial_pose`, or waits for transmitters.
    pub fn new(params: &TdoaEkfParams) -> Self {
        let state = params.initial_pose.map(|p| {
            let v = p.sigma_xy_m * p.sigma_xy_m;
            let cov = Matrix3::from_diagonal(&Vector3::new(v, v, p.sigma_theta_rad.powi(2)));
            (Vector3::new(p.x_m, p.y_m, p.theta_rad), cov)
        });
        Self {
            params: *params,
            increments: IncrementTracker::default(),
            state,
            t_s: 0.0,
            heard: Vec::new(),
            gyro: None,
            gyro_turn_rad: 0.0,
            heading_from_track: None,
            watch: RejectionWatch::default(),
            last_outcome: None,
            fixes_disagreeing: 0,
        }
    }

    /// What the last range difference did (`None` before the first).
    pub fn last_outcome(&self) -> Option<Outcome> {
        self.last_outcome
    }

    fn gyro_sample(&mut self, t_s: f64, rate_rad_s: f64) {
        if let Some((t0, rate0)) = self.gyro.replace((t_s, rate_rad_s)) {
            let dt = t_s - t0;
            if dt > 0.0 && dt <= self.params.max_gyro_gap_s {
                self.gyro_turn_rad += rate0 * dt;
            }
        }
    }

    fn relative(&mut self, input: &Input) {
        let Some(inc) = self.increments.step(input) else {
            return;
        };
        let gyro_running = self.params.use_gyro
            && self
                .gyro
                .is_some_and(|(t, _)| (inc.t_s - t).abs() <= self.params.max_gyro_gap_s);
        let dtheta = if gyro_running {
            self.gyro_turn_rad
        } else {
            inc.dtheta_rad
        };
        self.gyro_turn_rad = 0.0;
        let Some((x, p)) = &mut self.state else {
            return;
        };
        if let Some(track) = &mut self.heading_from_track {
            // Heading unknown: the position diffuses by the distance driven.
            let v = inc.distance_m * inc.distance_m;
            p[(0, 0)] += v;
            p[(1, 1)] += v;
            if let Some(start) = track {
                start.turn_rad += dtheta;
            }
            return;
        }
        let (vd, vt) = self.params.noise.variances(inc.distance_m, dtheta);
        let mid = x.z + 0.5 * dtheta;
        let (nx, ny, nt) = arc_step(x.x, x.y, x.z, inc.distance_m, dtheta);
        let np = propagate_covariance(p, mid, inc.distance_m, vd, vt);
        if [nx, ny, nt].iter().chain(np.iter()).all(|v| v.is_finite()) {
            *x = Vector3::new(nx, ny, nt);
            *p = np;
        }
    }

    fn start_from_transmitters(&mut self, m: &RangeDifferenceSample) {
        for c in [m.a_m, m.b_m] {
            if !self.heard.contains(&c) {
                self.heard.push(c);
            }
        }
        if self.heard.len() < self.params.start_transmitters.max(1) {
            return;
        }
        let n = self.heard.len() as f64;
        let cx = self.heard.iter().map(|c| c[0]).sum::<f64>() / n;
        let cy = self.heard.iter().map(|c| c[1]).sum::<f64>() / n;
        let v = self.params.start_sigma_xy_m.powi(2);
        self.state = Some((
            Vector3::new(cx, cy, 0.0),
            Matrix3::from_diagonal(&Vector3::new(v, v, PI * PI)),
        ));
        self.heading_from_track = Some(None);
        self.heard.clear();
    }

    /// While the heading is unknown, after each accepted update: starts the
    /// chord once the position has settled, and sets the heading when it is
    /// long enough.
    fn heading_from_track(&mut self) {
        let (Some(track), Some((x, p))) = (&mut self.heading_from_track, &mut self.state) else {
            return;
        };
        if p[(0, 0)].max(p[(1, 1)]).sqrt() > self.params.settled_sigma_m {
            return;
        }
        let Some(start) = track else {
            *track = Some(TrackStart {
                x_m: x.x,
                y_m: x.y,
                turn_rad: 0.0,
            });
            return;
        };
        let (dx, dy) = (x.x - start.x_m, x.y - start.y_m);
        if dx.hypot(dy) < self.params.heading_chord_m {
            return;
        }
        x.z = dy.atan2(dx) + 0.5 * start.turn_rad;
        let v = self.params.track_heading_sigma_deg.to_radians().powi(2);
        for k in 0..2 {
            p[(k, 2)] = 0.0;
            p[(2, k)] = 0.0;
        }
        p[(2, 2)] = v;
        self.heading_from_track = None;
    }

    /// Watches one MSU fix; re-localises after a run of disagreeing ones.
    fn fix(&mut self, f: &FixSample) {
        if self.params.relocalise_after == 0 || self.heading_from_track.is_some() {
            return;
        }
        let Some((x, p)) = &mut self.state else {
            return;
        };
        let d = Vector2::new(f.x_m - x.x, f.y_m - x.y);
        let s = p.fixed_view::<2, 2>(0, 0) + f.covariance;
        let Some(m2) = s.try_inverse().map(|si| (d.transpose() * si * d)[0]) else {
            return;
        };
        if m2.is_finite() && m2 <= self.params.relocalise_gate_sigma.powi(2) {
            self.fixes_disagreeing = 0;
            return;
        }
        self.fixes_disagreeing += 1;
        if self.fixes_disagreeing < self.params.relocalise_after {
            return;
        }
        self.fixes_disagreeing = 0;
        let floor = crate::estimator::MIN_VARIANCE;
        let cov = (f.covariance + f.covariance.transpose()) * 0.5;
        x.x = f.x_m;
        x.y = f.y_m;
        let heading_v = p[(2, 2)]
            + self
                .params
                .relocalise_heading_sigma_deg
                .to_radians()
                .powi(2);
        *p = Matrix3::zeros();
        p.fixed_view_mut::<2, 2>(0, 0).copy_from(&cov);
        p[(0, 0)] = p[(0, 0)].max(floor);
        p[(1, 1)] = p[(1, 1)].max(floor);
        p[(2, 2)] = heading_v;
        self.watch = RejectionWatch::default();
    }

    fn range_difference(&mut self, m: &RangeDifferenceSample) -> Outcome {
        if let Err(r) = observation::check(m) {
            return Outcome::Rejected(r);
        }
        if self.state.is_none() {
            self.start_from_transmitters(m);
        }
        let Some((x, p)) = self.state else {
            return Outcome::Rejected(Rejection::NotInitialised);
        };
        let at = nalgebra::Vector3::new(x.x, x.y, self.params.receiver_height_m);
        let Some(lin) = observation::linearise(&at, m, 0.0) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        let h = RowVector3::new(lin.gradient.x, lin.gradient.y, 0.0);
        let innovation = m.d_m - lin.predicted_m;
        match observation::gated_update(&x, &p, &h, innovation, m.sigma_m, self.params.gate_sigma) {
            Ok((x, p, outcome)) => {
                self.state = Some((x, p));
                self.watch.note(false, &self.params.recovery);
                self.heading_from_track();
                outcome
            }
            Err(r) => {
                let gated = matches!(r, Rejection::Gate { .. });
                if gated && self.watch.note(true, &self.params.recovery) {
                    let v = self.params.recovery.sigma_m.powi(2);
                    if let Some((_, p)) = &mut self.state {
                        p[(0, 0)] += v;
                        p[(1, 1)] += v;
                    }
                }
                Outcome::Rejected(r)
            }
        }
    }
}

impl Core for TdoaEkf {
    fn name(&self) -> &'static str {
        "tdoa-ekf"
    }

    fn step(&mut self, input: &Input) {
        match input {
            Input::Gyro(g) => self.gyro_sample(g.t_s, g.rate_rad_s),
            Input::Odometry(_) | Input::Encoders(_) => self.relative(input),
            Input::RangeDifference(m) => {
                self.last_outcome = Some(self.range_difference(m));
            }
            Input::Fix(f) => self.fix(f),
            Input::Range(_) => return,
        }
        self.t_s = self.t_s.max(input.t_s());
    }

    fn pose(&self) -> Option<PoseEstimate> {
        let (x, p) = self.state?;
        Some(PoseEstimate {
            t_s: self.t_s,
            x_m: x.x,
            y_m: x.y,
            theta_rad: x.z,
            covariance: p,
        })
    }
}
