//! The watch over a range-difference filter: it publishes nothing until a
//! consistent window of measurements has placed the filter, keeps the state
//! inside the flight volume, sets late anchors aside, and declares the
//! filter lost (then re-places it from a consistent window, or stops
//! publishing until one comes) when
//! - most recent measurements fail the gate,
//! - the state keeps pressing against the volume's walls,
//! - consistent windows keep placing the receiver elsewhere (a filter
//!   settled on a mirror solution passes its own gate), or
//! - time jumps (a gap in the stream, a clock stepped back or forth).
//!
//! Its worst moments are bounded by three rules:
//! - a measurement set aside as late counts against the state like one
//!   the gate refused: a state that explains only the anchors it kept is
//!   not confirmed by them (otherwise a wrong state sets aside the anchors
//!   that contradict it and slides on with the rest);
//! - anchors are blamed for late arrivals only once a consistent window
//!   has confirmed the state since it was last placed;
//! - a lost filter is re-placed only where the receiver can have gone
//!   since its last confirmed estimate at its top speed
//!   ([`LostParams::max_speed_m_s`]); a window farther away waits (the
//!   reach grows with time, so a wrong confirmed estimate does not hold the
//!   filter for ever), and nothing is published meanwhile;
//! - a filter that keeps tracking while lost (an IMU-driven one,
//!   [`GuardedFilter::tracks_while_lost`]) is resumed, not restarted, when
//!   it was lost for failing the gate and the window puts the receiver
//!   within [`LostParams::disagree_m`] of it:
//!   a lost verdict during a run of biased range differences says the run
//!   disagreed with the filter, and a window of that same run is no better
//!   a start than the height and velocity the IMU carried through it.
//!
//! Any filter implementing [`GuardedFilter`] can be watched: the 3D
//! constant-velocity and IMU filters of [`crate::estimator::flight`] do; a planar
//! filter can, by answering its position at its known height.

use nalgebra::{Matrix3, Vector3};

use super::late::{LateArrivals, LateParams};
use super::volume::FlightVolume;
use super::window::{Window, WindowFix, WindowParams};
use crate::estimator::RangeDifferenceSample;
use crate::estimator::tdoa_ekf::{Outcome, RecoveryParams, Rejection};

/// What the watch needs of a filter.
pub trait GuardedFilter {
    /// Moves the state to `t_s` (a time not after the state's: no change).
    fn predict_to(&mut self, t_s: f64);
    /// The receiver's position, metres.
    fn position_m(&self) -> Vector3<f64>;
    /// The standard deviation of the position, largest axis, metres.
    fn position_sigma_m(&self) -> f64;
    /// The covariance of [`Self::position_m`], m^2.
    fn position_covariance_m2(&self) -> Matrix3<f64>;
    /// The range difference the state predicts for `m`, metres.
    fn predicted_m(&self, m: &RangeDifferenceSample) -> Option<f64>;
    /// The gated update with `m` at the state's time.
    fn update(&mut self, m: &RangeDifferenceSample) -> Outcome;
    /// Restarts the position at `position_m` with `sigma_m` per axis, at
    /// rest within the filter's start velocity uncertainty, at time `t_s`.
    fn reset(&mut self, t_s: f64, position_m: Vector3<f64>, sigma_m: f64);
    /// Projects the state into `volume`; whether it was outside.
    fn constrain(&mut self, volume: &FlightVolume) -> bool;
    /// Whether the state keeps following the receiver while the watch
    /// holds it lost: a state driven by an IMU does, a constant-velocity
    /// extrapolation does not. Such a state, lost for failing the gate, is
    /// resumed, not restarted, when a window puts the receiver where it
    /// already is.
    fn tracks_while_lost(&self) -> bool {
        false
    }
}

/// When the filter counts as lost.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LostParams {
    /// The share of gate rejections that makes a filter lost (`window` and
    /// `rejected_share`; the watch re-places the filter from a window
    /// instead of widening it, so `sigma_m` is not used).
    pub rejections: RecoveryParams,
    /// Consecutive updates ending outside the volume that make it lost.
    pub outside_updates: u32,
    /// Consecutive windows placing the receiver elsewhere that make it
    /// lost.
    pub disagreeing_windows: u32,
    /// A window places the receiver elsewhere when it is further than this
    /// from the filter, metres (and than 3 combined standard deviations).
    pub disagree_m: f64,
    /// A gap between measurements longer than this, or time going back by
    /// more, restarts the filter, seconds.
    pub max_gap_s: f64,
    /// Standard deviation of the position when placed from a window, at
    /// least, metres.
    pub min_reset_sigma_m: f64,
    /// The receiver's top speed, m/s: a window may re-place a lost filter
    /// only where the receiver can have gone since its last confirmed
    /// estimate at this speed (within 3 combined standard deviations).
    pub max_speed_m_s: f64,
}

impl Default for LostParams {
    /// Gate rejections: over half of the last 50; 25 updates outside (a
    /// twentieth of a second of UWB); 3 windows in a row (0.3 s); 0.5 m
    /// (five times the UWB measurement noise, well beyond the 0.1 m a
    /// window smears over); 1 s (a constant-velocity prediction then
    /// carries up to a metre of error); 0.1 m; 3 m/s (a small multirotor
    /// flying indoors, taken from the class of vehicle before any flight
    /// was scored: faster than that it crosses a 7 m room in 2 s).
    fn default() -> Self {
        Self {
            rejections: RecoveryParams::default(),
            outside_updates: 25,
            disagreeing_windows: 3,
            disagree_m: 0.5,
            max_gap_s: 1.0,
            min_reset_sigma_m: 0.1,
            max_speed_m_s: 3.0,
        }
    }
}

/// Parameters of the watch.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GuardParams {
    /// The consistent window.
    pub window: WindowParams,
    /// Late anchors.
    pub late: LateParams,
    /// The lost filter.
    pub lost: LostParams,
}

/// Why the filter was declared lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LostReason {
    /// Most recent measurements failed the gate.
    Rejections,
    /// The state kept leaving the volume.
    Outside,
    /// Consistent windows placed the receiver elsewhere.
    Disagreement,
    /// Time jumped or the stream paused.
    TimeJump,
}

/// Counters of what the watch did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct GuardCounts {
    /// Lost for too many gate rejections.
    pub lost_rejections: u64,
    /// Lost for leaving the volume.
    pub lost_outside: u64,
    /// Lost for disagreeing with consistent windows.
    pub lost_disagreement: u64,
    /// Lost for a time jump.
    pub lost_time_jump: u64,
    /// Updates that ended outside the volume and were projected back.
    pub constrained: u64,
    /// Measurements not used because an anchor was set aside as late.
    pub set_aside: u64,
    /// Windows that were ambiguous (mirror solutions, no hint).
    pub ambiguous_windows: u64,
    /// Times the filter was placed from a window.
    pub placements: u64,
    /// Consistent windows not used to re-place the filter: farther from
    /// its last confirmed estimate than the receiver can have moved.
    pub unreachable_windows: u64,
    /// Times a lost filter that kept tracking was resumed where a window
    /// agreed with it instead of being re-placed.
    pub resumed: u64,
}

/// What one measurement did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The published estimate after it (none while not placed), metres.
    pub published_m: Option<[f64; 3]>,
    /// What the filter did with it (none when it was not offered: not
    /// placed yet, or a late anchor set aside).
    pub outcome: Option<Outcome>,
    /// Set when the filter was declared lost at this measurement.
    pub lost: Option<LostReason>,
}

/// A filter under watch.
#[derive(Debug, Clone)]
pub struct Guarded<F> {
    filter: F,
    volume: FlightVolume,
    params: GuardParams,
    window: Window,
    late: LateArrivals,
    watch_share: f64,
    watch_seen: u32,
    placed: bool,
    last_t_s: Option<f64>,
    last_check_s: f64,
    outside_run: u32,
    disagree_run: u32,
    trusted_m: Option<Vector3<f64>>,
    confirmed: Option<Confirmed>,
    confirmed_since_placed: bool,
    /// Why the filter was last declared lost (none before the first
    /// placement).
    lost_for: Option<LostReason>,
    counts: GuardCounts,
}

/// The last estimate a consistent window agreed with.
#[derive(Debug, Clone, Copy)]
struct Confirmed {
    t_s: f64,
    position_m: Vector3<f64>,
    sigma_m: f64,
}

impl<F: GuardedFilter> Guarded<F> {
    /// Watches `filter` in `volume`. `start_hint_m`, when given, is where
    /// the receiver starts (it settles a mirror ambiguity at the start).
    pub fn new(
        filter: F,
        volume: FlightVolume,
        params: GuardParams,
        start_hint_m: Option<[f64; 3]>,
    ) -> Self {
        Self {
            filter,
            volume,
            params,
            window: Window::new(params.window),
            late: LateArrivals::new(params.late),
            watch_share: 0.0,
            watch_seen: 0,
            placed: false,
            last_t_s: None,
            last_check_s: f64::NEG_INFINITY,
            outside_run: 0,
            disagree_run: 0,
            trusted_m: start_hint_m.map(Vector3::from),
            confirmed: None,
            confirmed_since_placed: false,
            lost_for: None,
            counts: GuardCounts::default(),
        }
    }

    /// The filter.
    pub fn filter(&self) -> &F {
        &self.filter
    }

    /// The filter, to feed it other sensors (an IMU) between measurements.
    pub fn filter_mut(&mut self) -> &mut F {
        &mut self.filter
    }

    /// Whether the filter is placed (its estimates are published).
    pub fn is_placed(&self) -> bool {
        self.placed
    }

    /// The flight volume.
    pub fn volume(&self) -> &FlightVolume {
        &self.volume
    }

    /// What the watch did so far.
    pub fn counts(&self) -> GuardCounts {
        self.counts
    }

    /// Feeds one measurement.
    pub fn step(&mut self, m: &RangeDifferenceSample) -> Step {
        let mut lost = None;
        if let Some(last) = self.last_t_s {
            let gap = self.params.lost.max_gap_s;
            if m.t_s - last > gap || last - m.t_s > gap {
                // The window holds the other side of the jump, and the
                // time of the last check is on the old clock.
                self.window.clear();
                self.last_check_s = f64::NEG_INFINITY;
                lost = self.lose(LostReason::TimeJump);
                // Also while already lost: a state from the old clock is
                // not resumed.
                self.lost_for = Some(LostReason::TimeJump);
            }
        }
        if self.last_t_s.is_none_or(|l| m.t_s > l) || lost.is_some() {
            self.last_t_s = Some(m.t_s);
        }
        if let Err(r) = crate::estimator::tdoa_ekf::check(m) {
            return self.finish(Some(Outcome::Rejected(r)), lost);
        }
        self.window.push(*m);
        if !self.placed {
            if m.t_s - self.last_check_s >= self.params.window.window_s {
                self.last_check_s = m.t_s;
                self.try_place(m.t_s, self.trusted_m);
            }
            return self.finish(None, lost);
        }
        self.filter.predict_to(m.t_s);
        if self.late.is_aside(m) {
            self.counts.set_aside += 1;
            // A measurement the state cannot use does not confirm it.
            if self.note_gate(true) {
                lost = self.lose(LostReason::Rejections);
                let hint = self.trusted_m;
                self.try_place(m.t_s, hint);
            }
            return self.finish(None, lost);
        }
        let innovation = self.filter.predicted_m(m).map(|p| m.d_m - p);
        let outcome = self.filter.update(m);
        let gated = matches!(outcome, Outcome::Rejected(Rejection::Gate { .. }));
        // Blame needs a state known to be right: a wrong state blames the
        // anchors that contradict it and sets aside the ones it needs.
        if self.confirmed_since_placed {
            self.late.note(m, innovation.filter(|_| gated));
        }
        if self.filter.constrain(&self.volume) {
            self.counts.constrained += 1;
            self.outside_run += 1;
        } else {
            self.outside_run = 0;
        }
        let reason = if self.note_gate(gated) {
            Some(LostReason::Rejections)
        } else if self.outside_run >= self.params.lost.outside_updates {
            Some(LostReason::Outside)
        } else if m.t_s - self.last_check_s >= self.params.window.window_s {
            self.last_check_s = m.t_s;
            self.check_against_window(m.t_s)
                .then_some(LostReason::Disagreement)
        } else {
            None
        };
        if let Some(reason) = reason {
            lost = self.lose(reason);
            let hint = self.trusted_m;
            self.try_place(m.t_s, hint);
        }
        self.finish(Some(outcome), lost)
    }

    fn finish(&self, outcome: Option<Outcome>, lost: Option<LostReason>) -> Step {
        let published_m = self.placed.then(|| self.filter.position_m().into());
        Step {
            published_m,
            outcome,
            lost,
        }
    }

    /// The running share of gate rejections; whether it says lost.
    fn note_gate(&mut self, rejected: bool) -> bool {
        let r = &self.params.lost.rejections;
        let alpha = 1.0 / f64::from(r.window.max(1));
        self.watch_share += alpha * (f64::from(u8::from(rejected)) - self.watch_share);
        self.watch_seen = self.watch_seen.saturating_add(1);
        self.watch_seen >= r.window && self.watch_share > r.rejected_share
    }

    /// Whether the window has disagreed with the filter for long enough.
    fn check_against_window(&mut self, t_s: f64) -> bool {
        let here = self.filter.position_m();
        match self.window.solve(&self.volume, Some(here)) {
            WindowFix::Fix {
                position_m,
                sigma_m,
            } => {
                let apart = (position_m - here).norm();
                let combined = (sigma_m.powi(2) + self.filter.position_sigma_m().powi(2)).sqrt();
                if apart > self.params.lost.disagree_m.max(3.0 * combined) {
                    self.disagree_run += 1;
                } else {
                    self.disagree_run = 0;
                    self.trusted_m = Some(here);
                    self.confirmed = Some(Confirmed {
                        t_s,
                        position_m: here,
                        sigma_m: combined,
                    });
                    self.confirmed_since_placed = true;
                }
            }
            WindowFix::Ambiguous { .. } => self.counts.ambiguous_windows += 1,
            WindowFix::Inconsistent => {}
        }
        self.disagree_run >= self.params.lost.disagreeing_windows
    }

    fn lose(&mut self, reason: LostReason) -> Option<LostReason> {
        if !self.placed {
            return None;
        }
        match reason {
            LostReason::Rejections => self.counts.lost_rejections += 1,
            LostReason::Outside => self.counts.lost_outside += 1,
            LostReason::Disagreement => self.counts.lost_disagreement += 1,
            LostReason::TimeJump => self.counts.lost_time_jump += 1,
        }
        self.placed = false;
        self.lost_for = Some(reason);
        Some(reason)
    }

    /// Places the filter from the window when it is consistent.
    fn try_place(&mut self, t_s: f64, hint: Option<Vector3<f64>>) {
        match self.window.solve(&self.volume, hint) {
            WindowFix::Fix {
                position_m,
                sigma_m,
            } => {
                let sigma = sigma_m.max(self.params.lost.min_reset_sigma_m);
                if let Some(c) = self.confirmed {
                    let reach_m = self.params.lost.max_speed_m_s * (t_s - c.t_s).abs()
                        + 3.0 * (c.sigma_m.powi(2) + sigma.powi(2)).sqrt();
                    if (position_m - c.position_m).norm() > reach_m {
                        self.counts.unreachable_windows += 1;
                        return;
                    }
                }
                if self.filter.tracks_while_lost() && self.lost_for == Some(LostReason::Rejections)
                {
                    self.filter.predict_to(t_s);
                    let apart = (self.filter.position_m() - position_m).norm();
                    if apart <= self.params.lost.disagree_m {
                        self.placed = true;
                        self.counts.resumed += 1;
                        self.watch_share = 0.0;
                        self.watch_seen = 0;
                        self.outside_run = 0;
                        self.disagree_run = 0;
                        return;
                    }
                }
                self.filter.reset(t_s, position_m, sigma);
                self.confirmed_since_placed = false;
                self.placed = true;
                self.counts.placements += 1;
                self.late.clear();
                self.watch_share = 0.0;
                self.watch_seen = 0;
                self.outside_run = 0;
                self.disagree_run = 0;
                self.trusted_m = Some(position_m);
            }
            WindowFix::Ambiguous { .. } => self.counts.ambiguous_windows += 1,
            WindowFix::Inconsistent => {}
        }
    }
}
