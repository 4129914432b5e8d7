//! Dilution of precision and the Cramer-Rao lower bound of a TDOA geometry.
//!
//! Each arrival carries independent Gaussian noise, so each pseudo-range
//! `rho_i = |p - s_i| + b + n_i`, `n_i ~ N(0, sigma^2)`. With `b` a nuisance
//! parameter the Fisher information of `(p, b)` is `G^T G / sigma^2`, rows
//! `[g_i^T, 1]`, `g_i = (p - s_i)/|p - s_i|`; its Schur complement for `p` is
//!
//! ```text
//! I_p = (1/sigma^2) sum_i (g_i - g_bar)(g_i - g_bar)^T ,  CRLB = I_p^-1 .
//! ```
//!
//! This equals `J^T Sigma^-1 J` of the range-difference model
//! `d_i = r_i - r_1` with its correlated covariance
//! `Sigma = sigma^2 (I + 1 1^T)` (checked in the tests), and the position
//! block of the GNSS-style DOP matrix `(G^T G)^-1`. In 2D only `x, y` are
//! unknown and the height is the mode's.

use nalgebra::{Matrix3, Vector3};

use super::refine::unit;
use super::{Mode, SolveError};

/// Dilution of precision: position error per metre of range noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dop {
    /// Horizontal: `sqrt(C_xx + C_yy)`.
    pub hdop: f64,
    /// Vertical: `sqrt(C_zz)`; `None` in 2D where the height is given.
    pub vdop: Option<f64>,
    /// Position: `sqrt(trace C)` (equals `hdop` in 2D).
    pub pdop: f64,
}

/// The Cramer-Rao lower bound of the position for a geometry and noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// Lowest covariance an unbiased fix can have, m^2 (zero `z` row and
    /// column in 2D).
    pub covariance_m2: Matrix3<f64>,
    /// `sqrt(trace)`: the lowest root-mean-square position error, metres.
    pub rms_m: f64,
    /// The same for `x, y` alone, metres.
    pub horizontal_rms_m: f64,
    /// The geometry's dilution of precision.
    pub dop: Dop,
}

/// Dilution of precision of the transmitters seen from `position_m`. In 2D
/// the mode's height replaces `position_m.z`.
pub fn dop(
    transmitters_m: &[Vector3<f64>],
    position_m: Vector3<f64>,
    mode: Mode,
) -> Result<Dop, SolveError> {
    let c = unit_covariance(transmitters_m, position_m, mode)?;
    Ok(dop_of(&c, mode))
}

fn dop_of(c: &Matrix3<f64>, mode: Mode) -> Dop {
    Dop {
        hdop: (c[(0, 0)] + c[(1, 1)]).sqrt(),
        vdop: mode.height_m().is_none().then(|| c[(2, 2)].sqrt()),
        pdop: c.trace().sqrt(),
    }
}

/// Cramer-Rao lower bound for independent range noise `sigma_range_m`
/// (timing noise times the speed of sound) on every arrival.
pub fn crlb(
    transmitters_m: &[Vector3<f64>],
    position_m: Vector3<f64>,
    sigma_range_m: f64,
    mode: Mode,
) -> Result<Bound, SolveError> {
    if !(sigma_range_m > 0.0 && sigma_range_m.is_finite()) {
        return Err(SolveError::InvalidConfig {
            field: "sigma_range_m",
            reason: "must be positive and finite",
        });
    }
    let unit = unit_covariance(transmitters_m, position_m, mode)?;
    let covariance_m2 = unit * (sigma_range_m * sigma_range_m);
    Ok(Bound {
        covariance_m2,
        rms_m: covariance_m2.trace().sqrt(),
        horizontal_rms_m: (covariance_m2[(0, 0)] + covariance_m2[(1, 1)]).sqrt(),
        dop: dop_of(&unit, mode),
    })
}

/// `I_p^-1` for unit noise, zero `z` row and column in 2D.
fn unit_covariance(
    transmitters_m: &[Vector3<f64>],
    position_m: Vector3<f64>,
    mode: Mode,
) -> Result<Matrix3<f64>, SolveError> {
    mode.validate()?;
    let need = mode.min_signals();
    if transmitters_m.len() < need {
        return Err(SolveError::TooFewSignals {
            got: transmitters_m.len(),
            need,
        });
    }
    let mut p = position_m;
    if let Some(h) = mode.height_m() {
        p.z = h;
    }
    if !p.iter().all(|v| v.is_finite()) {
        return Err(SolveError::NonFinite {
            field: "position_m",
            index: 0,
        });
    }
    let two_d = mode.height_m().is_some();
    let mut sg = Vector3::zeros();
    let mut sgg = Matrix3::zeros();
    for (index, tx) in transmitters_m.iter().enumerate() {
        if !tx.iter().all(|v| v.is_finite()) {
            return Err(SolveError::NonFinite {
                field: "transmitters_m",
                index,
            });
        }
        let (g, r) = unit(&p, tx, two_d);
        // On a transmitter the range has no gradient.
        if r == 0.0 {
            return Err(SolveError::SingularInformation);
        }
        sg += g;
        sgg += g * g.transpose();
    }
    let n = transmitters_m.len() as f64;
    let mut info = sgg - sg * sg.transpose() / n;
    if two_d {
        info[(2, 2)] = 1.0;
    }
    // Relative floor: a rank-deficient information matrix can still pass
    // Cholesky through rounding.
    let eigen = info.symmetric_eigenvalues();
    if eigen.min().is_nan() || eigen.min() <= 1e-12 * eigen.max().max(1.0) {
        return Err(SolveError::SingularInformation);
    }
    let mut c = info
        .cholesky()
        .ok_or(SolveError::SingularInformation)?
        .inverse();
    if two_d {
        c[(2, 2)] = 0.0;
    }
    Ok(c)
}
