//! Refinement on pairwise range differences with no common reference, as
//! UWB TDOA systems measure them (anchor pairs, each pair on its own).

use nalgebra::{Matrix3, Vector3};

use super::refine::unit;
use super::{RefineConfig, SolveError};

/// One range difference: `|p - b| - |p - a| = d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairMeasurement {
    /// First transmitter (anchor), metres.
    pub a_m: Vector3<f64>,
    /// Second transmitter, metres.
    pub b_m: Vector3<f64>,
    /// Measured `|p - b| - |p - a|`, metres.
    pub d_m: f64,
}

/// A 3D position from [`refine_pairs`].
#[derive(Debug, Clone, PartialEq)]
pub struct Solution3 {
    /// Position, metres.
    pub position_m: Vector3<f64>,
    /// `sigma^2 (H^T H)^-1`, with `sigma` the configured noise or the
    /// residuals' own scale when larger, m^2.
    pub covariance_m2: Matrix3<f64>,
    /// `d - (|p - b| - |p - a|)` per pair, in input order, metres.
    pub residuals_m: Vec<f64>,
    /// Iterations run.
    pub iterations: u32,
}

/// Gauss-Newton with step halving from `start_m` on independent pairwise
/// range differences (each with noise `config.sigma_m`). Needs at least 3
/// pairs whose gradients span 3D.
pub fn refine_pairs(
    pairs: &[PairMeasurement],
    start_m: Vector3<f64>,
    config: &RefineConfig,
) -> Result<Solution3, SolveError> {
    config.validate()?;
    validate(pairs, &start_m)?;
    let mut p = start_m;
    let (mut cost, mut info, mut hte) = linearise(pairs, &p);
    let mut iterations = 0;
    let mut last_step_m = f64::INFINITY;
    while iterations < config.max_iterations {
        iterations += 1;
        let step = solve3(&info)?.solve(&hte);
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..=12 {
            let candidate = p + step * t;
            let lin = linearise(pairs, &candidate);
            if lin.0 <= cost {
                accepted = Some((candidate, lin));
                break;
            }
            t *= 0.5;
        }
        let Some((next, lin)) = accepted else {
            // No descent left: a minimum to rounding.
            last_step_m = 0.0;
            break;
        };
        last_step_m = (step * t).norm();
        p = next;
        (cost, info, hte) = lin;
        if last_step_m < config.step_tolerance_m {
            break;
        }
    }
    if last_step_m >= config.step_tolerance_m || !p.iter().all(|v| v.is_finite()) {
        return Err(SolveError::NotConverged {
            iterations,
            last_step_m,
        });
    }
    let redundancy = pairs.len() - 3;
    let sigma2 = config.sigma_m * config.sigma_m;
    let variance = if redundancy > 0 {
        sigma2.max(cost / redundancy as f64)
    } else {
        sigma2
    };
    Ok(Solution3 {
        position_m: p,
        covariance_m2: solve3(&info)?.inverse() * variance,
        residuals_m: pairs.iter().map(|m| residual(m, &p)).collect(),
        iterations,
    })
}

fn validate(pairs: &[PairMeasurement], start_m: &Vector3<f64>) -> Result<(), SolveError> {
    if !start_m.iter().all(|v| v.is_finite()) {
        return Err(SolveError::NonFinite {
            field: "start_m",
            index: 0,
        });
    }
    for (index, m) in pairs.iter().enumerate() {
        let finite = m.a_m.iter().chain(m.b_m.iter()).all(|v| v.is_finite());
        if !finite {
            return Err(SolveError::NonFinite {
                field: "a_m/b_m",
                index,
            });
        }
        if !m.d_m.is_finite() {
            return Err(SolveError::NonFinite {
                field: "d_m",
                index,
            });
        }
        if m.a_m == m.b_m {
            return Err(SolveError::CoincidentPair { index });
        }
    }
    if pairs.len() < 3 {
        return Err(SolveError::TooFewSignals {
            got: pairs.len(),
            need: 3,
        });
    }
    Ok(())
}

fn residual(m: &PairMeasurement, p: &Vector3<f64>) -> f64 {
    m.d_m - ((p - m.b_m).norm() - (p - m.a_m).norm())
}

/// Cost, `H^T H` and `H^T e` at `p`, with `H` rows `g_b - g_a`.
fn linearise(pairs: &[PairMeasurement], p: &Vector3<f64>) -> (f64, Matrix3<f64>, Vector3<f64>) {
    let mut cost = 0.0;
    let mut info = Matrix3::zeros();
    let mut hte = Vector3::zeros();
    for m in pairs {
        let (ga, ra) = unit(p, &m.a_m, false);
        let (gb, rb) = unit(p, &m.b_m, false);
        let h = gb - ga;
        let e = m.d_m - (rb - ra);
        cost += e * e;
        info += h * h.transpose();
        hte += h * e;
    }
    (cost, info, hte)
}

fn solve3(info: &Matrix3<f64>) -> Result<nalgebra::Cholesky<f64, nalgebra::U3>, SolveError> {
    let eigen = info.symmetric_eigenvalues();
    if eigen.min().is_nan() || eigen.min() <= 1e-12 * eigen.max() {
        return Err(SolveError::SingularInformation);
    }
    info.cholesky().ok_or(SolveError::SingularInformation)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn anchors() -> [Vector3<f64>; 6] {
        [
            Vector3::new(0.0, 0.0, 0.2),
            Vector3::new(6.0, 0.0, 2.8),
            Vector3::new(6.0, 5.0, 0.3),
            Vector3::new(0.0, 5.0, 2.7),
            Vector3::new(3.0, -0.5, 1.5),
            Vector3::new(3.2, 5.5, 2.9),
        ]
    }

    fn pairs_at(p: Vector3<f64>) -> Vec<PairMeasurement> {
        let a = anchors();
        // A chain of pairs and some crossings: no common reference.
        [
            (0, 1),
            (1, 2),
            (2, 3),
            (3, 4),
            (4, 5),
            (5, 0),
            (0, 2),
            (1, 3),
        ]
        .iter()
        .map(|&(i, j)| PairMeasurement {
            a_m: a[i],
            b_m: a[j],
            d_m: (p - a[j]).norm() - (p - a[i]).norm(),
        })
        .collect()
    }

    #[test]
    fn refine_pairs_recovers_an_exact_position_from_a_rough_start() {
        let truth = Vector3::new(2.1, 3.3, 1.2);
        let sol = refine_pairs(
            &pairs_at(truth),
            Vector3::new(3.0, 2.5, 1.5),
            &RefineConfig::default(),
        )
        .unwrap();
        assert!((sol.position_m - truth).norm() < 1e-6, "{sol:?}");
        assert!(sol.residuals_m.iter().all(|r| r.abs() < 1e-6));
        assert!(sol.covariance_m2.trace() > 0.0);
    }

    #[test]
    fn refine_pairs_rejects_bad_input() {
        let truth = Vector3::new(2.1, 3.3, 1.2);
        let cfg = RefineConfig::default();
        let mut pairs = pairs_at(truth);
        assert_eq!(
            refine_pairs(&pairs[..2], truth, &cfg),
            Err(SolveError::TooFewSignals { got: 2, need: 3 })
        );
        pairs[1].b_m = pairs[1].a_m;
        assert_eq!(
            refine_pairs(&pairs, truth, &cfg),
            Err(SolveError::CoincidentPair { index: 1 })
        );
        let mut pairs = pairs_at(truth);
        pairs[2].d_m = f64::NAN;
        assert!(matches!(
            refine_pairs(&pairs, truth, &cfg),
            Err(SolveError::NonFinite {
                field: "d_m",
                index: 2
            })
        ));
        let bad = RefineConfig {
            sigma_m: 0.0,
            ..cfg
        };
        assert!(refine_pairs(&pairs_at(truth), truth, &bad).is_err_and(|e| e.is_bad_input()));
    }

    #[test]
    fn refine_pairs_reports_a_degenerate_geometry() {
        // Three pairs along one line through the receiver: no 3D fix.
        let a = Vector3::new(0.0, 0.0, 0.0);
        let pairs: Vec<_> = [1.0, 2.0, 3.0]
            .iter()
            .map(|&x| PairMeasurement {
                a_m: a,
                b_m: Vector3::new(x, 0.0, 0.0),
                d_m: 0.0,
            })
            .collect();
        assert_eq!(
            refine_pairs(
                &pairs,
                Vector3::new(5.0, 0.0, 0.0),
                &RefineConfig::default()
            ),
            Err(SolveError::SingularInformation)
        );
    }
}
