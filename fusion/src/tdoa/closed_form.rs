//! The ICKON paper, s3.1 eq. 1-3: the least-squares hyperbola intersection.
//!
//! Coordinates are taken relative to the reference transmitter, `q = p - s_1`,
//! `a_i = s_i - s_1`, so that `r_1 = |q|`. Subtracting the reference circle
//! equation `|q|^2 = r_1^2` from `|q - a_i|^2 = (r_1 + r_i1)^2` (eq. 2)
//! leaves one linear equation per other signal,
//!
//! ```text
//! a_i . q = 1/2 (|a_i|^2 - r_i1^2) - r_1 r_i1 ,
//! ```
//!
//! so least squares gives `q = u + r_1 v` with
//! `u = 1/2 (A^T A)^-1 A^T c`, `v = (A^T A)^-1 A^T d`, `c_i = |a_i|^2 - r_i1^2`,
//! `d_i = -r_i1` (eq. 3), and `r_1^2 = |q|^2` becomes
//! `(|v|^2 - 1) r_1^2 + 2 (u.v) r_1 + |u|^2 = 0`.
//! In 2D the height is known: `q_z = h - z_1` moves to the right-hand side,
//! and its square joins the constant term.
//!
//! `A^T A` is accumulated directly into a fixed 3x3 (in 2D the z row is the
//! identity, so one code path serves both modes): no heap allocation.

use nalgebra::{Matrix3, Vector3};

use super::residuals::{self, Stats};
use super::signal::{self, Signal, Subset};
use super::{Mode, SolveError};

/// Transmitter spreads thinner than this fraction of their extent count as
/// flat (coplanar in 3D, collinear in 2D): the position across the thin
/// direction would amplify the timing noise more than a thousandfold.
pub const MIN_THICKNESS_RATIO: f64 = 1e-3;

/// One root of the closed form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Receiver position, metres (in 2D, `z` is the given height).
    pub position_m: Vector3<f64>,
    /// Distance to the reference transmitter `r_1`, metres.
    pub range_to_reference_m: f64,
    /// Common offset `b` that fits the pseudo-ranges best, metres.
    pub bias_m: f64,
    /// Root mean square of the pseudo-range residuals, metres.
    pub rms_residual_m: f64,
    /// Largest absolute pseudo-range residual, metres.
    pub max_abs_residual_m: f64,
    pub(crate) stats: Stats,
}

/// The physical roots of the closed form, best first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedForm {
    /// The root with the smaller residual.
    pub best: Candidate,
    /// The other physical root, if there is one: with exactly the minimum
    /// number of signals both fit exactly and the data cannot choose.
    pub other: Option<Candidate>,
}

impl ClosedForm {
    /// The roots, best first.
    pub fn candidates(&self) -> impl Iterator<Item = &Candidate> {
        std::iter::once(&self.best).chain(self.other.iter())
    }
}

/// Closed-form fix from all `signals`, the first one as reference.
pub fn closed_form(signals: &[Signal], mode: Mode) -> Result<ClosedForm, SolveError> {
    mode.validate()?;
    signal::validate(signals, mode.min_signals())?;
    closed_form_subset(signals, Subset::first(signals.len()), mode)
}

/// Closed form over a validated subset of at least `mode.min_signals()`.
pub(crate) fn closed_form_subset(
    signals: &[Signal],
    set: Subset,
    mode: Mode,
) -> Result<ClosedForm, SolveError> {
    let need = mode.min_signals();
    if set.len() < need {
        return Err(SolveError::TooFewSignals {
            got: set.len(),
            need,
        });
    }
    let mut others = set.of(signals);
    let reference = others
        .next()
        .ok_or(SolveError::TooFewSignals { got: 0, need })?;
    let s1 = reference.tx_m;
    let dz = mode.height_m().map_or(0.0, |h| h - s1.z);
    let two_d = mode.height_m().is_some();

    let mut ata = Matrix3::<f64>::zeros();
    let mut atc = Vector3::<f64>::zeros();
    let mut atd = Vector3::<f64>::zeros();
    for s in others {
        let a = s.tx_m - s1;
        let ri1 = s.pseudo_range_m - reference.pseudo_range_m;
        let mut c = 0.5 * (a.norm_squared() - ri1 * ri1);
        let row = if two_d {
            c -= a.z * dz;
            Vector3::new(a.x, a.y, 0.0)
        } else {
            a
        };
        ata += row * row.transpose();
        atc += row * c;
        atd -= row * ri1;
    }
    if two_d {
        ata[(2, 2)] = 1.0;
    }
    let thickness_ratio = thickness_ratio(&ata, two_d);
    if thickness_ratio.is_nan() || thickness_ratio < MIN_THICKNESS_RATIO {
        return Err(SolveError::DegenerateGeometry {
            thickness_ratio,
            two_d,
        });
    }
    let chol = ata.cholesky().ok_or(SolveError::DegenerateGeometry {
        thickness_ratio: 0.0,
        two_d,
    })?;
    let u = chol.solve(&atc);
    let v = chol.solve(&atd);

    let qa = v.norm_squared() - 1.0;
    let qb = u.dot(&v);
    let qc = u.norm_squared() + dz * dz;
    let mut roots = [f64::NAN; 2];
    let scale = qb * qb + (qa * qc).abs();
    let mut discriminant = qb * qb - qa * qc;
    // Noise can push a double root's discriminant just below zero.
    if discriminant < 0.0 && discriminant >= -1e-12 * scale {
        discriminant = 0.0;
    }
    if discriminant < 0.0 {
        return Err(SolveError::NoRealRoot { discriminant });
    }
    if qa.abs() <= 1e-12 * (1.0 + qb.abs()) {
        // |v| = 1: the quadratic degenerates to 2 qb r + qc = 0.
        if qb != 0.0 {
            roots[0] = -qc / (2.0 * qb);
        }
    } else {
        // Citardauq form: no cancellation whichever sign qb has.
        let q = -(qb + qb.signum() * discriminant.sqrt());
        roots[0] = q / qa;
        roots[1] = if q != 0.0 { qc / q } else { roots[0] };
    }

    let tol_m = 1e-9 * (1.0 + u.norm() + v.norm());
    let mut found: [Option<Candidate>; 2] = [None, None];
    for (k, &r1) in roots.iter().enumerate() {
        if !r1.is_finite() || (k == 1 && (r1 - roots[0]).abs() <= tol_m) {
            continue;
        }
        let physical = set
            .of(signals)
            .all(|s| r1 + (s.pseudo_range_m - reference.pseudo_range_m) >= -tol_m);
        if !physical {
            continue;
        }
        let r1 = r1.max(0.0);
        let mut q = u + v * r1;
        q.z += dz;
        let position_m = s1 + q;
        let stats = residuals::stats(signals, set, &position_m, reference.pseudo_range_m - r1);
        found[k] = Some(Candidate {
            position_m,
            range_to_reference_m: r1,
            bias_m: stats.bias_m,
            rms_residual_m: (stats.ssr_m2 / set.len() as f64).sqrt(),
            max_abs_residual_m: stats.max_abs_m(),
            stats,
        });
    }
    match found {
        [Some(a), Some(b)] if b.stats.ssr_m2 < a.stats.ssr_m2 => Ok(ClosedForm {
            best: b,
            other: Some(a),
        }),
        [Some(a), b] | [b @ None, Some(a)] => Ok(ClosedForm { best: a, other: b }),
        [None, None] => Err(SolveError::NoPhysicalRoot),
    }
}

/// `sqrt(lambda_min / lambda_max)` of `A^T A` (its 2x2 block in 2D): the
/// thickness of the transmitter constellation relative to its extent.
fn thickness_ratio(m: &Matrix3<f64>, two_d: bool) -> f64 {
    let (lo, hi) = if two_d {
        let (a, b, d) = (m[(0, 0)], m[(0, 1)], m[(1, 1)]);
        let mid = 0.5 * (a + d);
        let half = (0.25 * (a - d) * (a - d) + b * b).sqrt();
        (mid - half, mid + half)
    } else {
        symmetric_extreme_eigenvalues(m)
    };
    if hi > 0.0 {
        (lo.max(0.0) / hi).sqrt()
    } else {
        0.0
    }
}

/// Smallest and largest eigenvalue of a symmetric 3x3, in closed form
/// (trigonometric solution of the characteristic cubic): a few flops instead
/// of an iterative decomposition in the hot path.
fn symmetric_extreme_eigenvalues(m: &Matrix3<f64>) -> (f64, f64) {
    let off = m[(0, 1)].powi(2) + m[(0, 2)].powi(2) + m[(1, 2)].powi(2);
    let q = m.trace() / 3.0;
    let d = m.diagonal().add_scalar(-q);
    let p = ((d.norm_squared() + 2.0 * off) / 6.0).sqrt();
    if p == 0.0 {
        return (q, q);
    }
    let b = (m - Matrix3::identity() * q) / p;
    let r = (0.5 * b.determinant()).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let hi = q + 2.0 * p * phi.cos();
    let lo = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_eigenvalues_match_the_decomposition() {
        let m = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 0.01);
        let (lo, hi) = symmetric_extreme_eigenvalues(&m);
        let e = m.symmetric_eigenvalues();
        assert!((lo - e.min()).abs() < 1e-12, "{lo} vs {}", e.min());
        assert!((hi - e.max()).abs() < 1e-12, "{hi} vs {}", e.max());
    }
}
