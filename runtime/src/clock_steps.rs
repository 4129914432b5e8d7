//! Clock steps at run time, for `ickon sim --faults clockstep:NODE@T+STEP`
//! (simulation only).
//!
//! A node started with `--sim-clock-steps-us 5000,-200` steps its
//! [`SimulatedClock`] by the next step of that list each time it receives
//! SIGUSR1 (the supervisor sends it at the planned time). Why a signal and
//! a list given at start:
//! - nothing on the network can step a clock: a control key would be one
//!   more message any client of the mesh can forge, a signal comes only from the same user or root on the machine;
//! - the steps are fixed by whoever started the node and bounded like
//!   `--clock-offset-us`: a signal carries no value to forge;
//! - a node started without the flag installs no handler, so it behaves
//!   as it always did (SIGUSR1's default action ends it), and a real site's
//!   nodes never have it.
//!
//! Signals beyond the list change nothing (counted in the log).

use std::sync::atomic::{AtomicUsize, Ordering};

use crate::clock::SimulatedClock;

/// The largest step, microseconds: the bound of `--clock-offset-us`.
const MAX_STEP_US: f64 = 1e9;

/// The steps of `--sim-clock-steps-us`, nanoseconds, in order (one flag
/// value: clap would take a bare `Vec` for a repeated flag).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StepList(pub Vec<i64>);

/// `--sim-clock-steps-us` as a [`StepList`].
pub fn parse_step_list(text: &str) -> Result<StepList, String> {
    parse_steps_us(text).map(StepList)
}

/// Parses `--sim-clock-steps-us`: a comma-separated list of finite steps in
/// microseconds, each within 1000 s either way; returns nanoseconds.
pub fn parse_steps_us(text: &str) -> Result<Vec<i64>, String> {
    text.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            let v: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
            if v.is_finite() && v.abs() <= MAX_STEP_US {
                Ok((v * 1e3).round() as i64)
            } else {
                Err(format!(
                    "`{s}`: a step must be a finite number of at most {MAX_STEP_US} us either way"
                ))
            }
        })
        .collect()
}

/// The steps still to take, in order.
#[derive(Debug)]
pub struct ClockSteps {
    steps: Vec<i64>,
    next: AtomicUsize,
}

impl ClockSteps {
    /// Steps to take in this order.
    pub fn new(steps: Vec<i64>) -> Self {
        Self {
            steps,
            next: AtomicUsize::new(0),
        }
    }

    /// Takes the next step on `clock`; returns it, or `None` when every
    /// step was taken.
    pub fn take_next(&self, clock: &SimulatedClock) -> Option<i64> {
        let i = self.next.fetch_add(1, Ordering::Relaxed);
        let step = *self.steps.get(i)?;
        clock.step(step);
        Some(step)
    }
}

/// Takes the next of `steps` on `clock` at each SIGUSR1, for the life of
/// the process (spawned on the current Tokio runtime). Nothing is
/// installed for an empty list.
pub fn listen(steps: Vec<i64>, clock: SimulatedClock) -> Result<(), std::io::Error> {
    if steps.is_empty() {
        return Ok(());
    }
    use tokio::signal::unix::{SignalKind, signal};
    let mut usr1 = signal(SignalKind::user_defined1())?;
    let steps = ClockSteps::new(steps);
    tokio::spawn(async move {
        while usr1.recv().await.is_some() {
            match steps.take_next(&clock) {
                Some(step) => tracing::warn!(
                    "clock stepped by {} us (simulated fault); {} us in all",
                    step as f64 / 1e3,
                    clock.stepped_ns() as f64 / 1e3
                ),
                None => tracing::warn!("SIGUSR1 beyond the planned clock steps: ignored"),
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::time::Time;

    #[test]
    fn steps_are_read_in_microseconds_and_bounded() {
        assert_eq!(parse_steps_us("5000, -200"), Ok(vec![5_000_000, -200_000]));
        assert_eq!(parse_steps_us("0.5"), Ok(vec![500]));
        for bad in ["NaN", "inf", "1e16", "5ms", "-1e10"] {
            assert!(parse_steps_us(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn each_step_is_taken_once_in_order_then_nothing() {
        let clock = SimulatedClock::new(Time(0), 0, 0.0).with_own_steps();
        let steps = ClockSteps::new(vec![5_000_000, -2_000_000]);
        assert_eq!(steps.take_next(&clock), Some(5_000_000));
        assert_eq!(steps.take_next(&clock), Some(-2_000_000));
        assert_eq!(steps.take_next(&clock), None);
        assert_eq!(clock.stepped_ns(), 3_000_000);
    }

    #[test]
    fn a_signal_steps_the_clock() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let clock = SimulatedClock::new(Time(0), 0, 0.0).with_own_steps();
            listen(vec![5_000_000], clock).unwrap();
            nix::sys::signal::raise(nix::sys::signal::Signal::SIGUSR1).unwrap();
            for _ in 0..200 {
                if clock.stepped_ns() != 0 {
                    break;
                }
                tokio::time::sleep(std::time::Duration::from_millis(5)).await;
            }
            assert_eq!(clock.stepped_ns(), 5_000_000);
        });
    }
}
