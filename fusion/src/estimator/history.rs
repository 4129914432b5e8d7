//! Out-of-order handling shared by every estimator: a short history of
//! inputs, so that a late input is applied at its own time and the later
//! inputs are replayed on top of it.
//!
//! Inputs with equal times keep their arrival order. The history covers the
//! last `history_s` seconds before the newest input; an input older than
//! that is rejected with [`EstimatorError::TooLate`]. With the default 2 s
//! and a 100 Hz gyro a late fix replays at most ~220 cheap steps.
//!
//! The state before an input is kept only at checkpoints, one every
//! [`CHECKPOINT_S`] of input time; a late input restores the checkpoint
//! before it and steps forward to its place. Keeping the state before
//! every input cost a copy of the whole filter per input: on an MSU of
//! `tdoa-ekf` most of its time went into those copies (each cycle's range
//! differences arrive late, one by one, and each rebuilt the states of
//! the 0.3 s of gyro and odometry after it). Stepping is deterministic, so
//! the states rebuilt from a checkpoint are the ones that were copied: the
//! results are the same to the bit.

use std::collections::VecDeque;

use super::{Estimator, EstimatorError, Input, PoseEstimate, checked_covariance};

/// Default seconds of input history kept for late inputs.
pub(crate) fn default_history_s() -> f64 {
    2.0
}

/// Input time between two kept states, seconds: a late input steps at most
/// this much further than it did when every state was kept (about 15 steps
/// of a 100 Hz gyro and 50 Hz wheels), while copies of the state fall from
/// one per input to one per checkpoint.
pub const CHECKPOINT_S: f64 = 0.1;

/// An estimator's state machine, fed strictly in time order by [`LateInputHistory`].
pub trait InOrderFilter: Clone + Send {
    /// Registry name.
    fn name(&self) -> &'static str;
    /// Applies one validated input, not older than any input applied before.
    fn step(&mut self, input: &Input);
    /// The current estimate (before the final sanity check).
    fn pose(&self) -> Option<PoseEstimate>;
}

/// One input of the history, with the state just before it at a checkpoint.
#[derive(Debug, Clone)]
struct Entry<C> {
    input: Input,
    before: Option<C>,
}

/// Wraps a [`InOrderFilter`] into an [`Estimator`] that accepts late inputs.
#[derive(Debug, Clone)]
pub struct LateInputHistory<C: InOrderFilter> {
    initial: C,
    current: C,
    history_s: f64,
    /// Each input, oldest first; the oldest always holds the state before
    /// it, later ones at checkpoints.
    history: VecDeque<Entry<C>>,
    /// Time of the newest input dropped from the history: nothing older can
    /// be inserted any more.
    floor_s: f64,
}

impl<C: InOrderFilter> LateInputHistory<C> {
    /// Wraps `core`, keeping `history_s` seconds of inputs (negative or
    /// non-finite values are read as 0: no late input is accepted).
    pub fn new(core: C, history_s: f64) -> Self {
        let history_s = if history_s.is_finite() {
            history_s.max(0.0)
        } else {
            0.0
        };
        Self {
            initial: core.clone(),
            current: core,
            history_s,
            history: VecDeque::new(),
            floor_s: f64::NEG_INFINITY,
        }
    }

    /// The wrapped state machine.
    pub fn core(&self) -> &C {
        &self.current
    }

    fn newest_s(&self) -> f64 {
        self.history
            .back()
            .map_or(f64::NEG_INFINITY, |e| e.input.t_s())
    }

    /// Time of the newest checkpoint, if any.
    fn newest_checkpoint_s(&self) -> Option<f64> {
        self.history
            .iter()
            .rev()
            .find(|e| e.before.is_some())
            .map(|e| e.input.t_s())
    }

    /// The state just before history entry `at` (or after the whole
    /// history when `at` is its length), rebuilt from the checkpoint
    /// before it; `None` only if the history lost its first checkpoint.
    fn state_before(&self, at: usize) -> Option<C> {
        if self.history.is_empty() {
            return Some(self.current.clone());
        }
        let from = (0..=at.min(self.history.len().saturating_sub(1)))
            .rev()
            .find(|&k| self.history[k].before.is_some())?;
        let mut state = self.history[from].before.clone()?;
        for e in self.history.range(from..at) {
            state.step(&e.input);
        }
        Some(state)
    }

    /// Appends an input no older than any in the history.
    fn push_in_order(&mut self, input: &Input) -> Result<(), EstimatorError> {
        let t_s = input.t_s();
        let checkpoint = self
            .newest_checkpoint_s()
            .is_none_or(|last| t_s - last >= CHECKPOINT_S);
        self.history.push_back(Entry {
            input: input.clone(),
            before: checkpoint.then(|| self.current.clone()),
        });
        self.current.step(input);
        if sane(&self.current) {
            return Ok(());
        }
        // Numerically invalid: back to the state before it, unchanged.
        let kept = self.history.pop_back().and_then(|e| e.before);
        self.current = match kept {
            Some(state) => state,
            None => self
                .state_before(self.history.len())
                .unwrap_or_else(|| self.initial.clone()),
        };
        Err(EstimatorError::Numerical { t_s })
    }

    /// Inserts `input` before history entry `at`; returns the new state and
    /// the rebuilt tail of the history, or `None` if the result is
    /// numerically invalid.
    fn insert_late(&self, input: &Input, at: usize) -> Option<Rebuilt<C>> {
        let mut state = self.state_before(at)?;
        // A checkpoint at `at` is the state the input now comes after: the
        // input's own entry takes it over (`None` forces it).
        let mut last_checkpoint_s = if self.history[at].before.is_some() {
            None
        } else {
            (0..at)
                .rev()
                .find(|&k| self.history[k].before.is_some())
                .map(|k| self.history[k].input.t_s())
        };
        let mut tail = Vec::with_capacity(self.history.len() - at + 1);
        for next in std::iter::once(input).chain(self.history.range(at..).map(|e| &e.input)) {
            let t_s = next.t_s();
            let checkpoint = last_checkpoint_s.is_none_or(|last| t_s - last >= CHECKPOINT_S);
            if checkpoint {
                last_checkpoint_s = Some(t_s);
            }
            tail.push(Entry {
                input: next.clone(),
                before: checkpoint.then(|| state.clone()),
            });
            state.step(next);
        }
        sane(&state).then_some(Rebuilt { state, at, tail })
    }

    /// Drops the inputs older than the history's span, keeping the
    /// checkpoint the oldest input kept needs.
    fn trim(&mut self) {
        let oldest_kept = self.newest_s() - self.history_s;
        let first_kept = self
            .history
            .partition_point(|e| e.input.t_s() < oldest_kept);
        let Some(cut) = (0..=first_kept.min(self.history.len().saturating_sub(1)))
            .rev()
            .find(|&k| self.history[k].before.is_some())
        else {
            return;
        };
        for _ in 0..cut {
            if let Some(e) = self.history.pop_front() {
                self.floor_s = e.input.t_s();
            }
        }
    }
}

/// The outcome of inserting an input: the new current state, where the
/// history was cut, and the rebuilt entries from there on.
struct Rebuilt<C> {
    state: C,
    at: usize,
    tail: Vec<Entry<C>>,
}

fn sane<C: InOrderFilter>(core: &C) -> bool {
    match core.pose() {
        None => true,
        Some(p) => {
            [p.t_s, p.x_m, p.y_m, p.theta_rad]
                .iter()
                .all(|v| v.is_finite())
                && checked_covariance(p.covariance).is_some()
        }
    }
}

impl<C: InOrderFilter> Estimator for LateInputHistory<C> {
    fn name(&self) -> &'static str {
        self.current.name()
    }

    fn handle(&mut self, input: &Input) -> Result<(), EstimatorError> {
        input.validate()?;
        let t_s = input.t_s();
        let oldest_s = self.floor_s.max(self.newest_s() - self.history_s);
        if t_s < oldest_s {
            return Err(EstimatorError::TooLate { t_s, oldest_s });
        }
        // First entry strictly newer than the input: it goes just before it.
        let at = self.history.partition_point(|e| e.input.t_s() <= t_s);
        if at == self.history.len() {
            self.push_in_order(input)?;
        } else {
            let Rebuilt { state, at, tail } = self
                .insert_late(input, at)
                .ok_or(EstimatorError::Numerical { t_s })?;
            self.history.truncate(at);
            self.history.extend(tail);
            self.current = state;
        }
        self.trim();
        Ok(())
    }

    fn pose(&self) -> Option<PoseEstimate> {
        let mut p = self.current.pose()?;
        p.theta_rad = crate::angle::wrap_pi(p.theta_rad);
        p.covariance = checked_covariance(p.covariance)?;
        Some(p)
    }

    fn reset(&mut self) {
        self.current = self.initial.clone();
        self.history.clear();
        self.floor_s = f64::NEG_INFINITY;
    }
}

#[cfg(test)]
mod tests;
