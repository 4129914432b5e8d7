//! The ground-robot filter behind [`crate::estimator::Estimator`], one
//! tightly coupled EKF for every absolute sensor a ground robot carries.
//!
//! - State ([`super::ground_state`]): position, heading, the turn-rate bias
//!   of the heading source (gyro, or wheels without one), the distance
//!   scale of the wheels, the pseudo-range offset of the cycle being fused,
//!   and the bias and scale error of absolute radio ranges.
//! - Prediction at the wheels' rate: the arc of seed 003 with the distance
//!   scaled and the heading change integrated from the gyro at its own rate
//!   (the wheels' when no gyro sample came within `max_gyro_gap_s`), the
//!   bias removed; noise from the sensors' data sheets ([`GroundNoise`]).
//! - Each arrival fused on its own, motion-compensated: the cycle's range
//!   differences are chained back into pseudo-ranges
//!   ([`super::ground_chain`]); the first arrival of a cycle initialises
//!   the offset, every later one is a scalar update of
//!   `|p(t_i) - s_i| + offset`, with `p(t_i)` the position at its own
//!   arrival time (the filter's motion between its last step and `t_i`).
//! - Reflections as what they are: late. An arrival far later than
//!   predicted is rejected; one moderately late is down-weighted (its
//!   variance grows with the square of its lateness beyond
//!   `late_soft_sigma`: a heavy tail on one side only); one far *earlier*
//!   than predicted cannot be a reflection, so the cycle's offset (set by
//!   an earlier arrival, possibly itself late) is re-initialised from it.
//! - The receiver-id heading of seed 000 (eq. 4-6), carried by the MSU
//!   fixes, as a heading measurement with its honest `heading_sigma_deg`
//!   (30 deg: half a 60 deg sector plus the beams' overlap); the fixes'
//!   positions are not fused (the filter already has their arrivals).
//! - Absolute ranges to radio beacons ([`TdoaEkf::range`]) with the range
//!   bias estimated, for robots that range instead of timing differences.
//! - A floor plan (`floor`), when given: a state outside it is impossible
//!   and projected back onto it; a re-initialisation outside it is refused.
//! - Recovery: when most recent arrivals that were not late (accepted, or
//!   earlier than predicted beyond the gate: no reflection does that) are
//!   early ones, the filter counts as lost ([`RecoveryParams`]); it then waits for a cycle whose arrivals
//!   agree with each other (a redundant, motion-compensated fix without
//!   rejected residuals, [`crate::tdoa::solve_moving`]); when two of them
//!   agree with each other but not with the filter, it re-initialises its
//!   position there (when they agree with the filter too, it was not
//!   displaced and simply counts as found again), counted in [`TdoaEkf::reinitialisations`]. It does
//!   not widen its variance or jump to single fixes meanwhile.
//! - Start: at `initial_pose` when given, but only as a guess checked like
//!   a lost filter's position: its first two agreeing consistent cycles
//!   confirm it or, when three disagree with it (an MSU restarted on a
//!   robot that drove away from its start), replace it, as if there were no
//!   start pose. Otherwise at the first
//!   consistent cycle (or at the centroid of the first `start_transmitters`
//!   transmitters heard, with `start_sigma_xy_m`), heading unknown: the
//!   position only diffuses by the distance driven, and the heading is
//!   taken from the track once the robot has moved `heading_chord_m` with a
//!   settled position (the chord's direction plus half the turn driven).

use std::f64::consts::PI;

use nalgebra::Vector3;

use super::clock_slots::ClockSlots;
use super::ground_chain::{Arrival, Chain, Link};
use super::ground_noise::GroundNoise;
use super::ground_state::{
    self as gs, BIAS, CLOCK, Cov, OFFSET, RANGE_BIAS, RANGE_SCALE, Row, SCALE, State, Step, TH,
    TURN_SCALE, X, Y,
};
use super::observation::{self, Outcome, Rejection};
use super::recovery::{RecoveryParams, RejectionWatch};
use super::standstill::{self, Standstill};
use super::systematic::HeardLately;
use crate::angle;
use crate::estimator::dead_reckoning::IncrementTracker;
use crate::estimator::guard::{LateArrivals, LateParams};
use crate::estimator::history::InOrderFilter;
use crate::estimator::{InitialPose, Input, PoseEstimate, RangeDifferenceSample};
use crate::tdoa;

/// An axis-aligned floor plan the robot cannot leave, metres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Floor {
    /// Lower corner `(x, y)`.
    pub min_m: [f64; 2],
    /// Upper corner `(x, y)`.
    pub max_m: [f64; 2],
}

impl Floor {
    /// Whether `(x, y)` is on the floor.
    pub fn contains(&self, x_m: f64, y_m: f64) -> bool {
        (self.min_m[0]..=self.max_m[0]).contains(&x_m)
            && (self.min_m[1]..=self.max_m[1]).contains(&y_m)
    }
}

/// Parameters of `tdoa-ekf` (ground robot).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TdoaEkfParams {
    /// Start pose; `None` starts from the first consistent cycle.
    pub initial_pose: Option<InitialPose>,
    /// Height of the receiver above the floor, metres (the lab site's MSU:
    /// 0.5).
    pub receiver_height_m: f64,
    /// Data-sheet noise of the gyro and the wheels.
    pub sensors: GroundNoise,
    /// Whether the gyro gives the heading change when it is running.
    pub use_gyro: bool,
    /// Longest time without a gyro sample for the gyro to count as
    /// running, seconds.
    pub max_gyro_gap_s: f64,
    /// Innovation gate in standard deviations.
    pub gate_sigma: f64,
    /// Lateness, in standard deviations, beyond which an arrival's variance
    /// grows (one-sided heavy tail for reflections).
    pub late_soft_sigma: f64,
    /// Standard deviation of the receiver-id heading of the fixes, degrees
    /// (0: not fused).
    pub heading_sigma_deg: f64,
    /// When the filter counts as lost; its window also averages the
    /// normalised innovations for `model_nis`.
    pub recovery: RecoveryParams,
    /// Mean squared normalised innovation (one when the model holds)
    /// above which the heading and turn bias are reopened.
    pub model_nis: f64,
    /// Fewest arrivals of a cycle to re-initialise (or start) from: one
    /// more than a 2D fix needs, so their consistency can be checked.
    pub reinit_arrivals: usize,
    /// Standard deviation added to the heading on re-initialisation,
    /// degrees.
    pub reinit_heading_sigma_deg: f64,
    /// The floor plan, when known.
    pub floor: Option<Floor>,
    /// Distinct transmitters heard before starting at their centroid
    /// without a start pose (if no consistent cycle came first).
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
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
    /// When a transmitter whose arrivals keep coming late is set aside
    /// (the watch's [`LateArrivals`], shared with the 3D filters).
    pub late: LateParams,
    /// Whether each cell's sync error is learnt as a state (its prior: the
    /// sync sigma the cell reports, at least `sensors.cell_sync_sigma_us`;
    /// see `clock_slots.rs`). Off by default: it helps where the cells'
    /// sync is poor (a congested network: hundreds of microseconds), is
    /// neutral where it is good (`paper`), and on `lab`'s corridors under the
    /// `harsh` profile it cost 20-35 mm (see the README).
    pub learn_cell_sync: bool,
}

/// [`LateParams`] for ultrasound: each transmitter is heard once per cycle
/// (2-3 per second), not hundreds of times as a UWB anchor. Over half of
/// its last 10 arrivals (about 4 s) late; aside for 3 s (the robot moves
/// about a metre at 0.3 m/s, past the obstacle's shadow); at most 2 at once
/// (a 2D fix needs 3 of the 6-8 usually heard).
fn ultrasound_late_params() -> LateParams {
    LateParams {
        window: 10,
        blamed_share: 0.5,
        hold_s: 3.0,
        max_aside: 2,
    }
}

impl Default for TdoaEkfParams {
    fn default() -> Self {
        Self {
            initial_pose: None,
            receiver_height_m: 0.5,
            sensors: GroundNoise::default(),
            use_gyro: true,
            max_gyro_gap_s: 0.5,
            gate_sigma: 4.0,
            late_soft_sigma: 2.0,
            heading_sigma_deg: 30.0,
            recovery: RecoveryParams::default(),
            model_nis: 3.0,
            reinit_arrivals: 5,
            reinit_heading_sigma_deg: 20.0,
            floor: None,
            start_transmitters: 3,
            start_sigma_xy_m: 3.0,
            heading_chord_m: 0.5,
            settled_sigma_m: 0.1,
            track_heading_sigma_deg: 10.0,
            history_s: crate::estimator::history::default_history_s(),
            late: ultrasound_late_params(),
            learn_cell_sync: false,
        }
    }
}

/// A re-initialisation of a lost filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reinitialisation {
    /// When, seconds.
    pub t_s: f64,
    /// Position before, metres.
    pub from_m: [f64; 2],
    /// Position after, metres.
    pub to_m: [f64; 2],
}

/// The `tdoa-ekf` state machine (ground robot).
#[derive(Debug, Clone)]
pub struct TdoaEkf {
    params: TdoaEkfParams,
    increments: IncrementTracker,
    /// State and covariance, once started.
    state: Option<(State, Cov)>,
    /// Time of the newest input, seconds.
    t_s: f64,
    /// Time the state's position refers to (its last step), seconds.
    state_t_s: f64,
    /// Speed along the heading over the last step, m/s.
    speed_m_s: f64,
    /// Transmitters heard before the start (no start pose).
    heard: Vec<[f64; 3]>,
    /// Last gyro sample `(t_s, rate)`, the turn integrated since the last
    /// step and the time it spans.
    gyro: Option<(f64, f64)>,
    gyro_turn_rad: f64,
    gyro_time_s: f64,
    /// Since when the wheels have not moved (a still robot's gyro reads its bias).
    standstill: Standstill,
    /// While the heading is unknown: where the settled track started and
    /// the turn driven since (`None` inside until the position settles).
    heading_from_track: Option<Option<TrackStart>>,
    /// While the heading is unknown: the distance driven since the last
    /// accepted update (the motion is coherent, so the position's variance
    /// grows with its square, not with the sum of each step's square).
    unknown_heading_drift_m: f64,
    chain: Chain,
    /// Whether the cycle's offset is initialised for the current chain.
    offset_ready: bool,
    /// Whether an arrival has agreed with the offset since it was set.
    offset_confirmed: bool,
    /// Predicted range of the arrival that set the cycle's offset, metres.
    offset_range_m: f64,
    /// Running mean of the squared normalised innovations, and how many
    /// went in since the last adaptation.
    nis_mean: f64,
    nis_seen: u32,
    adaptations: u32,
    watch: RejectionWatch,
    lost: bool,
    /// Share of the recent arrivals gated, early or late (an exponential
    /// average over about ten): a start counts as lost until confirmed,
    /// but only this says its arrivals disagree with it.
    gated_share: f64,
    /// Whether consistent cycles have confirmed where the filter started
    /// (a start pose is the site's guess: a restarted MSU's robot is
    /// wherever it drove to).
    start_confirmed: bool,
    /// Since when the filter has fused arrivals with its heading known and
    /// none far earlier than predicted, seconds (`None`: not so now).
    tracking_since_s: Option<f64>,
    candidate: Option<Candidate>,
    last_outcome: Option<Outcome>,
    reinits: Vec<Reinitialisation>,
    late: LateArrivals,
    /// Whether the last arrival gated was late (not early).
    gated_late: bool,
    /// Transmitters of the arrivals fused lately: the survey's share of the
    /// published covariance.
    heard_lately: HeardLately,
    /// The cells whose clock bias the state holds.
    clocks: ClockSlots,
}

/// A fix of one cycle waiting for the next cycle to confirm it.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    chain_start_s: f64,
    t_s: f64,
    xy_m: [f64; 2],
    sigma_m: f64,
    /// Consistent cycles before it that agreed, each with the next.
    agreeing_before: u32,
    /// Time of the first cycle of that agreeing run, seconds.
    agreeing_since_s: f64,
    /// The filter's position when the cycle came, if its motion is known
    /// (heading known): the fixes of two cycles must have moved as it did.
    state_xy_m: Option<[f64; 2]>,
}

/// Share of the distance driven that the wheels may be wrong by when two
/// candidate fixes are compared with the filter's own motion (a few times
/// the sheet's 1 % slip, and the heading's error over a short drive).
const CANDIDATE_MOTION_SLACK: f64 = 0.1;

/// Share of recent arrivals gated above which a start not yet confirmed may
/// be replaced: most of them (a start 7 m off has nearly all gated; a
/// right one is gated only where reflections come early).
const START_DOUBTED_GATED_SHARE: f64 = 0.5;

/// Weight of one arrival in [`TdoaEkf`]'s gated share (about ten arrivals,
/// one or two cycles).
const GATED_SHARE_WEIGHT: f64 = 0.1;

/// Agreeing consistent cycles that replace a start pose not yet confirmed:
/// one more than the two that place a lost filter, since two cycles can
/// share a bias (the same reflection off a rack passes the solver's check
/// in both: on warehouse one robot's right start was moved 1.4 m that way
/// and lost its heading).
const AGREEING_CYCLES_AGAINST_A_START: u32 = 3;

/// Shortest time the cycles against a start pose, or against the state of
/// a filter that has been tracking, must span, seconds. The
/// count above was set at the `lab` rate (2.6 cycles/s: three cycles span
/// about a second); at 10 cycles/s (occupancy firing, two carrier channels)
/// three cycles come within 0.3 s from one place and share its reflections,
/// and a robot's right start was replaced by a wrong place 0.8 m off whose
/// heading then came from the track the wrong way round (`warehouse` with
/// two channels, 16 robots: that robot 127 mm mean, p95 569 mm).
/// The same holds for a tracked state: on `warehouse` at 6 cycles/s (16
/// robots, seed 8) a robot tracked to 11 mm was marked lost at a rack end
/// and moved 0.87 m by two cycles 0.17 s apart that shared one place's
/// reflections; it was wrong for 10 s.
const AGREEING_SPAN_AGAINST_A_START_S: f64 = 1.0;

/// A start pose from which the filter has fused arrivals this long, its
/// heading known and no arrival far earlier than predicted (the evidence
/// of a wrong state: a wrong start makes some arrivals early), is
/// confirmed, seconds: twice the span of
/// the cycles that may replace it, so the evidence for the start is the
/// stronger. Without it a start was confirmed only by cycles met while
/// lost, and a filter that had tracked from a right start for seconds,
/// once marked lost by a run of early arrivals, could still be moved by
/// three biased cycles as if it had never been right (`warehouse`, 16
/// robots, seed 3, `--fire-range-m 7`: robot r13 moved 0.8 m with its
/// heading reversed, wrong for ten seconds).
const TRACKING_CONFIRMS_A_START_S: f64 = 2.0;

/// Start of the chord an unknown heading is taken from.
#[derive(Debug, Clone, Copy)]
struct TrackStart {
    x_m: f64,
    y_m: f64,
    turn_rad: f64,
}

/// Most re-initialisations remembered (the count goes on).
const MAX_REINITS_KEPT: usize = 64;

impl TdoaEkf {
    /// Starts at `params.initial_pose`, or waits for transmitters.
    pub fn new(params: &TdoaEkfParams) -> Self {
        let state = params.initial_pose.map(|p| {
            let mut x = State::zeros();
            x[X] = p.x_m;
            x[Y] = p.y_m;
            x[TH] = p.theta_rad;
            (x, prior(params, p.sigma_xy_m, p.sigma_theta_rad))
        });
        Self {
            params: *params,
            increments: IncrementTracker::default(),
            state,
            t_s: 0.0,
            state_t_s: f64::NEG_INFINITY,
            speed_m_s: 0.0,
            heard: Vec::new(),
            gyro: None,
            gyro_turn_rad: 0.0,
            gyro_time_s: 0.0,
            standstill: Standstill::default(),
            heading_from_track: None,
            unknown_heading_drift_m: 0.0,
            chain: Chain::default(),
            offset_ready: false,
            offset_range_m: 0.0,
            offset_confirmed: false,
            nis_mean: 1.0,
            nis_seen: 0,
            adaptations: 0,
            watch: RejectionWatch::default(),
            // A start pose is checked like a lost filter's position: the
            // filter fuses as usual, and its first two consistent cycles
            // either confirm the start or replace it (see `try_reinitialise`).
            lost: true,
            gated_share: 0.0,
            start_confirmed: false,
            tracking_since_s: None,
            candidate: None,
            last_outcome: None,
            reinits: Vec::new(),
            late: LateArrivals::new(params.late),
            gated_late: false,
            heard_lately: HeardLately::default(),
            clocks: ClockSlots::default(),
        }
    }

    /// What the last range difference or range did (`None` before the first).
    pub fn last_outcome(&self) -> Option<Outcome> {
        self.last_outcome
    }

    /// The re-initialisations so far (the latest [`MAX_REINITS_KEPT`]).
    pub fn reinitialisations(&self) -> &[Reinitialisation] {
        &self.reinits
    }

    /// How many times the filter reopened its heading and turn bias
    /// because the arrivals disagreed with its model.
    pub fn adaptations(&self) -> u32 {
        self.adaptations
    }

    /// Whether the filter currently counts as lost (also from a start
    /// pose until consistent cycles confirm it).
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// The estimated turn-rate bias of the heading source, rad/s.
    pub fn turn_bias_rad_s(&self) -> Option<f64> {
        self.state.map(|(x, _)| x[BIAS])
    }

    /// The estimated range bias of absolute ranges, metres.
    pub fn range_bias_m(&self) -> Option<f64> {
        self.state.map(|(x, _)| x[RANGE_BIAS])
    }

    /// The estimated range scale error of absolute ranges (a range reads
    /// the distance times one plus it, plus the bias).
    pub fn range_scale(&self) -> Option<f64> {
        self.state.map(|(x, _)| x[RANGE_SCALE])
    }

    /// The estimated turn scale error of the heading source (its reported
    /// turn is the true one times one plus it, plus the bias).
    pub fn turn_scale(&self) -> Option<f64> {
        self.state.map(|(x, _)| x[TURN_SCALE])
    }

    /// The estimated distance scale error (travelled = measured times one
    /// plus it).
    pub fn distance_scale(&self) -> Option<f64> {
        self.state.map(|(x, _)| x[SCALE])
    }

    fn gyro_sample(&mut self, t_s: f64, rate_rad_s: f64) {
        if let Some((t0, rate0)) = self.gyro.replace((t_s, rate_rad_s)) {
            let dt = t_s - t0;
            if dt > 0.0 && dt <= self.params.max_gyro_gap_s {
                self.gyro_turn_rad += rate0 * dt;
                self.gyro_time_s += dt;
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
        let (dtheta, turn_time) = if gyro_running {
            (self.gyro_turn_rad, self.gyro_time_s)
        } else {
            (inc.dtheta_rad, inc.dt_s.max(0.0))
        };
        self.gyro_turn_rad = 0.0;
        self.gyro_time_s = 0.0;
        let standing = self.standstill.note(&inc);
        if gyro_running && standing && turn_time > 0.0 && self.heading_from_track.is_none() {
            // Nothing turned: the heading holds, and the gyro read its bias.
            self.increment(inc.t_s, 0.0, 0.0, 0.0, true);
            let var = self.params.sensors.var_gyro_turn(turn_time) / turn_time.powi(2);
            self.gyro_bias_at_rest(dtheta / turn_time, var);
            return;
        }
        self.increment(inc.t_s, inc.distance_m, dtheta, turn_time, gyro_running);
    }

    /// The gyro's mean rate `rate_rad_s` (variance `var`) over a stretch
    /// in which the robot stood still: a measurement of its bias
    /// ([`standstill`]), gated.
    fn gyro_bias_at_rest(&mut self, rate_rad_s: f64, var: f64) {
        let Some((x, p)) = &mut self.state else {
            return;
        };
        if !(rate_rad_s.is_finite() && var.is_finite() && var > 0.0) {
            return;
        }
        let mut h = Row::zeros();
        h[BIAS] = 1.0;
        let nu = rate_rad_s - x[BIAS];
        if let Ok((nx, np, _)) =
            observation::gated_update(x, p, &h, nu, var.sqrt(), standstill::GATE_SIGMAS)
        {
            *x = nx;
            *p = np;
        }
    }

    /// One dead-reckoning step ending at `t_s`: `distance_m` driven (signed)
    /// while the heading source turned by `dtheta_rad` over `turn_time_s`
    /// (bias included); `from_gyro` says whose noise applies. For callers
    /// that drive the filter directly from their own increments.
    pub fn increment(
        &mut self,
        t_s: f64,
        distance_m: f64,
        dtheta_rad: f64,
        turn_time_s: f64,
        from_gyro: bool,
    ) {
        if ![t_s, distance_m, dtheta_rad, turn_time_s]
            .iter()
            .all(|v| v.is_finite())
        {
            return;
        }
        let dt = if self.state_t_s.is_finite() {
            (t_s - self.state_t_s).max(0.0)
        } else {
            turn_time_s.max(0.0)
        };
        self.state_t_s = t_s;
        self.t_s = self.t_s.max(t_s);
        self.speed_m_s = if dt > 0.0 { distance_m / dt } else { 0.0 };
        let Some((x, p)) = &mut self.state else {
            return;
        };
        if let Some(track) = &mut self.heading_from_track {
            // Heading unknown: the robot may have driven anywhere within the
            // distance since the position was last measured. Growing the
            // variance by each step's square instead let a robot at 0.3 m/s
            // drift 8 cm between cycles while the filter claimed 1.5 cm: its
            // updates were gated out, the filter counted itself lost and
            // re-placed, and the heading's chord started again (a restarted
            // MSU took 5-10 s to find its heading).
            let before = self.unknown_heading_drift_m;
            self.unknown_heading_drift_m += distance_m.abs();
            let v = self.unknown_heading_drift_m.powi(2) - before.powi(2);
            p[(X, X)] += v;
            p[(Y, Y)] += v;
            if let Some(start) = track {
                start.turn_rad += dtheta_rad;
            }
            return;
        }
        let n = &self.params.sensors;
        let omega = if dt > 0.0 { dtheta_rad / dt } else { 0.0 };
        let (var_dtheta, walk) = if from_gyro {
            (n.var_gyro_turn(turn_time_s), n.gyro_bias_walk_deg_s_sqrt_s)
        } else {
            (
                n.var_wheel_turn(dtheta_rad, distance_m),
                n.wheel_bias_walk_deg_s_sqrt_s,
            )
        };
        let step = Step {
            distance_m,
            dtheta_rad,
            turn_time_s,
            var_distance: n.var_distance(distance_m, omega),
            var_dtheta,
            var_bias: walk.to_radians().powi(2) * dt,
        };
        if let Some((nx, mut np)) = gs::predict(x, p, &step) {
            np[(RANGE_BIAS, RANGE_BIAS)] += n.range_bias_walk_m_sqrt_s.powi(2) * dt;
            for (c, sigma_m) in self.clocks.used() {
                np[(c, c)] += n.var_clock_walk(sigma_m, dt);
            }
            *x = nx;
            *p = np;
            self.project_on_floor();
        }
    }

    /// The receiver position at time `t_s`: the state's, moved on along
    /// the heading at the last step's speed.
    fn position_at(&self, x: &State, t_s: f64) -> Vector3<f64> {
        let dt = if self.state_t_s.is_finite() {
            t_s - self.state_t_s
        } else {
            0.0
        };
        let (s, c) = x[TH].sin_cos();
        let ds = self.speed_m_s * dt;
        Vector3::new(x[X] + ds * c, x[Y] + ds * s, self.params.receiver_height_m)
    }

    /// Predicted pseudo-range of an arrival without the offset, and its
    /// row (position columns, and its cell's clock bias in `clock`).
    fn arrival_model(&self, x: &State, a: &Arrival, clock: Option<usize>) -> Option<(f64, Row)> {
        let p = self.position_at(x, a.t_s);
        let r = p - Vector3::from(a.tx_m);
        let d = r.norm();
        if d < 1e-6 {
            return None;
        }
        let mut h = Row::zeros();
        h[X] = r.x / d;
        h[Y] = r.y / d;
        let bias = clock.map_or(0.0, |c| {
            h[c] = 1.0;
            x[c]
        });
        Some((d + bias, h))
    }

    /// The state column of the clock bias of `a`'s cell (giving the cell a
    /// slot when it has none).
    fn clock_column(&mut self, a: &Arrival) -> Option<usize> {
        if !self.params.learn_cell_sync {
            return None;
        }
        let sigma_m = self.params.sensors.clock_bias_sigma_m();
        let (x, p) = self.state.as_mut()?;
        self.clocks.column(a.clock, a.t_s, sigma_m, x, p)
    }

    /// Variance of one arrival's pseudo-range whose timing noise is
    /// `sigma_m`: never less than the survey's sigma squared. Where each
    /// transmitter really hangs is known only to the survey's accuracy, so
    /// an arrival is never better than that, however fine its stamp. With
    /// the timing alone, receivers five times better than the data sheet's
    /// (5 us instead of 70) made the filter trust its arrivals beyond the
    /// transmitters' 1 cm, gate the good ones and lose robots on
    /// `warehouse` (one at 321 mm mean; 31 mm at worst with the floor), and
    /// the `ideal` profile's microsecond stamps put `lab`'s `eight` at 36.6
    /// mm (7.8 with it). A floor and not a sum: at the sheet's timing (24
    /// mm) the survey's share is small beside it, and adding it cost about
    /// 1 mm of mean error on `warehouse`'s routes (seeds 1-3); with the
    /// floor every number at the sheet's timing is unchanged.
    fn arrival_variance(&self, sigma_m: f64) -> f64 {
        sigma_m.max(self.params.sensors.survey_sigma_m).powi(2)
    }

    /// Initialises the cycle's offset from arrival `a`.
    fn offset_from(&mut self, a: &Arrival, sigma_m: f64) -> bool {
        let clock = self.clock_column(a);
        let Some((x, _)) = self.state else {
            return false;
        };
        let Some((pred, h)) = self.arrival_model(&x, a, clock) else {
            return false;
        };
        let r = self.arrival_variance(sigma_m);
        if let Some((x, p)) = &mut self.state {
            gs::init_offset(x, p, &h, a.rho_m, pred, r);
        }
        self.offset_ready = true;
        self.offset_confirmed = false;
        self.offset_range_m = pred;
        true
    }

    /// Watches the normalised innovations of accepted arrivals: their
    /// squares average one when the model holds. A run well above that
    /// (a gyro bias step, a slipping wheel: the data sheet's model no
    /// longer holds) reopens the heading and the turn bias to the sheet's
    /// power-up uncertainty, so the arrivals can pull them back.
    fn adapt(&mut self, normalised: f64) {
        let n = f64::from(self.params.recovery.window.max(1));
        let nis = normalised * normalised;
        self.nis_mean += (nis - self.nis_mean) / n;
        self.nis_seen = self.nis_seen.saturating_add(1);
        if self.nis_seen < self.params.recovery.window || self.nis_mean < self.params.model_nis {
            return;
        }
        self.nis_seen = 0;
        self.nis_mean = 1.0;
        if let Some((_, p)) = &mut self.state {
            let b = self.params.sensors.gyro_bias_sigma_deg_s.to_radians();
            p[(BIAS, BIAS)] += b * b;
            p[(TH, TH)] += self.params.reinit_heading_sigma_deg.to_radians().powi(2) / 4.0;
            let s = turn_scale_sigma(&self.params);
            p[(TURN_SCALE, TURN_SCALE)] += s * s;
        }
        self.adaptations = self.adaptations.saturating_add(1);
    }

    /// Fuses one arrival of the chain (offset already initialised).
    fn arrival(&mut self, a: &Arrival, sigma_m: f64) -> Outcome {
        let clock = self.clock_column(a);
        let Some((x, p)) = self.state else {
            return Outcome::Rejected(Rejection::NotInitialised);
        };
        let Some((pred, mut h)) = self.arrival_model(&x, a, clock) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        h[OFFSET] = 1.0;
        let nu = a.rho_m - pred - x[OFFSET];
        // The speed of sound is known only as well as the air's temperature:
        // a range error in proportion to the distance. The part common to
        // the cycle goes into its offset; what is left is the error of the
        // difference to the arrival that set it. Without it, an exact world
        // (timing sigma 0.3 mm, the 1 us stamp) made the filter trust its
        // arrivals beyond every other model error it has and fail (57-118
        // mm on `lab` under `ideal`; 2-5 mm with it, see the README).
        let speed = self.params.sensors.speed_of_sound_rel_sigma() * (pred - self.offset_range_m);
        let r = self.arrival_variance(sigma_m) + speed * speed;
        let s = gs::innovation_variance(&p, &h, r);
        if !(s.is_finite() && s > 0.0) {
            return Outcome::Rejected(Rejection::Numerical);
        }
        let normalised = nu / s.sqrt();
        let (gate, soft) = (self.params.gate_sigma, self.params.late_soft_sigma);
        self.gated_late = normalised > gate;
        let gated = normalised.abs() > gate;
        self.gated_share += GATED_SHARE_WEIGHT * (f64::from(u8::from(gated)) - self.gated_share);
        if normalised > gate {
            // Far later than predicted: a reflection. Not evidence of a lost
            // filter (a healthy one in a burst of reflections sees many).
            return Outcome::Rejected(Rejection::Gate { normalised });
        }
        if normalised < -gate || (normalised < -soft && !self.offset_confirmed) {
            // Earlier than predicted beyond the noise: no path is shorter
            // than the direct one, so the offset (set by an earlier arrival
            // that was itself late) is what is wrong: it starts again from
            // this arrival, which is not fused. While no arrival has yet
            // agreed with the offset, "beyond the noise" is the soft bound;
            // once one has, only the gate, and it counts as evidence of a
            // lost filter.
            self.note(normalised < -gate);
            self.offset_from(a, sigma_m);
            return Outcome::Rejected(Rejection::Gate {
                normalised: normalised.abs(),
            });
        }
        let r = if normalised > soft {
            // One-sided heavy tail: a moderately late arrival may carry a
            // short reflection; trust it less the later it is.
            r + s * ((normalised / soft).powi(2) - 1.0)
        } else {
            r
        };
        match gs::update(&x, &p, &h, nu, r) {
            Some((nx, np)) => {
                self.state = Some((nx, np));
                self.note(false);
                self.confirm_start_by_tracking(a.t_s);
                self.offset_confirmed |= normalised.abs() <= soft;
                self.adapt(normalised);
                self.project_on_floor();
                self.unknown_heading_drift_m = 0.0;
                self.heading_from_track();
                Outcome::Accepted {
                    innovation_m: nu,
                    normalised: normalised.abs(),
                }
            }
            None => Outcome::Rejected(Rejection::Numerical),
        }
    }

    /// After an accepted arrival at `t_s`: confirms the start pose once the
    /// filter has tracked from it for [`TRACKING_CONFIRMS_A_START_S`].
    fn confirm_start_by_tracking(&mut self, t_s: f64) {
        if self.heading_from_track.is_some() {
            self.tracking_since_s = None;
            return;
        }
        let since = *self.tracking_since_s.get_or_insert(t_s);
        if t_s - since >= TRACKING_CONFIRMS_A_START_S {
            self.start_confirmed = true;
            // A filter that tracks is not lost, whatever marked it so (a
            // start counts as lost until confirmed): it is found again as
            // when consistent cycles agree with it.
            if self.lost {
                self.lost = false;
                self.candidate = None;
                self.watch = RejectionWatch::default();
            }
        }
    }

    /// Notes a gated measurement; marks the filter lost when most recent
    /// ones were rejected.
    fn note(&mut self, rejected: bool) {
        if rejected {
            // Far earlier than predicted: evidence against the state, so
            // the time tracked from the start counts again from zero.
            self.tracking_since_s = None;
        }
        if self.watch.note(rejected, &self.params.recovery) {
            self.lost = true;
            self.tracking_since_s = None;
        }
    }

    fn range_difference(&mut self, m: &RangeDifferenceSample) -> Outcome {
        let physical = observation::check(m);
        if let Err(r @ (Rejection::NonFinite { .. } | Rejection::BadSigma { .. })) = physical {
            return Outcome::Rejected(r);
        }
        let link = self
            .chain
            .add(m.a_m, m.b_m, m.d_m, m.t_s, m.a_t_s, m.clocks);
        // One arrival's sigma: the pair's is that of two.
        let sigma = m.sigma_m / std::f64::consts::SQRT_2;
        if self.state.is_none() {
            self.start_from_transmitters(m);
        }
        if self.lost && self.try_reinitialise(m.t_s) {
            return self
                .last_outcome
                .unwrap_or(Outcome::Rejected(Rejection::Gate {
                    normalised: f64::INFINITY,
                }));
        }
        if self.state.is_none() {
            return Outcome::Rejected(Rejection::NotInitialised);
        }
        let b = match link {
            Link::Started(a, b) => {
                self.offset_ready = false;
                // A transmitter set aside as late does not set the offset.
                if !self.late.is_arrival_aside(a.t_s, a.tx_m) && !self.offset_from(&a, sigma) {
                    return Outcome::Rejected(Rejection::Numerical);
                }
                b
            }
            Link::Continued(b) => b,
        };
        if self.late.is_arrival_aside(b.t_s, b.tx_m) {
            return Outcome::Rejected(Rejection::SetAside);
        }
        if !self.offset_ready {
            // The first arrival of the chain not set aside: it carries no
            // position by itself.
            return if self.offset_from(&b, sigma) {
                Outcome::Accepted {
                    innovation_m: 0.0,
                    normalised: 0.0,
                }
            } else {
                Outcome::Rejected(Rejection::Numerical)
            };
        }
        // A |d| beyond the baseline (physical check) means one of the two
        // arrivals is a reflection: the chain keeps the difference (the
        // next one undoes it) and the arrival is judged against the
        // prediction like any other, where a late one fails.
        let out = self.arrival(&b, sigma);
        match out {
            Outcome::Accepted { .. } => self.late.note_arrival(b.t_s, b.tx_m, false),
            Outcome::Rejected(Rejection::Gate { normalised }) => {
                // Gated late: blamed on this arrival. An early one (it
                // re-set the offset instead) is no late arrival.
                self.late
                    .note_arrival(b.t_s, b.tx_m, normalised > 0.0 && self.gated_late);
            }
            _ => {}
        }
        out
    }

    /// While lost (or not started): re-initialises at a redundant,
    /// self-consistent fix of the chain's arrivals. Returns whether it did.
    fn try_reinitialise(&mut self, t_s: f64) -> bool {
        let arrivals = self.chain.arrivals().to_vec();
        if arrivals.len() < self.params.reinit_arrivals.max(4) {
            return false;
        }
        let height = self.params.receiver_height_m;
        let heading = self.state.map_or(0.0, |(x, _)| x[TH]);
        let known_motion = self.state.is_some() && self.heading_from_track.is_none();
        let (s, c) = heading.sin_cos();
        let speed = if known_motion { self.speed_m_s } else { 0.0 };
        let signals: Vec<tdoa::Signal> = arrivals
            .iter()
            .enumerate()
            .map(|(i, a)| tdoa::Signal {
                tx_id: i as u32,
                tx_m: Vector3::from(a.tx_m),
                pseudo_range_m: a.rho_m,
                t_s: a.t_s,
            })
            .collect();
        let moves: Vec<Vector3<f64>> = arrivals
            .iter()
            .map(|a| Vector3::new(c, s, 0.0) * speed * (a.t_s - t_s))
            .collect();
        let config = tdoa::SolverConfig {
            mode: tdoa::Mode::TwoD { height_m: height },
            sigma_range_m: 0.03,
            ..tdoa::SolverConfig::default()
        };
        let Ok(fix) = tdoa::solve_moving(&signals, &moves, &config) else {
            return false;
        };
        if fix.quality != tdoa::Quality::Good || !fix.rejected.is_empty() {
            return false;
        }
        let (fx, fy) = (fix.position_m.x, fix.position_m.y);
        if self.params.floor.is_some_and(|f| !f.contains(fx, fy)) {
            return false;
        }
        let cov = fix.covariance_xy_m2();
        // One self-consistent cycle can still be a coincidence of
        // reflections: the fixes of two different cycles must agree (within
        // their noise and the distance driven between them).
        let chain_start = arrivals[0].t_s;
        let sigma = cov.trace().max(0.0).sqrt();
        let state_xy_m = self
            .state
            .filter(|_| known_motion)
            .map(|(x, _)| [x[X], x[Y]]);
        let mut candidate = Candidate {
            chain_start_s: chain_start,
            t_s,
            xy_m: [fx, fy],
            sigma_m: sigma,
            agreeing_before: 0,
            agreeing_since_s: t_s,
            state_xy_m,
        };
        match self.candidate {
            Some(c) if c.chain_start_s != chain_start => {
                let (dx, dy) = (fx - c.xy_m[0], fy - c.xy_m[1]);
                // With the motion known, the fixes must have moved as the
                // filter did (a kidnapped robot's fixes do: both are at the
                // new place); two cycles that share one place's reflections
                // but not the robot's motion do not. Without it, as far as
                // the robot can have driven.
                let (apart, slack) = match (state_xy_m, c.state_xy_m) {
                    (Some(now), Some(then)) => {
                        let (mx, my) = (now[0] - then[0], now[1] - then[1]);
                        (
                            (dx - mx).hypot(dy - my),
                            CANDIDATE_MOTION_SLACK * mx.hypot(my),
                        )
                    }
                    _ => (dx.hypot(dy), self.speed_m_s.abs() * (t_s - c.t_s).abs()),
                };
                if apart > 3.0 * (sigma + c.sigma_m) + slack {
                    self.candidate = Some(candidate);
                    return false;
                }
                candidate.agreeing_before = c.agreeing_before + 1;
                candidate.agreeing_since_s = c.agreeing_since_s;
            }
            Some(_) => return false,
            None => {
                self.candidate = Some(candidate);
                return false;
            }
        }
        let agreeing = candidate.agreeing_before + 1;
        self.candidate = None;
        let tracking = self.heading_from_track.is_none();
        if let (true, Some((x, p))) = (tracking, &self.state) {
            // The consistent cycles put the robot where the filter has it:
            // it is not displaced (its arrivals only disagreed with its
            // model for a while), so there is nothing to jump to.
            let own = (p[(X, X)] + p[(Y, Y)]).max(0.0).sqrt();
            if (fx - x[X]).hypot(fy - x[Y]) <= 3.0 * (sigma + own) {
                self.lost = false;
                self.start_confirmed = true;
                self.watch = RejectionWatch::default();
                return false;
            }
            let span_s = candidate.t_s - candidate.agreeing_since_s;
            // A start whose arrivals mostly agree with it is not replaced
            // by cycles that merely agree with each other: near a rack end
            // several cycles share one place's reflections (`warehouse`, 16
            // robots at 6 cycles/s, seed 7: a right start moved 0.26 m,
            // then 0.9 m, wrong for 10 s). A restarted MSU on a robot that
            // drove away has nearly all its arrivals gated.
            if span_s < AGREEING_SPAN_AGAINST_A_START_S
                || (!self.start_confirmed
                    && (agreeing < AGREEING_CYCLES_AGAINST_A_START
                        || self.gated_share < START_DOUBTED_GATED_SHARE))
            {
                // Not yet: the next consistent cycle may confirm the start
                // (or the tracked state).
                self.candidate = Some(candidate);
                return false;
            }
            if !self.start_confirmed {
                // The start pose was wrong (an MSU restarted on a robot
                // that had driven away): its heading is no better than its
                // position, so start as without one, at the consistent fix.
                self.state = None;
            }
        }
        self.start_confirmed = true;
        let cov = [[cov[(0, 0)], cov[(0, 1)]], [cov[(1, 0)], cov[(1, 1)]]];
        let extra = self.params.reinit_heading_sigma_deg.to_radians().powi(2);
        match &mut self.state {
            Some((x, p)) => {
                let from = [x[X], x[Y]];
                gs::reset_position(x, p, [fx, fy], cov, if tracking { extra } else { 0.0 });
                if !tracking {
                    // Still starting: not an event, and the chord of an
                    // unknown heading starts again (the jump is no motion).
                    self.heading_from_track = Some(None);
                } else if self.reinits.len() >= MAX_REINITS_KEPT {
                    self.reinits.remove(0);
                }
                if tracking {
                    self.reinits.push(Reinitialisation {
                        t_s,
                        from_m: from,
                        to_m: [fx, fy],
                    });
                }
            }
            None => {
                let mut x = State::zeros();
                x[X] = fx;
                x[Y] = fy;
                let mut p = prior(&self.params, 1.0, PI);
                gs::reset_position(&mut x, &mut p, [fx, fy], cov, 0.0);
                self.state = Some((x, p));
                self.clocks.clear();
                self.heading_from_track = Some(None);
                self.heard.clear();
            }
        }
        // The state moved under the chain's offset: set it again; the
        // blame was measured against a state now known to be wrong.
        self.offset_ready = false;
        self.late.clear();
        self.lost = false;
        self.gated_share = 0.0;
        self.watch = RejectionWatch::default();
        let last = *self.chain.arrivals().last().unwrap_or(&Arrival {
            tx_m: [0.0; 3],
            rho_m: 0.0,
            t_s,
            clock: None,
        });
        self.offset_from(&last, config.sigma_range_m);
        self.last_outcome = Some(Outcome::Accepted {
            innovation_m: 0.0,
            normalised: 0.0,
        });
        true
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
        let sxy = self.params.start_sigma_xy_m;
        let mut x = State::zeros();
        x[X] = cx;
        x[Y] = cy;
        self.state = Some((x, prior(&self.params, sxy, PI)));
        self.clocks.clear();
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
        if p[(X, X)].max(p[(Y, Y)]).sqrt() > self.params.settled_sigma_m {
            return;
        }
        let Some(start) = track else {
            *track = Some(TrackStart {
                x_m: x[X],
                y_m: x[Y],
                turn_rad: 0.0,
            });
            return;
        };
        let (dx, dy) = (x[X] - start.x_m, x[Y] - start.y_m);
        if dx.hypot(dy) < self.params.heading_chord_m {
            return;
        }
        x[TH] = dy.atan2(dx) + 0.5 * start.turn_rad;
        let v = self.params.track_heading_sigma_deg.to_radians().powi(2);
        for k in 0..gs::N {
            if k != TH {
                p[(k, TH)] = 0.0;
                p[(TH, k)] = 0.0;
            }
        }
        p[(TH, TH)] = v;
        self.heading_from_track = None;
    }

    /// Fuses the receiver-id heading of one MSU fix.
    fn fix(&mut self, f: &tdoa::Fix) {
        let sigma = self.params.heading_sigma_deg.to_radians();
        let (Some(heading), true) = (f.heading_rad, sigma > 0.0) else {
            return;
        };
        // A lost filter's heading waits for its position; an unconfirmed
        // start pose is no lost filter (the heading is measured as well).
        if self.heading_from_track.is_some() || (self.lost && self.start_confirmed) {
            return;
        }
        let Some((x, p)) = self.state else {
            return;
        };
        let mut h = Row::zeros();
        h[TH] = 1.0;
        let nu = angle::diff(heading, x[TH]);
        let r = sigma * sigma;
        let s = gs::innovation_variance(&p, &h, r);
        if nu.abs() > self.params.gate_sigma * s.sqrt() {
            return;
        }
        if let Some(next) = gs::update(&x, &p, &h, nu, r) {
            self.state = Some(next);
        }
    }

    /// Fuses one absolute range `range_m` (standard deviation `sigma_m`)
    /// to a beacon at `beacon_m` (`x, y`, same height as the antenna),
    /// measured at `t_s`, read as `(1 + scale) d + bias` with both estimated. Late (long)
    /// ranges are down-weighted and rejected like late arrivals.
    pub fn range(&mut self, t_s: f64, beacon_m: [f64; 2], range_m: f64, sigma_m: f64) -> Outcome {
        let out = self.range_update(t_s, beacon_m, range_m, sigma_m);
        self.t_s = self.t_s.max(t_s);
        self.last_outcome = Some(out);
        out
    }

    fn range_update(
        &mut self,
        t_s: f64,
        beacon_m: [f64; 2],
        range_m: f64,
        sigma_m: f64,
    ) -> Outcome {
        if ![t_s, beacon_m[0], beacon_m[1], range_m]
            .iter()
            .all(|v| v.is_finite())
        {
            return Outcome::Rejected(Rejection::NonFinite { field: "range" });
        }
        if !(sigma_m.is_finite() && sigma_m > 0.0) {
            return Outcome::Rejected(Rejection::BadSigma { sigma_m });
        }
        let Some((x, p)) = self.state else {
            return Outcome::Rejected(Rejection::NotInitialised);
        };
        let at = self.position_at(&x, t_s);
        let (dx, dy) = (at.x - beacon_m[0], at.y - beacon_m[1]);
        let d = dx.hypot(dy);
        if d < 1e-6 {
            return Outcome::Rejected(Rejection::Numerical);
        }
        let k = 1.0 + x[RANGE_SCALE];
        let mut h = Row::zeros();
        h[X] = k * dx / d;
        h[Y] = k * dy / d;
        h[RANGE_BIAS] = 1.0;
        h[RANGE_SCALE] = d;
        let nu = range_m - k * d - x[RANGE_BIAS];
        let r = sigma_m * sigma_m;
        let s = gs::innovation_variance(&p, &h, r);
        let normalised = nu / s.sqrt();
        if normalised.abs() > self.params.gate_sigma {
            // Only a range far shorter than predicted (impossible for a
            // late, non-direct path) is evidence of a lost filter.
            self.note(normalised < 0.0);
            return Outcome::Rejected(Rejection::Gate {
                normalised: normalised.abs(),
            });
        }
        let soft = self.params.late_soft_sigma;
        let r = if normalised > soft {
            r + s * ((normalised / soft).powi(2) - 1.0)
        } else {
            r
        };
        match gs::update(&x, &p, &h, nu, r) {
            Some(next) => {
                self.state = Some(next);
                self.note(false);
                self.adapt(normalised);
                self.project_on_floor();
                Outcome::Accepted {
                    innovation_m: nu,
                    normalised: normalised.abs(),
                }
            }
            None => Outcome::Rejected(Rejection::Numerical),
        }
    }

    /// A position off the floor is impossible: it is moved onto its edge.
    fn project_on_floor(&mut self) {
        let (Some(floor), Some((x, _))) = (self.params.floor, &mut self.state) else {
            return;
        };
        x[X] = x[X].clamp(floor.min_m[0], floor.max_m[0]);
        x[Y] = x[Y].clamp(floor.min_m[1], floor.max_m[1]);
    }
}

/// The prior covariance: position and heading as given, the calibration
/// states at their data-sheet uncertainty.
fn prior(params: &TdoaEkfParams, sigma_xy_m: f64, sigma_theta_rad: f64) -> Cov {
    let n = &params.sensors;
    let bias = if params.use_gyro {
        n.gyro_bias_sigma_deg_s
    } else {
        // Without a gyro the turn bias is the wheels' drift: start it at
        // the same sheet value, the data will tell.
        n.gyro_bias_sigma_deg_s
    }
    .to_radians();
    let v = sigma_xy_m * sigma_xy_m;
    let mut d = State::zeros();
    d[X] = v;
    d[Y] = v;
    d[TH] = sigma_theta_rad * sigma_theta_rad;
    d[BIAS] = bias * bias;
    d[SCALE] = n.distance_scale_sigma.powi(2);
    d[OFFSET] = 1.0;
    d[RANGE_BIAS] = n.range_bias_sigma_m.powi(2);
    d[RANGE_SCALE] = n.range_scale_sigma.powi(2);
    d[TURN_SCALE] = turn_scale_sigma(params).powi(2);
    // A slot not in use is uncorrelated with everything (one, like the
    // offset's, keeps the covariance positive definite).
    let clock = n.clock_bias_sigma_m();
    for c in CLOCK..gs::N {
        d[c] = if clock > 0.0 { clock * clock } else { 1.0 };
    }
    Cov::from_diagonal(&d)
}

/// The data sheet's scale error of the heading source.
fn turn_scale_sigma(params: &TdoaEkfParams) -> f64 {
    let n = &params.sensors;
    if params.use_gyro {
        n.gyro_scale_error
    } else {
        n.wheel_heading_rad_per_rad
    }
}

impl InOrderFilter for TdoaEkf {
    fn name(&self) -> &'static str {
        "tdoa-ekf"
    }

    fn step(&mut self, input: &Input) {
        match input {
            Input::Gyro(g) => self.gyro_sample(g.t_s, g.rate_rad_s),
            Input::Odometry(_) | Input::Encoders(_) => self.relative(input),
            Input::RangeDifference(m) => {
                let outcome = self.range_difference(m);
                if outcome.is_accepted() {
                    self.heard_lately.note(m.t_s, m.a_m);
                    self.heard_lately.note(m.t_s, m.b_m);
                }
                self.last_outcome = Some(outcome);
            }
            Input::Fix(f) => self.fix(f),
            Input::Range(_) => return,
        }
        self.t_s = self.t_s.max(input.t_s());
    }

    fn pose(&self) -> Option<PoseEstimate> {
        let (x, p) = self.state?;
        // The position moved on to the newest input's time (the last step
        // may be a wheel period older).
        let at = self.position_at(&x, self.t_s);
        let mut covariance = p.fixed_view::<3, 3>(0, 0).into_owned();
        let survey_sigma_m = self.params.sensors.survey_sigma_m;
        if let Some(c) = self.heard_lately.covariance(self.t_s, at, survey_sigma_m) {
            let mut xy = covariance.fixed_view_mut::<2, 2>(0, 0);
            xy += c;
        }
        Some(PoseEstimate {
            t_s: self.t_s,
            x_m: at.x,
            y_m: at.y,
            theta_rad: angle::wrap_pi(x[TH]),
            covariance,
        })
    }
}
