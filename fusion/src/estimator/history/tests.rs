//! The checkpointed history against the order it must reproduce: every
//! accepted input applied in time order (equal times in arrival order).

use proptest::prelude::*;

use super::*;
use crate::estimator::GyroSample;
use nalgebra::Matrix3;

/// A rate that makes the recorder's pose not a number.
const POISON_RAD_S: f64 = 99.0;

/// Records the inputs it was stepped with, in order.
#[derive(Debug, Clone, Default)]
struct Recorder {
    applied: Vec<(f64, f64)>,
}

impl InOrderFilter for Recorder {
    fn name(&self) -> &'static str {
        "recorder"
    }

    fn step(&mut self, input: &Input) {
        if let Input::Gyro(g) = input {
            self.applied.push((g.t_s, g.rate_rad_s));
        }
    }

    fn pose(&self) -> Option<PoseEstimate> {
        let poisoned = self.applied.iter().any(|&(_, r)| r == POISON_RAD_S);
        Some(PoseEstimate {
            t_s: self.applied.last().map_or(0.0, |a| a.0),
            x_m: if poisoned { f64::NAN } else { 0.0 },
            y_m: 0.0,
            theta_rad: 0.0,
            covariance: Matrix3::identity(),
        })
    }
}

fn gyro(t_s: f64, rate_rad_s: f64) -> Input {
    Input::Gyro(GyroSample { t_s, rate_rad_s })
}

/// Feeds `(time, tag)` inputs and checks, after each, the recorder against
/// the accepted inputs sorted stably by time, and each refusal's reason.
fn check(inputs: &[(f64, f64)], history_s: f64) -> Result<(), TestCaseError> {
    let mut replay = LateInputHistory::new(Recorder::default(), history_s);
    let mut accepted: Vec<(f64, f64)> = Vec::new();
    for &(t_s, tag) in inputs {
        let newest = accepted
            .iter()
            .map(|a| a.0)
            .fold(f64::NEG_INFINITY, f64::max);
        match replay.handle(&gyro(t_s, tag)) {
            Ok(()) => {
                prop_assert!(t_s >= newest - history_s, "{t_s} accepted, newest {newest}");
                prop_assert!(tag != POISON_RAD_S);
                accepted.push((t_s, tag));
            }
            Err(EstimatorError::TooLate { .. }) => {
                prop_assert!(t_s < newest - history_s, "{t_s} refused, newest {newest}");
            }
            Err(EstimatorError::Numerical { .. }) => prop_assert_eq!(tag, POISON_RAD_S),
            Err(e) => prop_assert!(false, "unexpected {e}"),
        }
        let mut expected = accepted.clone();
        expected.sort_by(|a, b| a.0.total_cmp(&b.0));
        prop_assert_eq!(&replay.core().applied, &expected);
        prop_assert!(replay.history.front().is_none_or(|e| e.before.is_some()));
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Inputs mostly in order, some late (some beyond the history), some at
    /// equal times, a few poisoned: the state is always the accepted inputs
    /// in time order.
    #[test]
    fn late_inputs_are_applied_at_their_time(
        steps in prop::collection::vec((0u32..12, 0u32..10, 0u32..260, 0u32..40), 1..400),
    ) {
        let mut clock_s = 0.0;
        let inputs: Vec<(f64, f64)> = steps
            .iter()
            .enumerate()
            .map(|(i, &(dt_ms, late_kind, late_cs, poison))| {
                clock_s += f64::from(dt_ms) * 1e-3;
                let late_s = if late_kind < 7 { 0.0 } else { f64::from(late_cs) * 0.01 };
                let tag = if poison == 0 { POISON_RAD_S } else { 1000.0 + i as f64 };
                (clock_s - late_s, tag)
            })
            .collect();
        check(&inputs, 2.0)?;
    }
}

#[test]
fn a_history_of_zero_seconds_takes_equal_times_and_refuses_older_ones() {
    check(
        &[(1.0, 0.0), (1.0, 1.0), (0.99, 2.0), (1.5, 3.0), (1.5, 4.0)],
        0.0,
    )
    .unwrap();
}

#[test]
fn a_poisoned_input_changes_nothing_in_order_or_late() {
    let mut inputs: Vec<(f64, f64)> = (0..100)
        .map(|i| (f64::from(i) * 0.01, 1000.0 + f64::from(i)))
        .collect();
    // In order, right after a checkpoint and between two.
    inputs.push((1.0, POISON_RAD_S));
    inputs.push((1.05, POISON_RAD_S));
    // Late, into the middle of the history.
    inputs.push((0.555, POISON_RAD_S));
    inputs.push((1.06, 200.0));
    inputs.push((0.2, 201.0));
    check(&inputs, 2.0).unwrap();
}

#[test]
fn the_history_keeps_a_state_per_checkpoint_not_per_input() {
    let mut replay = LateInputHistory::new(Recorder::default(), 2.0);
    // 150 inputs a second for 10 s, each tenth one 0.3 s late.
    for i in 0..1500 {
        let t_s = f64::from(i) / 150.0;
        let t_s = if i % 10 == 9 { t_s - 0.3 } else { t_s };
        replay.handle(&gyro(t_s, 1000.0 + f64::from(i))).unwrap();
    }
    let states = replay.history.iter().filter(|e| e.before.is_some()).count();
    let span_s = replay.newest_s() - replay.history.front().unwrap().input.t_s();
    // The history's 2 s, reaching back at most to the checkpoint before.
    assert!(
        (2.0 - 0.01..2.0 + CHECKPOINT_S + 0.01).contains(&span_s),
        "{span_s}"
    );
    // One per checkpoint interval, and the late inputs' own.
    assert!(
        states <= 2 * (span_s / CHECKPOINT_S).ceil() as usize + 1,
        "{states}"
    );
    assert!(replay.history.len() > 250, "{}", replay.history.len());
}
