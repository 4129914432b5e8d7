//! The one linear Kalman routine shared by every filter here (heading KF,
//! gyro complementary KF, position AKF): models are plain matrices, the
//! covariance update is in Joseph form and the result is symmetrised, so the
//! covariance stays symmetric positive definite.

use nalgebra::{SMatrix, SVector};

/// `P <- A P A^T + Q`, symmetrised.
pub(crate) fn predict<const N: usize>(
    p: &SMatrix<f64, N, N>,
    a: &SMatrix<f64, N, N>,
    q: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    symmetrise(a * p * a.transpose() + q)
}

/// Measurement update with a given innovation `z - H x` (the caller computes
/// it so that angles can be unwrapped first). Returns the corrected state and
/// covariance, or `None` when the innovation covariance is not positive
/// definite (the caller then skips the measurement).
pub(crate) fn update<const N: usize, const M: usize>(
    x: &SVector<f64, N>,
    p: &SMatrix<f64, N, N>,
    h: &SMatrix<f64, M, N>,
    r: &SMatrix<f64, M, M>,
    innovation: &SVector<f64, M>,
) -> Option<(SVector<f64, N>, SMatrix<f64, N, N>)> {
    let s = symmetrise(h * p * h.transpose() + r);
    let s_inv = s.cholesky()?.inverse();
    let k = p * h.transpose() * s_inv;
    let x_new = x + k * innovation;
    let i_kh = SMatrix::<f64, N, N>::identity() - k * h;
    let p_new = symmetrise(i_kh * p * i_kh.transpose() + k * r * k.transpose());
    let finite = x_new.iter().chain(p_new.iter()).all(|v| v.is_finite());
    finite.then_some((x_new, p_new))
}

/// `(P + P^T) / 2`.
pub(crate) fn symmetrise<const N: usize>(p: SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (p + p.transpose()) * 0.5
}

/// The constant-velocity model over `dt` seconds for position and velocity
/// blocks of three axes starting at state indices `pos` and `vel`:
/// `F` gets `dt` coupling velocity into position, `Q` the discretised
/// white-noise acceleration of spectral density `accel_psd` (van Loan).
pub(crate) fn constant_velocity<const N: usize>(
    f: &mut SMatrix<f64, N, N>,
    q: &mut SMatrix<f64, N, N>,
    pos: usize,
    vel: usize,
    dt: f64,
    accel_psd: f64,
) {
    for k in 0..3 {
        f[(pos + k, vel + k)] = dt;
        q[(pos + k, pos + k)] = accel_psd * dt.powi(3) / 3.0;
        q[(pos + k, vel + k)] = accel_psd * dt * dt / 2.0;
        q[(vel + k, pos + k)] = accel_psd * dt * dt / 2.0;
        q[(vel + k, vel + k)] = accel_psd * dt;
    }
}

/// The standard deviation of the worst of the three axes of the position
/// block starting at state index `first`.
pub(crate) fn largest_axis_sigma<const N: usize>(p: &SMatrix<f64, N, N>, first: usize) -> f64 {
    (first..first + 3)
        .map(|k| p[(k, k)])
        .fold(0.0_f64, f64::max)
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix1, Vector1};

    #[test]
    fn scalar_update_matches_textbook_gain() {
        // P = 4, R = 1: K = 0.8, x = 0 + 0.8 * 5 = 4, P = (1 - 0.8) * 4 = 0.8.
        let (x, p) = update(
            &Vector1::new(0.0),
            &Matrix1::new(4.0),
            &Matrix1::new(1.0),
            &Matrix1::new(1.0),
            &Vector1::new(5.0),
        )
        .unwrap();
        assert!((x[0] - 4.0).abs() < 1e-12);
        assert!((p[(0, 0)] - 0.8).abs() < 1e-12);
    }

    #[test]
    fn singular_innovation_covariance_is_refused() {
        let out = update(
            &Vector1::new(0.0),
            &Matrix1::new(0.0),
            &Matrix1::new(1.0),
            &Matrix1::new(0.0),
            &Vector1::new(1.0),
        );
        assert!(out.is_none());
    }
}
