//! Behaviour of both variants on synthetic measurements.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::estimator::history::InOrderFilter;
use crate::estimator::{InitialPose, Input, RangeDifferenceSample};

/// Eight transmitters on the corners of a 6 x 6 x 3 m room.
fn corners() -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    for &z in &[0.2, 2.8] {
        for &(x, y) in &[(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (0.0, 6.0)] {
            v.push([x, y, z]);
        }
    }
    v
}

fn measure(t_s: f64, p: [f64; 3], a: [f64; 3], b: [f64; 3], noise_m: f64) -> RangeDifferenceSample {
    let (p, va, vb) = (Vector3::from(p), Vector3::from(a), Vector3::from(b));
    RangeDifferenceSample {
        a_t_s: None,
        t_s,
        a_m: a,
        b_m: b,
        d_m: (p - vb).norm() - (p - va).norm() + noise_m,
        sigma_m: 0.05,
        clocks: None,
        speed_rel_sigma: None,
    }
}

/// Round-robin pairs (k, k+1) at 200 Hz along `path`, with Gaussian noise;
/// the worst and the RMS error over the second half.
fn fly(
    f: &mut TdoaEkf3d,
    path: impl Fn(f64) -> [f64; 3],
    seconds: f64,
    sigma_m: f64,
    seed: u64,
) -> (f64, f64) {
    let tx = corners();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma_m).unwrap();
    let (mut worst, mut sum2, mut n) = (0.0_f64, 0.0, 0.0);
    for k in 0..(seconds * 200.0) as usize {
        let t = k as f64 / 200.0;
        let (a, b) = (tx[k % 8], tx[(k + 1) % 8]);
        f.predict_to(t);
        f.update_range_difference(&measure(t, path(t), a, b, noise.sample(&mut rng)));
        if t > seconds / 2.0 {
            let e = Vector3::from(f.position_m()) - Vector3::from(path(t));
            worst = worst.max(e.norm());
            sum2 += e.norm_squared();
            n += 1.0;
        }
    }
    (worst, (sum2 / n).sqrt())
}

fn filter(start: [f64; 3]) -> TdoaEkf3d {
    TdoaEkf3d::new(TdoaEkf3dParams::default(), start, 0.0).unwrap()
}

#[test]
fn converges_to_a_still_tag_from_the_room_centre() {
    let mut f = filter([3.0, 3.0, 1.5]);
    let (worst, _) = fly(&mut f, |_| [1.0, 4.5, 0.8], 4.0, 0.0, 1);
    assert!(worst < 1e-3, "{worst}");
}

#[test]
fn tracks_a_tag_flying_a_circle_with_noisy_measurements() {
    let mut f = filter([3.0, 3.0, 1.5]);
    let circle = |t: f64| {
        [
            3.0 + 1.5 * (0.5 * t).cos(),
            3.0 + 1.5 * (0.5 * t).sin(),
            1.5,
        ]
    };
    // 5 cm of noise per measurement, 200 measurements a second.
    let (_, rms) = fly(&mut f, circle, 30.0, 0.05, 2);
    assert!(rms < 0.06, "{rms}");
    let v = Vector3::from(f.velocity_m_s()).norm();
    assert!((v - 0.75).abs() < 0.1, "{v}");
}

#[test]
fn physically_impossible_and_gated_measurements_leave_the_state_unchanged() {
    let mut f = filter([3.0, 3.0, 1.5]);
    fly(&mut f, |_| [2.0, 2.0, 1.0], 2.0, 0.0, 3);
    let before = (f.position_m(), f.velocity_m_s(), *f.covariance());
    let tx = corners();
    let mut m = measure(2.0, [2.0, 2.0, 1.0], tx[0], tx[1], 0.0);
    m.d_m = 6.5; // the transmitters are 6 m apart
    assert!(matches!(
        f.update_range_difference(&m),
        Outcome::Rejected(Rejection::Physical { .. })
    ));
    let outlier = measure(2.0, [2.0, 2.0, 1.0], tx[0], tx[1], 1.0);
    assert!(matches!(
        f.update_range_difference(&outlier),
        Outcome::Rejected(Rejection::Gate { normalised }) if normalised > 3.0
    ));
    let mut nan = outlier;
    nan.a_m[1] = f64::NAN;
    assert_eq!(
        f.update_range_difference(&nan),
        Outcome::Rejected(Rejection::NonFinite { field: "a_m" })
    );
    assert_eq!((f.position_m(), f.velocity_m_s(), *f.covariance()), before);
}

#[test]
fn a_filter_displaced_by_a_burst_comes_back_through_the_recovery() {
    // Certain of a wrong position: every true measurement fails the gate
    // until the run of rejections widens the variance.
    let params = TdoaEkf3dParams {
        initial_sigma_m: 0.01,
        initial_velocity_sigma_m_s: 0.01,
        accel_psd_m2_s3: 1e-4,
        ..TdoaEkf3dParams::default()
    };
    let mut f = TdoaEkf3d::new(params, [4.0, 1.0, 2.0], 0.0).unwrap();
    let (worst, _) = fly(&mut f, |_| [2.0, 4.0, 1.0], 10.0, 0.01, 4);
    assert!(f.recoveries() > 0);
    assert!(worst < 0.02, "{worst}");
}

#[test]
fn time_differences_are_converted_at_the_propagation_speed() {
    let tx = corners();
    let m = measure(0.0, [2.0, 2.0, 1.0], tx[0], tx[6], 0.0);
    let mut by_range = filter([3.0, 3.0, 1.5]);
    let mut by_time = by_range.clone();
    let speed = by_time.params().propagation_speed_m_s;
    by_range.update_range_difference(&m);
    by_time.update_time_difference(0.0, m.a_m, m.b_m, m.d_m / speed, m.sigma_m / speed);
    let (a, b) = (by_range.position_m(), by_time.position_m());
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() < 1e-9);
    }
}

#[test]
fn older_or_non_finite_times_do_not_move_the_state() {
    let mut f = filter([3.0, 3.0, 1.5]);
    f.predict_to(1.0);
    let before = f.clone();
    f.predict_to(0.5);
    f.predict_to(f64::NAN);
    assert_eq!(f, before);
}

#[test]
fn bad_parameters_are_named() {
    let p = TdoaEkf3dParams {
        gate_sigma: f64::NAN,
        ..TdoaEkf3dParams::default()
    };
    let err = TdoaEkf3d::new(p, [0.0; 3], 0.0).unwrap_err();
    assert_eq!(err.field, "gate_sigma");
    let err = TdoaEkf3d::new(TdoaEkf3dParams::default(), [f64::NAN, 0.0, 0.0], 0.0).unwrap_err();
    assert_eq!(err.field, "start");
}

#[test]
fn ground_variant_starts_at_the_transmitters_centroid_and_converges() {
    let params = TdoaEkfParams {
        receiver_height_m: 0.5,
        ..TdoaEkfParams::default()
    };
    let mut e = TdoaEkf::new(&params);
    let tx = corners();
    let truth = [1.5, 4.0, 0.5];
    assert!(e.pose().is_none());
    for k in 0..400 {
        let t = k as f64 * 0.01;
        e.step(&Input::RangeDifference(measure(
            t,
            truth,
            tx[k % 8],
            tx[(k + 3) % 8],
            0.0,
        )));
    }
    let p = e.pose().unwrap();
    assert!(
        (p.x_m - 1.5).abs() < 1e-3 && (p.y_m - 4.0).abs() < 1e-3,
        "{p:?}"
    );
    assert!(e.last_outcome().unwrap().is_accepted());
}

#[test]
fn ground_variant_uses_the_known_start_pose_and_ignores_fixes() {
    let params = TdoaEkfParams {
        initial_pose: Some(InitialPose {
            x_m: 1.0,
            y_m: 2.0,
            ..InitialPose::default()
        }),
        ..TdoaEkfParams::default()
    };
    let mut e = TdoaEkf::new(&params);
    e.step(&Input::Fix(crate::tdoa::Fix::from_position(
        0.1,
        5.0,
        5.0,
        nalgebra::Matrix2::identity() * 1e-4,
    )));
    let p = e.pose().unwrap();
    assert_eq!((p.x_m, p.y_m), (1.0, 2.0));
}

#[test]
fn the_receiver_id_heading_pulls_the_heading_and_a_wrong_sector_is_gated() {
    let params = TdoaEkfParams {
        initial_pose: Some(InitialPose {
            x_m: 1.0,
            y_m: 1.0,
            theta_rad: 0.0,
            sigma_xy_m: 0.02,
            sigma_theta_rad: 0.5,
        }),
        ..TdoaEkfParams::default()
    };
    let fix = |t_s: f64, heading: f64| {
        Input::Fix(
            crate::tdoa::Fix::from_position(t_s, 9.0, 9.0, nalgebra::Matrix2::identity() * 1e-4)
                .with_heading(Some(heading)),
        )
    };
    let mut f = TdoaEkf::new(&params);
    f.step(&fix(0.1, 0.3));
    let p = f.pose().unwrap();
    // The fix's position is not fused, its heading is: sigma 30 deg
    // (0.274 rad^2) against a 0.5 rad prior (0.25 rad^2) gives a gain of
    // 0.48, so 0.3 rad pulls it to 0.143.
    assert_eq!((p.x_m, p.y_m), (1.0, 1.0));
    assert!((p.theta_rad - 0.143).abs() < 0.001, "{p:?}");
    let before = p.theta_rad;
    f.step(&fix(0.2, 3.0));
    assert_eq!(f.pose().unwrap().theta_rad, before);
}
