//! The Cramer-Rao bound: its two derivations agree, and the refined solver
//! reaches it in a Monte-Carlo run.

use nalgebra::{DMatrix, Matrix3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::{ceiling, room, signals_at};
use crate::tdoa::*;

#[test]
fn crlb_equals_the_correlated_range_difference_form() {
    let p = Vector3::new(2.2, 1.7, 0.9);
    let sigma = 0.02;
    let tx = room();
    let bound = crlb(&tx, p, sigma, Mode::ThreeD).unwrap();
    // d_i = r_i - r_1 for i > 1: J rows g_i - g_1, Sigma = sigma^2 (I + 1 1^T).
    let g: Vec<Vector3<f64>> = tx.iter().map(|s| (p - s).normalize()).collect();
    let m = tx.len() - 1;
    let j = DMatrix::from_fn(m, 3, |i, k| g[i + 1][k] - g[0][k]);
    let sigma_d = (DMatrix::identity(m, m) + DMatrix::from_element(m, m, 1.0)) * sigma * sigma;
    let info = j.transpose() * sigma_d.try_inverse().unwrap() * &j;
    let expected = info.try_inverse().unwrap();
    for r in 0..3 {
        for c in 0..3 {
            let (a, b) = (bound.covariance_m2[(r, c)], expected[(r, c)]);
            assert!((a - b).abs() <= 1e-9 * expected.norm(), "{a} vs {b}");
        }
    }
    assert!((bound.rms_m - expected.trace().sqrt()).abs() < 1e-12);
    assert!((bound.rms_m - sigma * bound.dop.pdop).abs() < 1e-12);
    let vdop = bound.dop.vdop.unwrap();
    assert!((bound.dop.pdop.powi(2) - bound.dop.hdop.powi(2) - vdop.powi(2)).abs() < 1e-9);
}

#[test]
fn dop_of_a_2d_fix_has_no_vertical_part() {
    let d = dop(
        &ceiling(6),
        Vector3::new(3.0, 2.5, 9.9),
        Mode::TwoD { height_m: 0.5 },
    )
    .unwrap();
    assert_eq!(d.vdop, None);
    assert!((d.hdop - d.pdop).abs() < 1e-12);
    assert!(d.hdop > 0.0 && d.hdop.is_finite());
}

#[test]
fn crlb_rejects_degenerate_and_bad_input() {
    let p = Vector3::new(2.0, 2.0, 0.5);
    let two_d = Mode::TwoD { height_m: 0.5 };
    let line: Vec<_> = (0..4).map(|i| Vector3::new(i as f64, 0.0, 3.0)).collect();
    // Collinear seen from above with the receiver on the line's vertical
    // plane: nothing fixes y.
    let on_line = Vector3::new(1.5, 0.0, 0.5);
    assert_eq!(
        crlb(&line, on_line, 0.01, two_d),
        Err(SolveError::SingularInformation)
    );
    assert!(crlb(&room(), p, 0.0, Mode::ThreeD).is_err_and(|e| e.is_bad_input()));
    assert_eq!(
        crlb(&room()[..3], p, 0.01, Mode::ThreeD),
        Err(SolveError::TooFewSignals { got: 3, need: 4 })
    );
    let mut tx = room();
    tx[2].x = f64::NAN;
    assert!(dop(&tx, p, Mode::ThreeD).is_err_and(|e| e.is_bad_input()));
    // A receiver on a transmitter has no range gradient.
    assert_eq!(
        dop(&room(), room()[0], Mode::ThreeD),
        Err(SolveError::SingularInformation)
    );
}

#[test]
fn coplanar_transmitters_still_bound_a_3d_position_off_their_plane() {
    // The closed form needs non-coplanar transmitters, the information does
    // not: only the mirror image across the plane is lost, not local fixing.
    let b = crlb(&ceiling(6), Vector3::new(3.0, 2.5, 0.5), 0.01, Mode::ThreeD).unwrap();
    assert!(b.rms_m.is_finite() && b.rms_m > 0.0);
}

/// Mean squared error matrix of the refined solver around the truth over
/// `draws` seeded noise draws, and the mean reported covariance.
fn monte_carlo(
    tx: &[Vector3<f64>],
    p: Vector3<f64>,
    sigma: f64,
    mode: Mode,
    draws: usize,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let noise = Normal::new(0.0, sigma).unwrap();
    let config = SolverConfig {
        mode,
        sigma_range_m: sigma,
        max_rejections: 0,
        ..SolverConfig::default()
    };
    let mut mse = Matrix3::zeros();
    let mut reported = Matrix3::zeros();
    for _ in 0..draws {
        let mut s = signals_at(tx, p, 12.0);
        s.iter_mut()
            .for_each(|x| x.pseudo_range_m += noise.sample(&mut rng));
        let fix = solve(&s, &config).unwrap();
        let e = fix.position_m - p;
        mse += e * e.transpose();
        reported += fix.covariance_m2;
    }
    (mse / draws as f64, reported / draws as f64)
}

fn assert_reaches_crlb(tx: &[Vector3<f64>], p: Vector3<f64>, mode: Mode) {
    let sigma = 0.01;
    let bound = crlb(tx, p, sigma, mode).unwrap();
    let (mse, reported) = monte_carlo(tx, p, sigma, mode, 10_000);
    let ratio = mse.trace() / bound.covariance_m2.trace();
    println!(
        "{mode:?}: Monte-Carlo RMS {:.4} m, CRLB {:.4} m, variance ratio {ratio:.3}, \
         RMS ratio {:.3}",
        mse.trace().sqrt(),
        bound.rms_m,
        ratio.sqrt()
    );
    assert!((ratio - 1.0).abs() < 0.10, "variance ratio {ratio}");
    for k in 0..mode.dimension() {
        let axis = mse[(k, k)] / bound.covariance_m2[(k, k)];
        assert!((axis - 1.0).abs() < 0.10, "axis {k}: {axis}");
    }
    // The covariance the solver reports is the bound, widened only where
    // the residuals say so.
    let widening = reported.trace() / bound.covariance_m2.trace();
    assert!((1.0..1.5).contains(&widening), "reported/CRLB {widening}");
}

#[test]
fn refined_solver_reaches_the_crlb_in_3d() {
    assert_reaches_crlb(&room(), Vector3::new(2.5, 2.0, 1.0), Mode::ThreeD);
}

#[test]
fn refined_solver_reaches_the_crlb_in_2d() {
    assert_reaches_crlb(
        &ceiling(8),
        Vector3::new(3.5, 2.0, 0.4),
        Mode::TwoD { height_m: 0.4 },
    );
}
