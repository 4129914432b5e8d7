//! Exact recovery on noise-free data, and agreement of the closed form with
//! the refinement.

use nalgebra::Vector3;
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::{ceiling, room, signals_at};
use crate::tdoa::refine::refine_subset;
use crate::tdoa::signal::Subset;
use crate::tdoa::*;

const EXACT_M: f64 = 1e-6;

fn point(lo: [f64; 3], hi: [f64; 3]) -> impl Strategy<Value = Vector3<f64>> {
    (lo[0]..hi[0], lo[1]..hi[1], lo[2]..hi[2]).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

/// Transmitters anywhere in a 10 x 10 x 4 m hall.
fn hall(n: std::ops::RangeInclusive<usize>) -> impl Strategy<Value = Vec<Vector3<f64>>> {
    prop::collection::vec(point([0.0; 3], [10.0, 10.0, 4.0]), n)
}

/// Transmitters near a ceiling (2.5-3.5 m), or exactly on it.
fn overhead(n: std::ops::RangeInclusive<usize>) -> impl Strategy<Value = Vec<Vector3<f64>>> {
    (
        prop::collection::vec(point([0.0, 0.0, 2.5], [10.0, 10.0, 3.5]), n),
        any::<bool>(),
    )
        .prop_map(|(mut tx, flat)| {
            if flat {
                tx.iter_mut().for_each(|s| s.z = 3.0);
            }
            tx
        })
}

/// The closed form, with random geometries that happen to be flat skipped.
fn closed(signals: &[Signal], mode: Mode) -> Option<ClosedForm> {
    match closed_form(signals, mode) {
        Err(SolveError::DegenerateGeometry { .. }) => None,
        r => Some(r.expect("noise-free data has a root")),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn closed_form_recovers_exact_3d_positions(
        tx in hall(5..=12), p in point([1.0; 3], [9.0, 9.0, 3.5]), bias in -50.0..50.0f64,
    ) {
        let Some(cf) = closed(&signals_at(&tx, p, bias), Mode::ThreeD) else {
            return Err(TestCaseError::reject("flat draw"));
        };
        prop_assert!((cf.best.position_m - p).norm() < EXACT_M, "{cf:?} vs {p:?}");
        prop_assert!((cf.best.bias_m - bias).abs() < EXACT_M);
    }

    #[test]
    fn closed_form_with_four_signals_has_the_truth_among_its_roots(
        tx in hall(4..=4), p in point([1.0; 3], [9.0, 9.0, 3.5]), bias in -50.0..50.0f64,
    ) {
        let Some(cf) = closed(&signals_at(&tx, p, bias), Mode::ThreeD) else {
            return Err(TestCaseError::reject("flat draw"));
        };
        prop_assert!(cf.candidates().any(|c| (c.position_m - p).norm() < EXACT_M), "{cf:?}");
    }

    #[test]
    fn closed_form_recovers_exact_2d_positions(
        tx in overhead(4..=12), p in point([0.5, 0.5, 0.0], [9.5, 9.5, 1.5]), bias in -50.0..50.0f64,
    ) {
        let mode = Mode::TwoD { height_m: p.z };
        let Some(cf) = closed(&signals_at(&tx, p, bias), mode) else {
            return Err(TestCaseError::reject("collinear draw"));
        };
        prop_assert!((cf.best.position_m - p).norm() < EXACT_M, "{cf:?} vs {p:?}");
    }

    #[test]
    fn closed_form_with_three_signals_in_2d_has_the_truth_among_its_roots(
        tx in overhead(3..=3), p in point([0.5, 0.5, 0.0], [9.5, 9.5, 1.5]),
    ) {
        let mode = Mode::TwoD { height_m: p.z };
        let Some(cf) = closed(&signals_at(&tx, p, 7.0), mode) else {
            return Err(TestCaseError::reject("collinear draw"));
        };
        prop_assert!(cf.candidates().any(|c| (c.position_m - p).norm() < EXACT_M), "{cf:?}");
    }

    #[test]
    fn solve_recovers_exact_positions_without_rejecting_anything(
        p in point([0.3, 0.3, 0.2], [5.7, 4.7, 2.8]), bias in -50.0..50.0f64, two_d in any::<bool>(),
    ) {
        let (tx, mode) = if two_d {
            (ceiling(6), Mode::TwoD { height_m: p.z })
        } else {
            (room(), Mode::ThreeD)
        };
        let config = SolverConfig { mode, sigma_range_m: 0.01, ..SolverConfig::default() };
        let fix = solve(&signals_at(&tx, p, bias), &config).unwrap();
        prop_assert!((fix.position_m - p).norm() < EXACT_M, "{fix:?} vs {p:?}");
        prop_assert_eq!(fix.quality, Quality::Good);
        prop_assert!(fix.rejected.is_empty());
        prop_assert_eq!(fix.used_tx_ids.len(), tx.len());
        prop_assert!(fix.residuals_m.iter().all(|r| r.abs() < EXACT_M));
    }

    #[test]
    fn refinement_returns_to_the_truth_from_a_displaced_start(
        p in point([0.5, 0.5, 0.5], [5.5, 4.5, 2.5]), offset in point([-0.4; 3], [0.4; 3]),
    ) {
        let signals = signals_at(&room(), p, 3.0);
        let set = Subset::first(signals.len());
        let r = refine_subset(&signals, set, Mode::ThreeD, p + offset, 20).unwrap();
        prop_assert!((r.position_m - p).norm() < EXACT_M, "{:?} vs {p:?}", r.position_m);
        prop_assert!(r.iterations < 20);
    }
}

#[test]
fn refinement_stays_on_an_exact_closed_form_fix() {
    let p = Vector3::new(2.2, 3.1, 0.8);
    let signals = signals_at(&room(), p, -4.0);
    let cf = closed_form(&signals, Mode::ThreeD).unwrap();
    let set = Subset::first(signals.len());
    let r = refine_subset(&signals, set, Mode::ThreeD, cf.best.position_m, 10).unwrap();
    assert!((r.position_m - cf.best.position_m).norm() < 1e-9);
    assert!(r.iterations <= 2, "{}", r.iterations);
}

#[test]
fn refinement_agrees_with_the_closed_form_on_noisy_data_and_fits_better() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let sigma = 0.01;
    let noise = Normal::new(0.0, sigma).unwrap();
    for (tx, mode) in [
        (room(), Mode::ThreeD),
        (ceiling(8), Mode::TwoD { height_m: 0.4 }),
    ] {
        let p = Vector3::new(2.5, 2.0, mode.height_m().unwrap_or(1.0));
        let bound = crlb(&tx, p, sigma, mode).unwrap();
        for _ in 0..200 {
            let mut signals = signals_at(&tx, p, 1.0);
            signals
                .iter_mut()
                .for_each(|s| s.pseudo_range_m += noise.sample(&mut rng));
            let cf = closed_form(&signals, mode).unwrap().best;
            let set = Subset::first(signals.len());
            let r = refine_subset(&signals, set, mode, cf.position_m, 10).unwrap();
            let d = (r.position_m - cf.position_m).norm();
            assert!(d < 5.0 * bound.rms_m, "{d} vs CRLB {}", bound.rms_m);
            assert!(r.at.cost_m2 <= cf.rms_residual_m.powi(2) * signals.len() as f64 + 1e-15);
        }
    }
}

#[test]
fn solve_without_refinement_returns_the_closed_form_fix() {
    let p = Vector3::new(1.2, 3.9, 0.6);
    let mode = Mode::TwoD { height_m: 0.6 };
    let signals = signals_at(&ceiling(5), p, 0.3);
    let config = SolverConfig {
        mode,
        refine: false,
        ..SolverConfig::default()
    };
    let fix = solve(&signals, &config).unwrap();
    let cf = closed_form(&signals, mode).unwrap();
    assert_eq!(fix.iterations, 0);
    assert_eq!(fix.position_m, cf.best.position_m);
    assert!((fix.position_m - p).norm() < EXACT_M);
    assert_eq!(fix.covariance_m2[(2, 2)], 0.0);
    assert!(fix.covariance_xy_m2().determinant() > 0.0);
}
