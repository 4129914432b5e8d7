//! 2D TDOA fix with the MSU height known, until `ickon_fusion::tdoa` lands:
//! Gauss-Newton on `rho_i = |p - s_i| + b` (unknowns `x, y, b`), then
//! leave-one-out rejection of the worst signal while residuals exceed the
//! gate and at least five signals remain.

use nalgebra::{Matrix3, Vector3};

use crate::assembly::Signal;

/// Parameters `(x, y, b)`, `(J^T J)^-1`, residuals.
type Estimate = (Vector3<f64>, Matrix3<f64>, Vec<f64>);

/// A solved fix.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Solution {
    pub xy_m: [f64; 2],
    /// Covariance of x, y, m^2.
    pub cov_xy: [[f64; 2]; 2],
    pub used: Vec<usize>,
    pub residuals_m: Vec<f64>,
}

fn gauss_newton(
    signals: &[Signal],
    idx: &[usize],
    height_m: f64,
    start: [f64; 2],
) -> Option<Estimate> {
    let range = |p: &Vector3<f64>, s: &Signal| {
        ((p[0] - s.tx_m[0]).powi(2) + (p[1] - s.tx_m[1]).powi(2) + (height_m - s.tx_m[2]).powi(2))
            .sqrt()
    };
    let mut p = Vector3::new(start[0], start[1], 0.0);
    p[2] = idx
        .iter()
        .map(|&i| signals[i].pseudo_range_m - range(&p, &signals[i]))
        .sum::<f64>()
        / idx.len() as f64;
    let mut jtj = Matrix3::zeros();
    for _ in 0..20 {
        jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for &i in idx {
            let s = &signals[i];
            let r = range(&p, s).max(1e-6);
            let row = Vector3::new((p[0] - s.tx_m[0]) / r, (p[1] - s.tx_m[1]) / r, 1.0);
            let res = s.pseudo_range_m - (r + p[2]);
            jtj += row * row.transpose();
            jtr += row * res;
        }
        let step = jtj.try_inverse()? * jtr;
        p += step;
        if !p.iter().all(|v| v.is_finite()) {
            return None;
        }
        if step.norm() < 1e-10 {
            break;
        }
    }
    let residuals = idx
        .iter()
        .map(|&i| signals[i].pseudo_range_m - (range(&p, &signals[i]) + p[2]))
        .collect();
    let inv = jtj.try_inverse()?;
    Some((p, inv, residuals))
}

fn rms(r: &[f64]) -> f64 {
    (r.iter().map(|x| x * x).sum::<f64>() / r.len().max(1) as f64).sqrt()
}

/// Solves from `start`; `gate_m` bounds the largest acceptable residual.
pub(crate) fn solve_2d(
    signals: &[Signal],
    height_m: f64,
    start: [f64; 2],
    sigma_m: f64,
    gate_m: f64,
) -> Option<Solution> {
    let mut idx: Vec<usize> = (0..signals.len()).collect();
    if idx.len() < 3 {
        return None;
    }
    let mut best = gauss_newton(signals, &idx, height_m, start)?;
    while idx.len() >= 5 && best.2.iter().any(|r| r.abs() > gate_m) {
        let mut candidate: Option<(usize, Estimate)> = None;
        for k in 0..idx.len() {
            let mut sub = idx.clone();
            sub.remove(k);
            if let Some(sol) = gauss_newton(signals, &sub, height_m, start) {
                if candidate.as_ref().is_none_or(|c| rms(&sol.2) < rms(&c.1.2)) {
                    candidate = Some((k, sol));
                }
            }
        }
        let (k, sol) = candidate?;
        idx.remove(k);
        best = sol;
    }
    let (p, inv, residuals) = best;
    let var = sigma_m.max(rms(&residuals)).powi(2);
    Some(Solution {
        xy_m: [p[0], p[1]],
        cov_xy: [
            [var * inv[(0, 0)], var * inv[(0, 1)]],
            [var * inv[(1, 0)], var * inv[(1, 1)]],
        ],
        used: idx,
        residuals_m: residuals,
    })
}
