//! Pseudo-range residuals of a position: `e_i = rho_i - |p - s_i| - b`,
//! with `b` the offset that fits them best (their mean).

use nalgebra::Vector3;

use super::signal::{Signal, Subset};

/// Residual statistics of one position over a subset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Stats {
    /// Best common offset `b`, metres.
    pub bias_m: f64,
    /// Sum of squared residuals, m^2.
    pub ssr_m2: f64,
    /// Largest residual (signed, late arrivals positive), metres.
    pub max_m: f64,
    /// Smallest residual, metres.
    pub min_m: f64,
}

impl Stats {
    /// Largest absolute residual.
    pub(crate) fn max_abs_m(&self) -> f64 {
        self.max_m.max(-self.min_m)
    }
}

/// One pass over the subset. The sums are taken around `shift_m`, a guess of
/// the offset, because the offset can be metres while the residuals are
/// micrometres: summing raw values would cancel them away.
pub(crate) fn stats(signals: &[Signal], set: Subset, p: &Vector3<f64>, shift_m: f64) -> Stats {
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    let (mut hi, mut lo) = (f64::NEG_INFINITY, f64::INFINITY);
    for s in set.of(signals) {
        let e = s.pseudo_range_m - (p - s.tx_m).norm() - shift_m;
        sum += e;
        sum_sq += e * e;
        hi = hi.max(e);
        lo = lo.min(e);
    }
    let n = set.len().max(1) as f64;
    let mean = sum / n;
    Stats {
        bias_m: shift_m + mean,
        ssr_m2: (sum_sq - n * mean * mean).max(0.0),
        max_m: hi - mean,
        min_m: lo - mean,
    }
}

/// Residual of one signal against a position and offset.
pub(crate) fn residual(s: &Signal, p: &Vector3<f64>, bias_m: f64) -> f64 {
    s.pseudo_range_m - (p - s.tx_m).norm() - bias_m
}
