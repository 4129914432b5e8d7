//! `cv-fix`: a constant-velocity Kalman filter on the per-epoch fixes,
//! each weighted by the solver's own covariance (the loosely coupled
//! filter a system without odometry runs on its fixes).
//!
//! An epoch's arrival times share one unknown offset, so the range
//! differences they give are correlated through their common reference;
//! the solver accounts for that in its covariance, which the scalar
//! range-difference filters (fed one difference at a time) cannot.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

/// Default acceleration density, m^2/s^3: as `cv-ekf` (a mobile that
/// changes its velocity by about 1 m/s within a second).
pub const ACCEL_PSD_M2_S3: f64 = 1.0;
/// Innovation gate: the 99 % point of chi-square with 3 degrees of
/// freedom.
pub const GATE_CHI2: f64 = 11.34;
/// Fixes gated in a row after which the filter restarts at the next fix.
pub const RESTART_AFTER: u32 = 5;
/// Velocity uncertainty at a (re)start, m/s.
const START_VELOCITY_SIGMA_M_S: f64 = 1.0;
/// Variance given to an axis the fix does not solve (the known height of
/// a 2D fix), m^2: large against any position variance of the filter.
const UNSOLVED_AXIS_VARIANCE_M2: f64 = 1e6;

/// The filter.
#[derive(Debug, Clone)]
pub struct CvFix {
    accel_psd_m2_s3: f64,
    state: Option<(f64, Vector6<f64>, Matrix6<f64>)>,
    gated_in_row: u32,
    /// Fixes refused by the gate.
    pub gated: u64,
    /// Restarts after [`RESTART_AFTER`] refused fixes in a row.
    pub restarts: u64,
}

impl CvFix {
    /// A filter with acceleration density `accel_psd_m2_s3`.
    pub fn new(accel_psd_m2_s3: f64) -> Self {
        Self {
            accel_psd_m2_s3,
            state: None,
            gated_in_row: 0,
            gated: 0,
            restarts: 0,
        }
    }

    /// Fuses a fix at `t_s` with covariance `cov_m2`; the estimate then.
    pub fn step(
        &mut self,
        t_s: f64,
        p_m: [f64; 3],
        cov_m2: &Matrix3<f64>,
    ) -> Option<(f64, [f64; 3])> {
        let mut r = *cov_m2;
        for k in 0..3 {
            if r[(k, k)] <= 0.0 || !r[(k, k)].is_finite() {
                r[(k, k)] = UNSOLVED_AXIS_VARIANCE_M2;
            }
        }
        let z = Vector3::from(p_m);
        let Some((t0, x, p)) = self.state else {
            self.start(t_s, z, &r);
            return self.estimate();
        };
        let (x, p, t) = predict(x, p, t0, t_s, self.accel_psd_m2_s3);
        let h = SMatrix::<f64, 3, 6>::identity();
        let innovation = z - h * x;
        let s = h * p * h.transpose() + r;
        let Some(s_inv) = s.try_inverse() else {
            return self.estimate();
        };
        if (innovation.transpose() * s_inv * innovation)[0] > GATE_CHI2 {
            self.gated += 1;
            self.gated_in_row += 1;
            if self.gated_in_row >= RESTART_AFTER {
                self.restarts += 1;
                self.start(t_s, z, &r);
            } else {
                self.state = Some((t, x, p));
            }
            return self.estimate();
        }
        self.gated_in_row = 0;
        let k = p * h.transpose() * s_inv;
        let i_kh = Matrix6::identity() - k * h;
        // Joseph form: stays symmetric positive definite.
        let p = i_kh * p * i_kh.transpose() + k * r * k.transpose();
        self.state = Some((t, x + k * innovation, p));
        self.estimate()
    }

    fn start(&mut self, t_s: f64, z: Vector3<f64>, r: &Matrix3<f64>) {
        let mut p = Matrix6::zeros();
        p.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
        for k in 3..6 {
            p[(k, k)] = START_VELOCITY_SIGMA_M_S.powi(2);
        }
        let mut x = Vector6::zeros();
        x.fixed_rows_mut::<3>(0).copy_from(&z);
        self.state = Some((t_s, x, p));
        self.gated_in_row = 0;
    }

    fn estimate(&self) -> Option<(f64, [f64; 3])> {
        self.state.map(|(t, x, _)| (t, [x[0], x[1], x[2]]))
    }
}

/// The constant-velocity prediction from `t0` to `t1` (not backwards: an
/// older fix is applied at the state's time).
fn predict(
    x: Vector6<f64>,
    p: Matrix6<f64>,
    t0: f64,
    t1: f64,
    qa: f64,
) -> (Vector6<f64>, Matrix6<f64>, f64) {
    let dt = t1 - t0;
    if !dt.is_finite() || dt <= 0.0 {
        return (x, p, t0);
    }
    let mut f = Matrix6::identity();
    let mut q = Matrix6::zeros();
    for k in 0..3 {
        f[(k, k + 3)] = dt;
        q[(k, k)] = qa * dt.powi(3) / 3.0;
        q[(k, k + 3)] = qa * dt.powi(2) / 2.0;
        q[(k + 3, k)] = qa * dt.powi(2) / 2.0;
        q[(k + 3, k + 3)] = qa * dt;
    }
    (f * x, f * p * f.transpose() + q, t1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noisy_fixes_of_a_steady_motion_are_smoothed_and_an_outlier_is_gated() {
        let cov = Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 0.0));
        let mut f = CvFix::new(ACCEL_PSD_M2_S3);
        let mut last = None;
        for k in 0..100 {
            let t = f64::from(k) * 0.1;
            let noise = if k % 2 == 0 { 0.01 } else { -0.01 };
            let x = if k == 50 { 3.0 } else { 0.5 * t + noise };
            last = f.step(t, [x, 0.0, 0.0], &cov);
        }
        let (t, p) = last.unwrap();
        assert!((p[0] - 0.5 * t).abs() < 0.01, "{p:?}");
        assert_eq!((f.gated, f.restarts), (1, 0));
    }
}
