//! The ground-robot filter behind [`crate::estimator::Estimator`], one
//! tightly coupled EKF for every absolute sensor a ground robot carries.
//!
//! - State ([`super::ground_state`]): position, heading, the turn-rate bias
//!   of the heading source (gyro, or wheels without one), the distance
//!   scale of the wheels, the pseudo-range offset of the cycle being fused,
//!   and the bias and scale error of absolute radio ranges.
//! - Prediction at the wheels' rate: the arc of the CDA paper with the distance
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
//! - The receiver-id heading of the ICKON paper (eq. 4-6), carried by the MSU
//!   fixes, as a heading measurement with its honest `heading_sigma_deg`
//!   (30 deg: half a 60 deg sector plus the beams' overlap); the fixes'
//!   positions are not fused (the filter already has their arrivals).
//! - Absolute ranges to beacons ([`TdoaEkf::range`] for radio beacons at
//!   the antenna's height, [`crate::estimator::Input::BeaconRange`] for
//!   beacons anywhere, e.g. a Marvelmind kit's ultrasonic distances) with
//!   the ranges' bias and scale estimated, for robots that range instead
//!   of timing differences.
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

use super::clock_slots::ClockSlots;
use super::ground_chain::Chain;
use super::ground_noise::GroundNoise;
use super::ground_state::{
    self as gs, BIAS, CLOCK, Cov, OFFSET, RANGE_BIAS, RANGE_SCALE, SCALE, SOUND_SCALE, State, TH,
    TURN_SCALE, X, Y,
};
use super::observation::Outcome;
use super::recovery::{RecoveryParams, RejectionWatch};
use super::standstill::Standstill;
use super::systematic::{AirErrors, HeardLately};
use crate::angle;
use crate::estimator::dead_reckoning::IncrementTracker;
use crate::estimator::guard::{LateArrivals, LateParams};
use crate::estimator::history::InOrderFilter;
use crate::estimator::{InitialPose, Input, PoseEstimate};

mod beacons;
mod floor;
mod gate;
mod predict;
mod range_start;
mod reinit;
mod start;

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
    /// Ranges to beacons heard before the start (no start pose).
    range_start: range_start::RangeStart,
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
    /// What the arrivals' errors have of variance beyond what the filter
    /// predicted, m^2 (see `ground/gate.rs`, `note_unexplained`).
    unexplained_m2: f64,
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
    /// The relative sigma of the speed of sound the newest range
    /// difference was computed with, when its source said.
    solved_speed_rel_sigma: Option<f64>,
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
            range_start: range_start::RangeStart::default(),
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
            unexplained_m2: 0.0,
            start_confirmed: false,
            tracking_since_s: None,
            candidate: None,
            last_outcome: None,
            reinits: Vec::new(),
            late: LateArrivals::new(params.late),
            gated_late: false,
            heard_lately: HeardLately::default(),
            clocks: ClockSlots::default(),
            solved_speed_rel_sigma: None,
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

    /// The learnt relative error of the speed of sound where the robot
    /// drives against the speed the MSU uses (positive: sound is faster),
    /// when the filter learns it.
    pub fn sound_scale(&self) -> Option<f64> {
        if !self.params.sensors.learns_local_air() {
            return None;
        }
        self.state.map(|(x, _)| x[SOUND_SCALE])
    }

    /// The learnt wind where the robot drives, `[east, north]`, m/s, when
    /// the filter learns it.
    pub fn local_wind_m_s(&self) -> Option<[f64; 2]> {
        if !self.params.sensors.learns_local_wind() {
            return None;
        }
        let c = super::ground_noise::NOMINAL_SPEED_OF_SOUND_M_S;
        self.state
            .map(|(x, _)| [x[gs::WIND_X] * c, x[gs::WIND_Y] * c])
    }

    /// The estimated distance scale error (travelled = measured times one
    /// plus it).
    pub fn distance_scale(&self) -> Option<f64> {
        self.state.map(|(x, _)| x[SCALE])
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
    // Unused (and so uncorrelated) when the local air is not learnt.
    d[SOUND_SCALE] = if n.learns_local_air() {
        n.local_air_rel_sigma().powi(2)
    } else {
        1.0
    };
    let wind = n.local_wind_rel_sigma();
    for k in [gs::WIND_X, gs::WIND_Y] {
        d[k] = if wind > 0.0 { wind * wind } else { 1.0 };
    }
    // A slot not in use is uncorrelated with everything (one, like the
    // offset's, keeps the covariance positive definite).
    let clock = n.clock_bias_sigma_m();
    for c in CLOCK..gs::N {
        d[c] = if clock > 0.0 { clock * clock } else { 1.0 };
    }
    Cov::from_diagonal(&d)
}

impl TdoaEkf {
    /// The relative error of the speed of sound that no state of the
    /// filter holds: the assumed temperature's, unless the local speed is
    /// learnt.
    pub(super) fn unmodelled_speed_rel_sigma(&self) -> f64 {
        let sensors = &self.params.sensors;
        if sensors.learns_local_air() {
            0.0
        } else {
            sensors.speed_of_sound_rel_sigma()
        }
    }

    /// The air's errors the published covariance adds (`systematic.rs`).
    /// The speed of sound the ranges are computed with is the site-wide
    /// one (the fleet's published speed, or the site file's), known only
    /// to its own sigma: the local speed state holds the air where the
    /// robot is against that speed, not that speed's own error, so the
    /// latter is counted here whether the state is on or not. Its sigma is
    /// the one the ranges came with (the fleet's, 0.5 % while it has
    /// learnt little, 0.15-0.3 % later), else the sheet's temperature's.
    fn systematic_air(&self) -> AirErrors {
        let sensors = &self.params.sensors;
        let speed_rel_sigma = if sensors.learns_local_air() {
            self.solved_speed_rel_sigma
                .unwrap_or_else(|| sensors.speed_of_sound_rel_sigma())
        } else {
            sensors.speed_of_sound_rel_sigma()
        };
        AirErrors {
            speed_rel_sigma,
            wind_rel_sigma: sensors.unmodelled_wind_rel_sigma(),
        }
    }
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
                if m.speed_rel_sigma.is_some() {
                    self.solved_speed_rel_sigma = m.speed_rel_sigma;
                }
                let outcome = self.range_difference(m);
                if outcome.is_accepted() {
                    self.heard_lately.note(m.t_s, m.a_m);
                    self.heard_lately.note(m.t_s, m.b_m);
                }
                self.last_outcome = Some(outcome);
            }
            Input::BeaconRange(r) => {
                if self.state.is_none() {
                    self.start_from_ranges(r);
                }
                let outcome = self.range_update(r.t_s, r.beacon_m, r.range_m, r.sigma_m);
                if outcome.is_accepted() {
                    self.heard_lately.note(r.t_s, r.beacon_m);
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
        let sensors = &self.params.sensors;
        if let Some(c) = self.heard_lately.covariance(
            self.t_s,
            at,
            sensors.survey_sigma_m,
            self.unexplained_m2,
            self.systematic_air(),
        ) {
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
