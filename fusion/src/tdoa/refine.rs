//! Gauss-Newton on the range differences, seeded by the closed form.
//!
//! With independent noise on each pseudo-range, least squares on
//! `rho_i - |p - s_i| - b` over `(p, b)` is the maximum-likelihood fix, and
//! eliminating `b` (its optimum is the mean residual) turns it into least
//! squares on the *centred* residuals `e_i - mean(e)` with the centred unit
//! vectors `g_i - mean(g)` as Jacobian: exactly the range-difference problem
//! with its correlated covariance, in 3 (2D: 2) unknowns instead of 4.
//! The normal matrix `sum (g_i - g_bar)(g_i - g_bar)^T` is also the Fisher
//! information divided by `sigma^2` (see [`super::bound`]).

use nalgebra::{Matrix3, Vector3};

use super::signal::{Signal, Subset};
use super::{Mode, SolveError};

/// Steps shorter than this end the iteration: far below any timing noise.
const STEP_TOLERANCE_M: f64 = 1e-9;
/// Halvings of a step that does not lower the cost before giving up.
const MAX_HALVINGS: u32 = 12;

/// The least-squares problem linearised at one position.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Linearised {
    /// Centred residual sum of squares, m^2.
    pub cost_m2: f64,
    /// Centred normal matrix (unitless); in 2D its z row is the identity.
    pub info: Matrix3<f64>,
    /// Centred `J^T e`, metres.
    pub jte: Vector3<f64>,
    /// Best common offset at this position, metres.
    pub bias_m: f64,
}

/// Unit vector from transmitter to receiver, with `z` dropped in 2D.
pub(crate) fn unit(p: &Vector3<f64>, tx: &Vector3<f64>, two_d: bool) -> (Vector3<f64>, f64) {
    let d = p - tx;
    let r = d.norm();
    // A receiver on a transmitter has no direction; the degenerate
    // information matrix then reports it.
    let mut g = if r > 0.0 { d / r } else { Vector3::zeros() };
    if two_d {
        g.z = 0.0;
    }
    (g, r)
}

/// One pass over the subset; `shift_m` keeps the sums small (see
/// [`super::residuals::stats`]).
pub(crate) fn linearise(
    signals: &[Signal],
    set: Subset,
    mode: Mode,
    p: &Vector3<f64>,
    shift_m: f64,
) -> Linearised {
    let two_d = mode.height_m().is_some();
    let mut sg = Vector3::zeros();
    let mut sgg = Matrix3::zeros();
    let mut sge = Vector3::zeros();
    let (mut se, mut see) = (0.0, 0.0);
    for s in set.of(signals) {
        let (g, r) = unit(p, &s.tx_m, two_d);
        let e = s.pseudo_range_m - r - shift_m;
        sg += g;
        sgg += g * g.transpose();
        sge += g * e;
        se += e;
        see += e * e;
    }
    let n = set.len().max(1) as f64;
    let gm = sg / n;
    let em = se / n;
    let mut info = sgg - gm * gm.transpose() * n;
    if two_d {
        info[(2, 2)] = 1.0;
    }
    Linearised {
        cost_m2: (see - n * em * em).max(0.0),
        info,
        jte: sge - gm * (n * em),
        bias_m: shift_m + em,
    }
}

/// Result of [`refine_subset`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Refined {
    pub position_m: Vector3<f64>,
    /// The problem linearised at the final position.
    pub at: Linearised,
    pub iterations: u32,
}

/// Gauss-Newton with step halving from `start`. Never returns a position
/// with a higher cost than `start`.
pub(crate) fn refine_subset(
    signals: &[Signal],
    set: Subset,
    mode: Mode,
    start: Vector3<f64>,
    max_iterations: u32,
) -> Result<Refined, SolveError> {
    let mut p = start;
    if let Some(h) = mode.height_m() {
        p.z = h;
    }
    let first = set
        .of(signals)
        .next()
        .map_or(0.0, |s| s.pseudo_range_m - (p - s.tx_m).norm());
    let mut at = linearise(signals, set, mode, &p, first);
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        let step = at
            .info
            .cholesky()
            .ok_or(SolveError::SingularInformation)?
            .solve(&at.jte);
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..=MAX_HALVINGS {
            let candidate = p + step * t;
            let lin = linearise(signals, set, mode, &candidate, at.bias_m);
            if lin.cost_m2 <= at.cost_m2 {
                accepted = Some((candidate, lin));
                break;
            }
            t *= 0.5;
        }
        // No step lowers the cost: p is a minimum to rounding.
        let Some((next, lin)) = accepted else { break };
        p = next;
        at = lin;
        if (step * t).norm() < STEP_TOLERANCE_M {
            break;
        }
    }
    if !p.iter().all(|v| v.is_finite()) {
        return Err(SolveError::SingularInformation);
    }
    Ok(Refined {
        position_m: p,
        at,
        iterations,
    })
}
