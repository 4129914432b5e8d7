//! What a fix says of the arrivals it did not use: each one's pseudo-range
//! residual against the fix's position and common offset. A transmitter
//! knocked out of place is rejected by the fix's gates, then left out by
//! the central unit; its residuals from many places are what tells where
//! it went ([`ickon_proto::msg::robot::Fix::unused_residuals_m`]).

use ickon_fusion::tdoa;
use nalgebra::Vector3;

use crate::assembly::Signal;

/// The transmitters of `rejected` that have a signal in `heard` (the
/// signals of the cycle, in parts: those solved with, those left out;
/// their pseudo-ranges as the fix's were taken: lateness removed), the
/// first one found of each transmitter, each with its
/// residual `rho - |s - p| - b` against `fix`, in the order of `rejected`,
/// each id once. A residual that is not a number is left out.
///
/// The receiver is taken at the fix's position for every signal: the
/// motion within the cycle (centimetres at a robot's speed) is not
/// corrected, as it is not for the used signals' published residuals.
pub(crate) fn measured(
    fix: &tdoa::Fix,
    heard: &[&[Signal]],
    rejected: &[u32],
) -> (Vec<u32>, Vec<f64>) {
    let mut ids = Vec::new();
    let mut residuals = Vec::new();
    for &id in rejected {
        if ids.contains(&id) {
            continue;
        }
        let Some(s) = heard
            .iter()
            .flat_map(|part| part.iter())
            .find(|s| s.tx_id == id)
        else {
            continue;
        };
        let range = (Vector3::from(s.tx_m) - fix.position_m).norm();
        let residual = s.pseudo_range_m - range - fix.bias_m;
        if residual.is_finite() {
            ids.push(id);
            residuals.push(residual);
        }
    }
    (ids, residuals)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::time::Time;

    fn signal(tx_id: u32, tx_m: [f64; 3], range_m: f64, offset_m: f64) -> Signal {
        Signal {
            tx_id,
            tx_m,
            pseudo_range_m: range_m + offset_m,
            receiver_id: 0,
            offset_s: 0.0,
            t_arrival: Time::from_nanos(0),
            clock: 0,
        }
    }

    #[test]
    fn a_moved_transmitters_residual_is_its_range_change_and_others_are_skipped() {
        let p = Vector3::new(2.0, 1.0, 0.3);
        let mut fix = tdoa::Fix::from_position(0.0, p.x, p.y, nalgebra::Matrix2::identity());
        fix.position_m = p;
        fix.bias_m = 1.5;
        let surveyed = [5.0, 1.0, 3.3];
        let moved = [5.3, 1.0, 3.3];
        let true_range = (Vector3::from(moved) - p).norm();
        let near = [2.0, 4.0, 3.3];
        let signals = [
            signal(7, surveyed, true_range, 1.5),
            signal(8, near, (Vector3::from(near) - p).norm() + 0.02, 1.5),
        ];
        // 9 was heard but never reached the solver (no signal): not measured;
        // 7 is listed twice (rejected by a gate and left out): once.
        let (ids, residuals) = measured(&fix, &[&signals[..]], &[9, 7, 8, 7]);
        assert_eq!(ids, [7, 8]);
        let expected = true_range - (Vector3::from(surveyed) - p).norm();
        assert!((residuals[0] - expected).abs() < 1e-12, "{residuals:?}");
        assert!(expected > 0.2, "the move lengthens the path: {expected}");
        assert!((residuals[1] - 0.02).abs() < 1e-12);
    }

    #[test]
    fn a_signal_left_out_of_the_fix_is_measured_from_its_own_part() {
        let p = Vector3::new(2.0, 1.0, 0.3);
        let mut fix = tdoa::Fix::from_position(0.0, p.x, p.y, nalgebra::Matrix2::identity());
        fix.position_m = p;
        let (a, b) = ([2.0, 4.0, 3.3], [5.0, 1.0, 3.3]);
        let solved = [signal(8, a, (Vector3::from(a) - p).norm() + 0.02, 0.0)];
        let left_out = [signal(7, b, (Vector3::from(b) - p).norm() - 0.03, 0.0)];
        let (ids, residuals) = measured(&fix, &[&solved, &left_out], &[7, 8]);
        assert_eq!(ids, [7, 8]);
        assert!((residuals[0] + 0.03).abs() < 1e-12, "{residuals:?}");
        assert!((residuals[1] - 0.02).abs() < 1e-12, "{residuals:?}");
    }

    #[test]
    fn a_residual_that_is_not_a_number_is_left_out() {
        let fix = tdoa::Fix::from_position(0.0, 0.0, 0.0, nalgebra::Matrix2::identity());
        let mut s = signal(3, [1.0, 0.0, 3.0], 3.0, 0.0);
        s.pseudo_range_m = f64::NAN;
        assert_eq!(measured(&fix, &[&[s][..]], &[3]), (vec![], vec![]));
    }
}
