//! [`solve`]: the closed form and refinement wrapped in reflection
//! rejection.
//!
//! A reflected arrival travels further than the direct path, so its
//! pseudo-range is too long: rejection looks for *late* signals.
//! 1. Physical check, no statistics: `rho_i - rho_j <= |s_i - s_j|` for
//!    every pair (plus `sqrt(2)` gates of noise). The signal that is the
//!    longer side of the most violations goes first, until none is left.
//! 2. Consensus: while some residual exceeds the gate and redundancy
//!    remains, solve once without each signal. The removal that leaves the
//!    smallest residual sum names the suspect; it goes if its residual
//!    against the others' fix is beyond the gate (and late, by default).
//!    When removal leaves no redundancy every subset fits exactly, so a
//!    signal goes only if it is the single one whose residual is off:
//!    otherwise the data cannot tell which signal is wrong and the fix
//!    stays [`Quality::Suspect`].
//! 3. Roots and refined fixes outside the allowed area are discarded.
//! 4. If a residual is still over the gate, or no fix is left, the
//!    consensus of [`super::consensus`] may replace the result.

use nalgebra::{Matrix3, Vector3};

use super::closed_form::closed_form_subset;
use super::consensus;
use super::refine::{linearise, refine_subset};
use super::residuals::{self, Stats};
use super::signal::{self, Signal, Subset};
use super::{Fix, Quality, RejectReason, Rejection, SolveError, SolverConfig};

/// A fix over one subset, before it is turned into a [`Fix`].
#[derive(Debug, Clone, Copy)]
struct Estimate {
    position_m: Vector3<f64>,
    /// `(J^T J)^-1`, the covariance per unit range variance.
    unit_covariance: Matrix3<f64>,
    stats: Stats,
    alternative_m: Option<Vector3<f64>>,
    iterations: u32,
}

/// Fix from the signals of one cycle: checks, physical rejection, closed
/// form, refinement, leave-one-out rejection.
pub fn solve(signals: &[Signal], config: &SolverConfig) -> Result<Fix, SolveError> {
    config.validate()?;
    let need = config.mode.min_signals();
    signal::validate(signals, need)?;
    let gate_m = config.gate_m();
    let mut set = Subset::first(signals.len());
    let mut rejected = Vec::new();
    physical_check(
        signals,
        &mut set,
        gate_m * std::f64::consts::SQRT_2,
        &mut rejected,
    );
    if set.len() < need {
        if let Some(fix) = consensus_fix(signals, config, &rejected, gate_m) {
            return Ok(fix);
        }
        return Err(SolveError::TooFewConsistent {
            got: set.len(),
            need,
            rejected,
        });
    }
    let mut current = estimate(signals, set, config, gate_m);
    let mut removed = 0;
    loop {
        let fits = matches!(&current, Ok(e) if e.stats.max_abs_m() <= gate_m);
        if fits || set.len() <= need || removed >= config.max_rejections {
            break;
        }
        let Some((k, residual_m, est)) =
            leave_one_out(signals, set, config, gate_m, current.is_err())
        else {
            break;
        };
        rejected.push(Rejection {
            tx_id: signals[k].tx_id,
            reason: RejectReason::Residual { residual_m },
        });
        set = set.without(k);
        current = Ok(est);
        removed += 1;
    }
    let clean = matches!(&current, Ok(e) if e.stats.max_abs_m() <= gate_m);
    if !clean && let Some(fix) = consensus_fix(signals, config, &rejected, gate_m) {
        return Ok(fix);
    }
    Ok(into_fix(signals, set, config, current?, rejected, gate_m))
}

/// The consensus fallback as a [`Fix`]: every signal outside the agreeing
/// set is reported, with the physical check's reason where it had one, else
/// with its residual against the consensus fix.
fn consensus_fix(
    signals: &[Signal],
    config: &SolverConfig,
    checked: &[Rejection],
    gate_m: f64,
) -> Option<Fix> {
    if config.max_rejections == 0 {
        return None;
    }
    let (agreeing, est) = by_consensus(signals, config, gate_m)?;
    let outside = Subset::first(signals.len())
        .iter()
        .filter(|&i| !agreeing.contains(i));
    let rejected = outside
        .map(|i| {
            let tx_id = signals[i].tx_id;
            let baseline = checked.iter().find(|r| {
                r.tx_id == tx_id && matches!(r.reason, RejectReason::ExceedsBaseline { .. })
            });
            baseline.copied().unwrap_or(Rejection {
                tx_id,
                reason: RejectReason::Residual {
                    residual_m: residuals::residual(&signals[i], &est.position_m, est.stats.bias_m),
                },
            })
        })
        .collect();
    Some(into_fix(signals, agreeing, config, est, rejected, gate_m))
}

/// The fix of the largest set of signals that agree on one position
/// ([`consensus::agreeing_set`]), solved as a whole, widened once by the
/// signals that agree with that fix, and passing the gate.
fn by_consensus(
    signals: &[Signal],
    config: &SolverConfig,
    gate_m: f64,
) -> Option<(Subset, Estimate)> {
    let all = Subset::first(signals.len());
    let mut set = consensus::agreeing_set(signals, all, config, gate_m)?;
    let mut est = estimate(signals, set, config, gate_m).ok()?;
    let widened = all
        .iter()
        .filter(|&i| {
            residuals::residual(&signals[i], &est.position_m, est.stats.bias_m).abs() <= gate_m
        })
        .fold(Subset::empty(), Subset::with);
    if widened.len() > set.len()
        && let Ok(wider) = estimate(signals, widened, config, gate_m)
        && wider.stats.max_abs_m() <= gate_m
    {
        (set, est) = (widened, wider);
    }
    (est.stats.max_abs_m() <= gate_m).then_some((set, est))
}

/// Drops the longer side of range differences longer than their baseline.
fn physical_check(signals: &[Signal], set: &mut Subset, tol_m: f64, out: &mut Vec<Rejection>) {
    loop {
        // (index, violations, largest excess, partner)
        let mut worst: Option<(usize, u32, f64, usize)> = None;
        for i in set.iter() {
            let (mut count, mut excess, mut partner) = (0, 0.0, i);
            for j in set.iter() {
                let diff = signals[i].pseudo_range_m - signals[j].pseudo_range_m - tol_m;
                // The square root only for the rare pairs that may violate.
                if diff > 0.0 && diff * diff > (signals[i].tx_m - signals[j].tx_m).norm_squared() {
                    let e = diff - (signals[i].tx_m - signals[j].tx_m).norm();
                    count += 1;
                    if e > excess {
                        (excess, partner) = (e, j);
                    }
                }
            }
            let better = worst.is_none_or(|(_, c, x, _)| (count, excess) > (c, x));
            if count > 0 && better {
                worst = Some((i, count, excess, partner));
            }
        }
        let Some((i, _, excess_m, partner)) = worst else {
            return;
        };
        out.push(Rejection {
            tx_id: signals[i].tx_id,
            reason: RejectReason::ExceedsBaseline {
                other_tx_id: signals[partner].tx_id,
                excess_m,
            },
        });
        *set = set.without(i);
    }
}

/// Closed form, root choice by the allowed area, optional refinement.
fn estimate(
    signals: &[Signal],
    set: Subset,
    config: &SolverConfig,
    gate_m: f64,
) -> Result<Estimate, SolveError> {
    let mode = config.mode;
    let inside = |p: &Vector3<f64>| config.allowed_area_m.is_none_or(|a| a.contains(p, mode));
    let outside = |p: Vector3<f64>| SolveError::OutsideAllowedArea {
        position_m: p.into(),
    };
    let cf = closed_form_subset(signals, set, mode)?;
    let mut roots = cf.candidates().filter(|c| inside(&c.position_m));
    let chosen = *roots.next().ok_or_else(|| outside(cf.best.position_m))?;
    let alternative_m = roots
        .next()
        .filter(|o| o.stats.max_abs_m() <= gate_m)
        .map(|o| o.position_m);
    let (position_m, info, iterations) = if config.refine {
        let r = refine_subset(signals, set, mode, chosen.position_m, config.max_iterations)?;
        if !inside(&r.position_m) {
            return Err(outside(r.position_m));
        }
        (r.position_m, r.at.info, r.iterations)
    } else {
        let lin = linearise(signals, set, mode, &chosen.position_m, chosen.bias_m);
        (chosen.position_m, lin.info, 0)
    };
    let unit_covariance = info
        .cholesky()
        .ok_or(SolveError::SingularInformation)?
        .inverse();
    Ok(Estimate {
        position_m,
        unit_covariance,
        stats: residuals::stats(signals, set, &position_m, chosen.bias_m),
        alternative_m,
        iterations,
    })
}

/// The signal to drop, its residual against the others' fix, and that fix.
///
/// With redundancy left after the removal, the removal that leaves the
/// smallest residual sum names the suspect, and it is dropped only if its
/// own residual is off in the direction the config allows: an early outlier
/// under `late_only` must not get good signals dropped in its place.
/// Without redundancy left every subset fits exactly, so the direction alone
/// must single out one signal.
fn leave_one_out(
    signals: &[Signal],
    set: Subset,
    config: &SolverConfig,
    gate_m: f64,
    all_failed: bool,
) -> Option<(usize, f64, Estimate)> {
    let exact_after = set.len() - 1 == config.mode.min_signals();
    let off = |residual_m: f64| {
        // When the full set has no fix at all, any subset that has one is
        // evidence against the signal it leaves out.
        all_failed
            || if config.late_only {
                residual_m > gate_m
            } else {
                residual_m.abs() > gate_m
            }
    };
    let mut best: Option<(usize, f64, Estimate)> = None;
    let mut off_count = 0;
    for k in set.iter() {
        let Ok(est) = estimate(signals, set.without(k), config, gate_m) else {
            continue;
        };
        let residual_m = residuals::residual(&signals[k], &est.position_m, est.stats.bias_m);
        if exact_after {
            if !off(residual_m) {
                continue;
            }
            off_count += 1;
        }
        if best
            .as_ref()
            .is_none_or(|b| est.stats.ssr_m2 < b.2.stats.ssr_m2)
        {
            best = Some((k, residual_m, est));
        }
    }
    match best {
        Some(b) if exact_after && off_count == 1 => Some(b),
        Some(b) if !exact_after && off(b.1) => Some(b),
        _ => None,
    }
}

fn into_fix(
    signals: &[Signal],
    set: Subset,
    config: &SolverConfig,
    est: Estimate,
    rejected: Vec<Rejection>,
    gate_m: f64,
) -> Fix {
    let redundancy = set.len() - config.mode.min_signals();
    let sigma2 = config.sigma_range_m * config.sigma_range_m;
    // With redundancy the residuals estimate the noise themselves; a fix
    // whose residuals say "noisier than configured" gets a wider covariance.
    let variance = if redundancy > 0 {
        sigma2.max(est.stats.ssr_m2 / redundancy as f64)
    } else {
        sigma2
    };
    let mut covariance_m2 = est.unit_covariance * variance;
    if config.mode.height_m().is_some() {
        covariance_m2.fixed_view_mut::<1, 3>(2, 0).fill(0.0);
        covariance_m2.fixed_view_mut::<3, 1>(0, 2).fill(0.0);
    }
    let quality = if est.stats.max_abs_m() > gate_m {
        Quality::Suspect
    } else if est.alternative_m.is_some() {
        Quality::Ambiguous
    } else if redundancy == 0 {
        Quality::Minimal
    } else {
        Quality::Good
    };
    Fix {
        t_s: signals.iter().map(|s| s.t_s).sum::<f64>() / signals.len().max(1) as f64,
        position_m: est.position_m,
        covariance_m2,
        bias_m: est.stats.bias_m,
        used_tx_ids: set.of(signals).map(|s| s.tx_id).collect(),
        residuals_m: set
            .of(signals)
            .map(|s| residuals::residual(s, &est.position_m, est.stats.bias_m))
            .collect(),
        rejected,
        quality,
        alternative_m: est.alternative_m,
        iterations: est.iterations,
        heading_rad: None,
    }
}
