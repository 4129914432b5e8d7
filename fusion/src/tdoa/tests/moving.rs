//! Motion-compensated fixes: a receiver driving along a corridor while the
//! cycle's arrivals come in one after another.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::tdoa::*;

/// Two rows of transmitters on a 2.6 m ceiling over a 2 m wide corridor.
fn corridor() -> Vec<Vector3<f64>> {
    (0..8)
        .map(|i| {
            let x = 1.0 + 1.5 * f64::from(i / 2);
            let y = if i % 2 == 0 { 0.3 } else { 1.7 };
            Vector3::new(x, y, 2.6)
        })
        .collect()
}

const HEIGHT_M: f64 = 0.5;

fn config() -> SolverConfig {
    SolverConfig {
        mode: Mode::TwoD { height_m: HEIGHT_M },
        sigma_range_m: 0.024,
        ..SolverConfig::default()
    }
}

/// One cycle heard from a receiver starting at `p0` and moving at `v`:
/// signal `i` arrives `0.05 i` s after the reference instant. Returns the
/// signals and their arrival times.
fn moving_cycle(
    p0: Vector3<f64>,
    v: Vector3<f64>,
    noise_m: f64,
    rng: &mut ChaCha8Rng,
) -> (Vec<Signal>, Vec<f64>) {
    let noise = Normal::new(0.0, noise_m.max(1e-12)).unwrap();
    let times: Vec<f64> = (0..8).map(|i| 0.05 * f64::from(i)).collect();
    let signals = corridor()
        .iter()
        .zip(&times)
        .enumerate()
        .map(|(i, (s, t))| {
            let at = p0 + v * *t;
            Signal {
                tx_id: i as u32,
                tx_m: *s,
                pseudo_range_m: (at - s).norm() + 3.0 + noise_m * noise.sample(rng),
                t_s: *t,
            }
        })
        .collect();
    (signals, times)
}

#[test]
fn noise_free_moving_receiver_is_exact_with_its_displacements() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let p0 = Vector3::new(3.0, 1.2, HEIGHT_M);
    let v = Vector3::new(0.3, 0.0, 0.0);
    let (signals, times) = moving_cycle(p0, v, 0.0, &mut rng);
    let m = displacements_at_velocity(&times, 0.0, v);
    let fix = solve_moving(&signals, &m, &config()).unwrap();
    assert!((fix.position_m - p0).norm() < 1e-6, "{fix:?}");
    // The one-position solver is off by centimetres on the same data.
    let plain = solve(&signals, &config()).unwrap();
    assert!((plain.position_m - p0).norm() > 0.02, "{plain:?}");
}

#[test]
fn zero_displacements_give_the_plain_solve() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let (signals, _) = moving_cycle(
        Vector3::new(4.0, 0.8, HEIGHT_M),
        Vector3::zeros(),
        0.02,
        &mut rng,
    );
    let zeros = vec![Vector3::zeros(); signals.len()];
    assert_eq!(
        solve_moving(&signals, &zeros, &config()).unwrap(),
        solve(&signals, &config()).unwrap()
    );
}

#[test]
fn compensation_lowers_the_mean_error_of_noisy_fixes_on_the_move() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let v = Vector3::new(0.3, 0.0, 0.0);
    let (mut plain, mut moving) = (0.0, 0.0);
    let n = 300;
    for k in 0..n {
        let p0 = Vector3::new(2.5 + 0.01 * f64::from(k), 1.0, HEIGHT_M);
        let (signals, times) = moving_cycle(p0, v, 0.024, &mut rng);
        let m = displacements_at_velocity(&times, 0.0, v);
        moving += (solve_moving(&signals, &m, &config()).unwrap().position_m - p0).norm();
        plain += (solve(&signals, &config()).unwrap().position_m - p0).norm();
    }
    let (plain, moving) = (plain / f64::from(n), moving / f64::from(n));
    assert!(moving < 0.7 * plain, "moving {moving} plain {plain}");
}

#[test]
fn mismatched_or_non_finite_displacements_are_bad_input() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (signals, _) = moving_cycle(
        Vector3::new(3.0, 1.0, HEIGHT_M),
        Vector3::zeros(),
        0.0,
        &mut rng,
    );
    let short = vec![Vector3::zeros(); signals.len() - 1];
    let err = solve_moving(&signals, &short, &config()).unwrap_err();
    assert!(err.is_bad_input(), "{err}");
    let mut nan = vec![Vector3::zeros(); signals.len()];
    nan[2].y = f64::NAN;
    assert_eq!(
        solve_moving(&signals, &nan, &config()).unwrap_err(),
        SolveError::NonFinite {
            field: "displacements_m",
            index: 2
        }
    );
}

#[test]
fn displacements_from_a_track_interpolate_and_hold_at_the_ends() {
    let track = [(0.0, [1.0, 1.0]), (1.0, [2.0, 1.0]), (2.0, [2.0, 3.0])];
    let m = displacements_from_track(&track, &[0.5, 1.5, 3.0, -1.0], 1.0).unwrap();
    let expect = [[-0.5, 0.0], [0.0, 1.0], [0.0, 2.0], [-1.0, 0.0]];
    for (got, want) in m.iter().zip(expect) {
        assert!((got.x - want[0]).abs() < 1e-12 && (got.y - want[1]).abs() < 1e-12);
        assert_eq!(got.z, 0.0);
    }
    assert!(displacements_from_track(&[], &[0.0], 0.0).is_none());
    let backwards = [(1.0, [0.0, 0.0]), (0.0, [1.0, 0.0])];
    assert!(displacements_from_track(&backwards, &[0.5], 0.0).is_none());
}
