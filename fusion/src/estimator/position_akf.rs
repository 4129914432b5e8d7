//! The ICKON paper, section 3.2.3, the position fusion unit: a 2D adaptive Kalman
//! filter on `s = [x, y]`, shared by `ickon-akf`, `gyro-ckf` and `cda-msu`.
//!
//! - State model (eq. 12-14): `s_{k+1} = s_k + u_k + w`, `A = B = I`, with
//!   `u = [dx_hat_b, dy_hat_b]` the heading-corrected relative motion
//!   (eq. 10-11, computed by the caller).
//! - Process noise (eq. 15): `Q = diag(4, 4) mm^2` per relative step.
//! - Observation (eq. 16-18): `z = [x_g, y_g] = s + v`, `H = I`.
//! - Adaptive observation noise (eq. 19, residual-based):
//!   `R = c_pos diag((x - x_g)^2, (y - y_g)^2)`, `c_pos = 0.025`.
//!
//! Ambiguities and choices:
//! - Eq. 19's `x, y` is "the Kalman filter's output"; the posterior at time
//!   `k` needs `R` first, so we use the filter's output just before the
//!   correction (the prediction at the fix time). Note that this makes `R`
//!   proportional to the squared innovation: a far-off fix (a reflection)
//!   gets a tiny gain, as the seed intends.
//! - Floor on `R`: a fix that happens to agree with the prediction would give
//!   `R = 0`, hence gain 1 and a zero covariance; the filter would then lock
//!   onto that one fix and the covariance would stop being positive
//!   definite. Each diagonal term of `R` is therefore at least
//!   `r_floor_mm^2` (default 1 mm, well below the MSU noise, so the paper's
//!   behaviour is unchanged whenever the residual exceeds ~6 mm).
//! - Re-initialisation: the residual-based `R` makes the filter distrust
//!   large residuals, so after a long outage the drifted estimate would
//!   never be pulled back. If no fix was applied for `reinit_gap_s`
//!   (default 10 s), the next fix re-initialises the position at the fix with
//!   its own covariance (floored).
//! - The seed's units are millimetres; the state here is in metres and `Q`
//!   is converted.

use nalgebra::{Matrix2, Vector2};

use super::kf;
use crate::tdoa::Fix;

/// Parameters of the position AKF (the ICKON paper's values by default).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PositionAkfParams {
    /// Diagonal of `Q` per relative step, in mm^2 (eq. 15).
    pub q_mm2: f64,
    /// Coefficient `c_pos` of the residual-based `R` (eq. 19).
    pub c_pos: f64,
    /// Smallest standard deviation of a fix per axis, in mm (the floor on `R`).
    pub r_floor_mm: f64,
    /// Time without an applied fix after which the next fix re-initialises
    /// the position, in seconds.
    pub reinit_gap_s: f64,
}

impl Default for PositionAkfParams {
    fn default() -> Self {
        Self {
            q_mm2: 4.0,
            c_pos: 0.025,
            r_floor_mm: 1.0,
            reinit_gap_s: 10.0,
        }
    }
}

/// The adaptive position filter; empty until the first fix (or an explicit
/// initialisation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionAkf {
    params: PositionAkfParams,
    state: Option<(Vector2<f64>, Matrix2<f64>)>,
    last_fix_s: f64,
}

impl PositionAkf {
    /// An uninitialised filter.
    pub fn new(params: PositionAkfParams) -> Self {
        Self {
            params,
            state: None,
            last_fix_s: f64::NEG_INFINITY,
        }
    }

    /// Sets position and covariance (metres, m^2), for a known start pose.
    pub fn initialise(&mut self, x_m: f64, y_m: f64, covariance: Matrix2<f64>, t_s: f64) {
        self.state = Some((Vector2::new(x_m, y_m), self.floored(covariance)));
        self.last_fix_s = t_s;
    }

    /// Position and its covariance, if initialised.
    pub fn state(&self) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        self.state
    }

    /// Prediction, eq. 12-15, with the corrected relative motion in metres.
    pub fn predict(&mut self, dx_m: f64, dy_m: f64) {
        if let Some((s, p)) = &mut self.state {
            let q = self.params.q_mm2 * 1e-6;
            *s += Vector2::new(dx_m, dy_m);
            *p = kf::predict(p, &Matrix2::identity(), &Matrix2::from_diagonal_element(q));
        }
    }

    /// Correction, eq. 16-19, or (re-)initialisation at the fix when the
    /// filter is empty or the last fix is older than `reinit_gap_s`.
    /// Returns `false` if the update was numerically refused.
    pub fn correct(&mut self, fix: &Fix) -> bool {
        let z = Vector2::new(fix.x_m(), fix.y_m());
        let stale = fix.t_s - self.last_fix_s > self.params.reinit_gap_s;
        let Some((s, p)) = self.state.filter(|_| !stale) else {
            self.initialise(fix.x_m(), fix.y_m(), fix.covariance_xy_m2(), fix.t_s);
            return true;
        };
        let residual = z - s;
        let r = self.floored(Matrix2::new(
            self.params.c_pos * residual.x * residual.x,
            0.0,
            0.0,
            self.params.c_pos * residual.y * residual.y,
        ));
        match kf::update(&s, &p, &Matrix2::identity(), &r, &residual) {
            Some((s_new, p_new)) => {
                self.state = Some((s_new, p_new));
                self.last_fix_s = fix.t_s;
                true
            }
            None => false,
        }
    }

    /// Symmetrises and lifts the diagonal to the floor variance.
    fn floored(&self, m: Matrix2<f64>) -> Matrix2<f64> {
        let floor = (self.params.r_floor_mm * 1e-3).powi(2);
        let mut out = kf::symmetrise(m);
        out[(0, 0)] = out[(0, 0)].max(floor);
        out[(1, 1)] = out[(1, 1)].max(floor);
        if out.cholesky().is_none() {
            // A reported covariance that is not positive definite keeps only
            // its (floored) variances.
            out = Matrix2::from_diagonal(&out.diagonal());
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(t_s: f64, x_m: f64, y_m: f64) -> Fix {
        Fix::from_position(t_s, x_m, y_m, Matrix2::from_diagonal_element(1e-4))
    }

    #[test]
    fn adaptive_gain_matches_hand_computation() {
        let mut f = PositionAkf::new(PositionAkfParams::default());
        f.initialise(0.0, 0.0, Matrix2::from_diagonal_element(100e-6), 0.0);
        f.predict(0.1, 0.0);
        // P = 100 + 4 = 104 mm^2. Fix at (200, -50) mm from (100, 0) mm:
        // residual (100, -50) mm, R = 0.025 * (10000, 2500) = (250, 62.5) mm^2.
        f.correct(&fix(0.1, 0.2, -0.05));
        let (s, p) = f.state().unwrap();
        let kx = 104.0 / (104.0 + 250.0);
        let ky = 104.0 / (104.0 + 62.5);
        assert!((s.x * 1e3 - (100.0 + kx * 100.0)).abs() < 1e-9);
        assert!((s.y * 1e3 - (-ky * 50.0)).abs() < 1e-9);
        assert!((p[(0, 0)] * 1e6 - (1.0 - kx) * 104.0).abs() < 1e-9);
        assert!((p[(1, 1)] * 1e6 - (1.0 - ky) * 104.0).abs() < 1e-9);
    }

    #[test]
    fn exact_fix_keeps_covariance_positive_definite() {
        let mut f = PositionAkf::new(PositionAkfParams::default());
        f.initialise(1.0, 1.0, Matrix2::from_diagonal_element(1e-4), 0.0);
        for k in 1..100 {
            f.predict(0.0, 0.0);
            assert!(f.correct(&fix(f64::from(k) * 0.1, 1.0, 1.0)));
        }
        let (_, p) = f.state().unwrap();
        assert!(p.cholesky().is_some());
        assert!(p[(0, 0)] > 0.0);
    }

    #[test]
    fn fix_after_long_gap_reinitialises() {
        let mut f = PositionAkf::new(PositionAkfParams::default());
        f.initialise(0.0, 0.0, Matrix2::from_diagonal_element(1e-4), 0.0);
        // A fix 5 m away right away barely moves the filter (R ~ residual^2).
        f.correct(&fix(1.0, 5.0, 0.0));
        assert!(f.state().unwrap().0.x < 0.5);
        // The same after a 60 s outage re-initialises.
        f.correct(&fix(61.0, 5.0, 0.0));
        assert!((f.state().unwrap().0.x - 5.0).abs() < 1e-12);
    }
}
