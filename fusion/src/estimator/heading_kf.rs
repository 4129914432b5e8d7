//! The ICKON paper, section 3.2.1, the heading fusion unit: a scalar Kalman filter
//! on the heading `gamma`.
//!
//! - Dynamics (eq. 7): `gamma_{k+1} = gamma_k + d_gamma + w`, where
//!   `d_gamma` is the backward difference of the relative unit's heading
//!   (`gamma_b`), `w ~ N(0, sigma_w^2)`, `sigma_w = 2 deg` per step.
//! - Observation (eq. 8): `gamma_g = gamma_k + v`, `v ~ N(0, sigma_v^2)`,
//!   `sigma_v = 30 deg` ("exaggerated to be on the safe side").
//! - Before the correction the MSU heading is re-expressed by whole turns
//!   towards the prediction (the paper's "angle conversion block"), with
//!   [`crate::angle::unwrap_towards`]. The state itself is kept continuous
//!   (never wrapped), so a robot turning in circles never sees a 360 deg
//!   jump; it is wrapped only on output.
//!
//! Ambiguity: the seed gives `sigma_w` per step without a step length; we
//! apply it once per relative-positioning sample (the paper's robot reported
//! at ~10 Hz), and scale nothing by time.

use nalgebra::{Matrix1, Vector1};

use super::kf;
use crate::angle;

/// Parameters of the heading filter (the ICKON paper's values by default).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingKfParams {
    /// Process noise per relative-positioning step, `sigma_w`, in degrees.
    pub sigma_w_deg: f64,
    /// Noise of the MSU (receiver-id) heading, `sigma_v`, in degrees.
    pub sigma_v_deg: f64,
    /// Standard deviation of the heading before any MSU heading, in degrees.
    pub initial_sigma_deg: f64,
}

impl Default for HeadingKfParams {
    fn default() -> Self {
        Self {
            sigma_w_deg: 2.0,
            sigma_v_deg: 30.0,
            initial_sigma_deg: 180.0,
        }
    }
}

/// Scalar heading Kalman filter (eq. 7-8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingKf {
    params: HeadingKfParams,
    /// Continuous (unwrapped) heading estimate, radians.
    gamma_rad: f64,
    /// Variance of `gamma_rad`, rad^2.
    var_rad2: f64,
}

impl HeadingKf {
    /// A filter starting at `gamma_rad` with standard deviation `sigma_rad`.
    pub fn new(params: HeadingKfParams, gamma_rad: f64, sigma_rad: f64) -> Self {
        Self {
            params,
            gamma_rad,
            var_rad2: sigma_rad * sigma_rad,
        }
    }

    /// A filter that knows nothing yet: heading 0 with the configured
    /// (large) initial uncertainty, so that the first MSU heading dominates.
    pub fn uninformed(params: HeadingKfParams) -> Self {
        Self::new(params, 0.0, params.initial_sigma_deg.to_radians())
    }

    /// Continuous heading estimate, radians (not wrapped).
    pub fn heading_rad(&self) -> f64 {
        self.gamma_rad
    }

    /// Variance of the heading, rad^2.
    pub fn variance_rad2(&self) -> f64 {
        self.var_rad2
    }

    /// Prediction step, eq. 7, with the relative heading change `d_gamma_rad`.
    pub fn predict(&mut self, d_gamma_rad: f64) {
        let q = self.params.sigma_w_deg.to_radians().powi(2);
        self.gamma_rad += d_gamma_rad;
        self.var_rad2 = kf::predict(
            &Matrix1::new(self.var_rad2),
            &Matrix1::new(1.0),
            &Matrix1::new(q),
        )[(0, 0)];
    }

    /// Correction step, eq. 8, with the MSU heading (any representation).
    /// Returns `false` if the update was numerically refused.
    pub fn correct(&mut self, gamma_g_rad: f64) -> bool {
        let r = self.params.sigma_v_deg.to_radians().powi(2);
        let z = angle::unwrap_towards(gamma_g_rad, self.gamma_rad);
        match kf::update(
            &Vector1::new(self.gamma_rad),
            &Matrix1::new(self.var_rad2),
            &Matrix1::new(1.0),
            &Matrix1::new(r),
            &Vector1::new(z - self.gamma_rad),
        ) {
            Some((x, p)) => {
                self.gamma_rad = x[0];
                self.var_rad2 = p[(0, 0)];
                true
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_steps_match_hand_computation() {
        let params = HeadingKfParams::default();
        let mut f = HeadingKf::new(params, 0.0, 10.0_f64.to_radians());
        f.predict(5.0_f64.to_radians());
        // P = 100 + 4 = 104 deg^2; K = 104 / (104 + 900) = 0.103586;
        // z = 20 deg, innovation = 15 deg -> gamma = 5 + 1.553785 deg.
        let p_deg2: f64 = 104.0;
        let k = p_deg2 / (p_deg2 + 900.0);
        assert!((f.variance_rad2() - p_deg2.to_radians().to_radians()).abs() < 1e-12);
        f.correct(20.0_f64.to_radians());
        let expected = 5.0 + k * 15.0;
        assert!((f.heading_rad().to_degrees() - expected).abs() < 1e-9);
        let expected_p = (1.0 - k) * p_deg2;
        assert!((f.variance_rad2().to_degrees().to_degrees() - expected_p).abs() < 1e-9);
    }

    #[test]
    fn msu_heading_is_unwrapped_towards_prediction() {
        // Prediction at 179 deg, MSU says -179 deg: the innovation is +2 deg,
        // not -358 deg.
        let mut f = HeadingKf::new(HeadingKfParams::default(), 179.0_f64.to_radians(), 0.1);
        f.correct((-179.0_f64).to_radians());
        let h = f.heading_rad().to_degrees();
        assert!(h > 179.0 && h < 181.0, "heading {h}");
    }

    #[test]
    fn circling_for_ten_minutes_stays_continuous() {
        let mut f = HeadingKf::new(HeadingKfParams::default(), 0.0, 0.01);
        let step = 30.0_f64.to_radians() * 0.1; // 30 deg/s at 10 Hz
        let mut truth = 0.0_f64;
        for k in 0..6000 {
            truth += step;
            f.predict(step);
            if k % 3 == 0 {
                f.correct(angle::wrap_pi(truth));
            }
            assert!((f.heading_rad() - truth).abs() < 1e-6, "jump at step {k}");
        }
    }
}
