//! The part of the position error that no number of cycles averages away.
//!
//! The filter fuses every arrival as if its error were new each time. Two
//! errors are not: where each transmitter really hangs differs from the
//! survey by the survey's accuracy, and that difference is the same every
//! cycle the robot spends in one place. Fusing more cycles shrinks the
//! filter's covariance without shrinking that error, so the covariance
//! alone claims millimetres where the error is centimetres.
//!
//! The same holds for the speed of sound: the air the MSU turns arrival
//! times into ranges with is known only to the temperature it assumes,
//! and a speed off by a fraction scales every range by it, cycle after
//! cycle. And for a draft: sound is faster along it and slower against
//! it, so each range is off by the wind along its path, the same while
//! the robot stays in the draft.
//!
//! The published covariance therefore adds the covariance a single fix
//! from the transmitters heard in the last second would have with range
//! errors of the survey's sigma, a speed of sound off by its sigma and a
//! wind of its sigma (the common offset eliminated): these errors as this
//! geometry projects them onto the position. The state itself is not changed, so the estimate
//! is the same; only what it says about itself is.

use std::collections::VecDeque;

use nalgebra::{DMatrix, DVector, Matrix2, Vector3};

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

    /// The `x, y` covariance, m^2, that a fix at `position_m` (the
    /// receiver height in its `z`) from the transmitters heard within
    /// [`WINDOW_S`] before `now_s` has from the errors no cycle averages
    /// away: independent range errors on each transmitter of
    /// `survey_sigma_m` and of the variance `unexplained_m2` its arrivals
    /// showed beyond what the filter predicted (air the site-wide speed of
    /// sound does not follow: warm and cold spots), a speed of sound off
    /// by the relative `speed_rel_sigma`, which scales every range at
    /// once, and a wind of `wind_rel_sigma` of the speed of sound along
    /// each horizontal axis. `None` when fewer than three were heard or
    /// the geometry fixes no position.
    pub(super) fn covariance(
        &self,
        now_s: f64,
        position_m: Vector3<f64>,
        survey_sigma_m: f64,
        unexplained_m2: f64,
        air: AirErrors,
    ) -> Option<Matrix2<f64>> {
        let valid = |v: f64| v.is_finite() && v >= 0.0;
        if !(valid(survey_sigma_m)
            && valid(air.speed_rel_sigma)
            && valid(air.wind_rel_sigma)
            && !unexplained_m2.is_nan())
            || survey_sigma_m + air.speed_rel_sigma + air.wind_rel_sigma <= 0.0
        {
            return None;
        }
        let tx: Vec<Vector3<f64>> = self
            .heard
            .iter()
            .filter(|(t, _)| now_s - t <= WINDOW_S)
            .map(|(_, p)| Vector3::from(*p))
            .collect();
        if tx.len() < 3 || !position_m.iter().all(|v| v.is_finite()) {
            return None;
        }
        // A fix absorbs part of each transmitter's error into its own three
        // unknowns: what its arrivals show is about `(n - 3) / n` of it.
        let n = tx.len() as f64;
        let shown = ((n - 3.0) / n).max(0.25);
        let sigma_m = (survey_sigma_m.powi(2) + unexplained_m2.max(0.0) / shown).sqrt();
        fix_covariance(&tx, position_m, sigma_m, air)
    }
}

/// The errors of the air every range of a fix shares, over the speed of
/// sound.
#[derive(Debug, Clone, Copy)]
pub(super) struct AirErrors {
    /// Sigma of the speed's relative error: `k r_i` on each range `r_i`.
    pub(super) speed_rel_sigma: f64,
    /// Sigma of the wind along each horizontal axis: `u . h_i` on each
    /// range, `h_i` the horizontal path from the transmitter.
    pub(super) wind_rel_sigma: f64,
}

/// The covariance of the least-squares fix `(x, y, offset)` from
/// pseudo-ranges to `tx` whose errors are independent with sigma
/// `survey_sigma_m` plus the air's errors common to the fix: `M S M'` with
/// `M = (A'A)^-1 A'`, rows of `A` the horizontal unit vectors from each
/// transmitter and a one for the offset. The independent part alone is
/// the CRLB of [`crate::tdoa::crlb`]. A speed error is not absorbed by the
/// offset where the ranges differ, which is where the robot is off the
/// middle of what it hears; a wind is not absorbed anywhere: from paths
/// of similar length it is a shift of the fix along it.
fn fix_covariance(
    tx: &[Vector3<f64>],
    position_m: Vector3<f64>,
    survey_sigma_m: f64,
    air: AirErrors,
) -> Option<Matrix2<f64>> {
    let n = tx.len();
    let mut a = DMatrix::<f64>::zeros(n, 3);
    let mut ranges = DVector::<f64>::zeros(n);
    let mut paths = DMatrix::<f64>::zeros(n, 2);
    for (i, s) in tx.iter().enumerate() {
        let d = position_m - s;
        let r = d.norm();
        let h = d.xy();
        if r.is_nan() || r <= 1e-6 {
            return None;
        }
        a[(i, 0)] = h.x / r;
        a[(i, 1)] = h.y / r;
        a[(i, 2)] = 1.0;
        ranges[i] = r;
        paths[(i, 0)] = h.x;
        paths[(i, 1)] = h.y;
    }
    let info = a.transpose() * &a;
    let m = info.try_inverse()? * a.transpose();
    let mut s = DMatrix::<f64>::identity(n, n) * survey_sigma_m.powi(2);
    s += &ranges * ranges.transpose() * air.speed_rel_sigma.powi(2);
    s += &paths * paths.transpose() * air.wind_rel_sigma.powi(2);
    let c = &m * s * m.transpose();
    let c = Matrix2::new(c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]);
    c.iter().all(|v| v.is_finite()).then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tdoa;

    fn air(speed_rel_sigma: f64, wind_rel_sigma: f64) -> AirErrors {
        AirErrors {
            speed_rel_sigma,
            wind_rel_sigma,
        }
    }

    fn speed_only(speed_rel_sigma: f64) -> AirErrors {
        AirErrors {
            speed_rel_sigma,
            wind_rel_sigma: 0.0,
        }
    }

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
            .covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.01, 0.0, air(0.0, 0.0))
            .unwrap();
        let rms_m = c.trace().sqrt();
        // Four transmitters round the robot: the CRLB is of the order of
        // the range error, not millimetres.
        assert!((0.005..0.05).contains(&rms_m), "{rms_m}");
        // Doubling the survey error doubles the floor.
        let c2 = h
            .covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.02, 0.0, air(0.0, 0.0))
            .unwrap();
        assert!((c2.trace().sqrt() / rms_m - 2.0).abs() < 1e-9);
    }

    #[test]
    fn without_a_speed_error_it_is_the_crlb() {
        let tx: Vec<Vector3<f64>> = square().into_iter().map(Vector3::from).collect();
        for at in [Vector3::new(2.0, 2.0, 0.5), Vector3::new(0.7, 3.1, 0.5)] {
            let c = fix_covariance(&tx, at, 0.01, speed_only(0.0)).unwrap();
            let bound = tdoa::crlb(&tx, at, 0.01, tdoa::Mode::TwoD { height_m: 0.5 }).unwrap();
            let b = bound.covariance_m2.fixed_view::<2, 2>(0, 0).into_owned();
            assert!((c - b).norm() < 1e-12 * b.norm(), "{c} {b}");
        }
    }

    #[test]
    fn a_speed_error_costs_nothing_in_the_middle_and_grows_off_it() {
        let tx: Vec<Vector3<f64>> = square().into_iter().map(Vector3::from).collect();
        let middle = Vector3::new(2.0, 2.0, 0.5);
        let survey = fix_covariance(&tx, middle, 0.01, speed_only(0.0)).unwrap();
        let both = fix_covariance(&tx, middle, 0.01, speed_only(0.002)).unwrap();
        // Equal ranges: the offset takes the whole scale error.
        assert!((both - survey).norm() < 1e-12, "{both} {survey}");
        let corner = Vector3::new(0.5, 0.5, 0.5);
        let survey = fix_covariance(&tx, corner, 0.01, speed_only(0.0)).unwrap();
        let both = fix_covariance(&tx, corner, 0.01, speed_only(0.002)).unwrap();
        let speed = fix_covariance(&tx, corner, 0.0, speed_only(0.002)).unwrap();
        assert!((both - survey - speed).norm() < 1e-12);
        // Ranges of 2.6 to 5.2 m, 0.2 % off: millimetres towards the corner.
        let rms_mm = speed.trace().sqrt() * 1e3;
        assert!((1.0..20.0).contains(&rms_mm), "{rms_mm}");
    }

    #[test]
    fn a_draft_shifts_the_fix_even_in_the_middle() {
        let tx: Vec<Vector3<f64>> = square().into_iter().map(Vector3::from).collect();
        let middle = Vector3::new(2.0, 2.0, 0.5);
        let survey = fix_covariance(&tx, middle, 0.01, speed_only(0.0)).unwrap();
        let wind = AirErrors {
            speed_rel_sigma: 0.0,
            wind_rel_sigma: 0.5 / 343.0,
        };
        let windy = fix_covariance(&tx, middle, 0.01, wind).unwrap();
        let draft = windy - survey;
        // Equal paths of 3.77 m (2.83 m across, 2.5 m up): the wind moves
        // every range as a shift of the robot by `r w / c` moves it, 5.5 mm
        // along each axis, which no offset takes up (a speed error costs
        // nothing here).
        let r_m = (8.0_f64 + 2.5 * 2.5).sqrt();
        let expected_mm = r_m * 0.5 / 343.0 * 1e3;
        for k in 0..2 {
            let sigma_mm = draft[(k, k)].sqrt() * 1e3;
            assert!(
                (sigma_mm - expected_mm).abs() < 1e-6,
                "{sigma_mm} {expected_mm}"
            );
        }
        assert!(draft[(0, 1)].abs() < 1e-12);
        // Through the heard-lately window, as the filter publishes it.
        let mut h = HeardLately::default();
        for p in square() {
            h.note(0.0, p);
        }
        let published = h
            .covariance(0.5, middle, 0.01, 0.0, air(0.0, 0.5 / 343.0))
            .unwrap();
        assert!((published - windy).norm() < 1e-15);
    }

    #[test]
    fn unexplained_variance_widens_it_by_what_the_fixes_hide() {
        let mut h = HeardLately::default();
        for p in square() {
            h.note(0.0, p);
        }
        let at = Vector3::new(1.5, 2.5, 0.5);
        let survey = h.covariance(0.5, at, 0.01, 0.0, air(0.0, 0.0)).unwrap();
        // Four transmitters: a fix shows a quarter of each one's error, so
        // 1 cm^2 shown is 4 cm^2 in all, 5 cm^2 with the survey's.
        let wider = h.covariance(0.5, at, 0.01, 1e-4, air(0.0, 0.0)).unwrap();
        assert!((wider.trace() / survey.trace() - 5.0).abs() < 1e-9);
        // A negative estimate (arrivals better than predicted) narrows nothing.
        let same = h.covariance(0.5, at, 0.01, -1e-4, air(0.0, 0.0)).unwrap();
        assert_eq!(same, survey);
    }

    #[test]
    fn old_or_too_few_transmitters_give_no_floor() {
        let mut h = HeardLately::default();
        for p in square().into_iter().take(2) {
            h.note(0.0, p);
        }
        assert!(
            h.covariance(0.1, Vector3::new(2.0, 2.0, 0.5), 0.01, 0.0, air(0.0, 0.0))
                .is_none()
        );
        for p in square() {
            h.note(0.0, p);
        }
        assert!(
            h.covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.01, 0.0, air(0.0, 0.0))
                .is_some()
        );
        assert!(
            h.covariance(1.5, Vector3::new(2.0, 2.0, 0.5), 0.01, 0.0, air(0.0, 0.0))
                .is_none()
        );
        assert!(
            h.covariance(0.5, Vector3::new(2.0, 2.0, 0.5), 0.0, 0.0, air(0.0, 0.0))
                .is_none()
        );
        assert!(
            h.covariance(
                0.5,
                Vector3::new(2.0, 2.0, 0.5),
                0.01,
                0.0,
                air(f64::NAN, 0.0)
            )
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
