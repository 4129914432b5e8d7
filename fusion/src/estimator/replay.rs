//! Out-of-order handling shared by every estimator: a short history of
//! inputs with the state before each, so that a late input is applied at its
//! own time and the later inputs are replayed on top of it.
//!
//! Inputs with equal times keep their arrival order. The history covers the
//! last `history_s` seconds before the newest input; an input older than
//! that is rejected with [`EstimatorError::TooLate`]. With the default 2 s
//! and a 100 Hz gyro a late fix replays at most ~220 cheap steps.

use std::collections::VecDeque;

use super::{Estimator, EstimatorError, Input, PoseEstimate, checked_covariance};

/// An estimator's state machine, fed strictly in time order by [`Replay`].
pub trait Core: Clone + Send {
    /// Registry name.
    fn name(&self) -> &'static str;
    /// Applies one validated input, not older than any input applied before.
    fn step(&mut self, input: &Input);
    /// The current estimate (before the final sanity check).
    fn pose(&self) -> Option<PoseEstimate>;
}

/// Wraps a [`Core`] into an [`Estimator`] that accepts late inputs.
#[derive(Debug, Clone)]
pub struct Replay<C: Core> {
    initial: C,
    current: C,
    history_s: f64,
    /// Each input with the state just before it, oldest first.
    history: VecDeque<(Input, C)>,
    /// Time of the newest input dropped from the history: nothing older can
    /// be inserted any more.
    floor_s: f64,
}

impl<C: Core> Replay<C> {
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
            .map_or(f64::NEG_INFINITY, |(input, _)| input.t_s())
    }

    /// Inserts `input` at its time; returns the new state and the rebuilt
    /// tail of the history, or `None` if the result is numerically invalid.
    fn apply(&self, input: &Input) -> Option<Rebuilt<C>> {
        let t = input.t_s();
        // First entry strictly newer than the input: it goes just before it.
        let at = self.history.partition_point(|(i, _)| i.t_s() <= t);
        let mut state = match self.history.get(at) {
            Some((_, before)) => before.clone(),
            None => self.current.clone(),
        };
        let mut tail = Vec::with_capacity(self.history.len() - at + 1);
        for next in std::iter::once(input).chain(self.history.range(at..).map(|(i, _)| i)) {
            tail.push((next.clone(), state.clone()));
            state.step(next);
        }
        sane(&state).then_some(Rebuilt { state, at, tail })
    }

    fn trim(&mut self) {
        let oldest_kept = self.newest_s() - self.history_s;
        while let Some((input, _)) = self.history.front() {
            if input.t_s() >= oldest_kept {
                break;
            }
            self.floor_s = input.t_s();
            self.history.pop_front();
        }
    }
}

/// The outcome of inserting an input: the new current state, where the
/// history was cut, and the rebuilt entries from there on.
struct Rebuilt<C> {
    state: C,
    at: usize,
    tail: Vec<(Input, C)>,
}

fn sane<C: Core>(core: &C) -> bool {
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

impl<C: Core> Estimator for Replay<C> {
    fn name(&self) -> &'static str {
        self.current.name()
    }

    fn handle(&mut self, input: &Input) -> Result<(), EstimatorError> {
        input.validate()?;
        let t_s = input.t_s();
        if t_s < self.floor_s || (t_s < self.newest_s() - self.history_s) {
            return Err(EstimatorError::TooLate {
                t_s,
                oldest_s: self.floor_s.max(self.newest_s() - self.history_s),
            });
        }
        let Rebuilt { state, at, tail } =
            self.apply(input).ok_or(EstimatorError::Numerical { t_s })?;
        self.history.truncate(at);
        self.history.extend(tail);
        self.current = state;
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
