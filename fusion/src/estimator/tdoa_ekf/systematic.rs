//! The part of the position error that no number of cycles averages away.
//!
//! The filter fuses every arrival as if its error were new each time. Two
//! errors are not: where each transmitter really hangs differs from the
//! survey by the survey's accuracy, and that difference is the same every
//! cycle the robot spends in one place. Fusing more cycles shrinks the
//! filter's covariance without shrinking that error, so the covariance
//! alone claims millimetres where the error is centimetres.
//!
//! The published covariance therefore adds the covariance a single fix
//! from the transmitters heard in the last second would have with range
//! errors of the survey's sigma (the CRLB of [`crate::tdoa::crlb`], the
//! common offset eliminated): the survey's error as this geometry projects
//! it onto the position. The state itself is not changed, so the estimate
//! is the same; only what it says about itself is.

use std::collections::VecDeque;

use nalgebra::{Matrix2, Vector3};

use crate::tdoa;

/// How long a transmitter counts as heard, seconds: two cycles or more at
/// the schedules of `lab` and `warehouse`.
const WINDOW_S: f64 = 1.0;

/// At most this many transmitters are kept (the newest).
const MAX_TRANSMITTERS: usize = 32;

/// The transmitters heard lately, for the systematic part of the covariance.
#[derive(Debug, Clone, Default)]
pub(super) struct HeardLately {
    /// `(last heard, position)`, oldest first, one entry per position.
    heard: VecDeque<(f64, [f64; 3])>,
}

impl HeardLately {
    /// Notes that the transmitter at `tx_m` was used at `t_s`.
    pub(super) fn note(&mut self, t_s: f64, tx_m: [f64; 3]) {
        if !(t_s.is_finite() && tx_m.iter().all(|v| v.is_finite())) {
            return;
        }
        self.heard.retain(|(_, p)| *p != tx_m);
        self.heard.push_back((t_s, tx_m));
        while self.heard.len() > MAX_TRANSMITTERS {
            self.heard.pop_front();
        }
    }

    /// The `x, y` covariance, m^2, that range errors of `sigma_m` on the
    /// transmitters heard within [`WINDOW_S`] before `now_s` give a fix at
    /// `position_m` (the receiver height in its `z`); `None` when fewer than
    /// three were heard or the geometry fixes no position.
    pub(super) fn covariance(
        &self,
        now_s: f64,
        position_m: Vector3<f64>,
        sigma_m: f64,
    ) -> Option<Matrix2<f64>> {
        if sigma_m.is_nan() || sigma_m <= 0.0 {
            return None;
        }
        let tx: Vec<Vector3<f64>> = self
            .heard
            .iter()
            .filter(|(t, _)| now_s - t <= WINDOW_S)
            .map(|(_, p)| Vector3::from(*p))
            .collect();
        if tx.len() < 3 {
            return None;
        }
        let mode = tdoa::Mode::TwoD {
            height_m: position_m.z,
        };
        let bound = tdoa::crlb(&tx, position_m, sigma_m, mode).ok()?;
        let c = bound.covariance_m2.fixed_view::<2, 2>(0, 0).into_owned();
        c.iter().all(|v| v.is_finite()).then_some(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> [[f64; 3]; 4] {
        [
            [0.0, 0.0, 3.0],
            [4.0, 0.0, 3.0],
            [4.0, 4.0, 3.0],
            [0.0, 4.0, 3.0],
        ]
    }

    #[test]
    fn a_centred_robot_under_four_transmitters_gets_about_the_survey_sigma() {
        let mut h = HeardLately::default();
        for (k, p) in square().into_iter().enumerate() {
            h.note(k as f64 * 0.1, p);
        }
        let c = h
            .covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.01)
            .unwrap();
        let rms_m = c.trace().sqrt();
        // Four transmitters round the robot: the CRLB is of the order of
        // the range error, not millimetres.
        assert!((0.005..0.05).contains(&rms_m), "{rms_m}");
        // Doubling the survey error doubles the floor.
        let c2 = h
            .covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.02)
            .unwrap();
        assert!((c2.trace().sqrt() / rms_m - 2.0).abs() < 1e-9);
    }

    #[test]
    fn old_or_too_few_transmitters_give_no_floor() {
        let mut h = HeardLately::default();
        for p in square().into_iter().take(2) {
            h.note(0.0, p);
        }
        assert!(
            h.covariance(0.1, Vector3::new(2.0, 2.0, 0.5), 0.01)
                .is_none()
        );
        for p in square() {
            h.note(0.0, p);
        }
        assert!(
            h.covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.01)
                .is_some()
        );
        assert!(
            h.covariance(1.5, Vector3::new(2.0, 2.0, 0.5), 0.01)
                .is_none()
        );
        assert!(
            h.covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.0)
                .is_none()
        );
    }

    #[test]
    fn a_transmitter_heard_again_is_kept_once_and_garbage_is_ignored() {
        let mut h = HeardLately::default();
        for k in 0..100 {
            h.note(f64::from(k), [1.0, 2.0, 3.0]);
        }
        h.note(f64::NAN, [0.0, 0.0, 3.0]);
        h.note(1.0, [f64::INFINITY, 0.0, 3.0]);
        assert_eq!(h.heard.len(), 1);
        for k in 0..100 {
            h.note(1.0, [f64::from(k), 0.0, 3.0]);
        }
        assert_eq!(h.heard.len(), MAX_TRANSMITTERS);
    }
}
