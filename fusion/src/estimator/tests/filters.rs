//! Hand-computed steps, late inputs, bad inputs, reset.

use nalgebra::Matrix2;

use super::runs::{config, feed_for};
use super::sim::{Circle, GEOMETRY, Noise, circling_run};
use crate::estimator::cda::{Cda, CdaParams, HeadingSource};
use crate::estimator::gyro_ckf::GyroCkfParams;
use crate::estimator::history::LateInputHistory;
use crate::estimator::ickon_akf::IckonAkfParams;
use crate::estimator::{
    EncoderSample, Estimator, EstimatorConfig, EstimatorError, GyroSample, InitialPose, Input,
    OdometrySample, RangeSample, build, names, two_sensor_heading,
};
use crate::tdoa::Fix;

fn odo(t_s: f64, x_m: f64, y_m: f64, theta_rad: f64) -> Input {
    Input::Odometry(OdometrySample {
        t_s,
        x_m,
        y_m,
        theta_rad,
    })
}

fn fix(t_s: f64, x_m: f64, y_m: f64, heading_rad: Option<f64>) -> Input {
    Input::Fix(
        Fix::from_position(t_s, x_m, y_m, Matrix2::from_diagonal_element(1e-4))
            .with_heading(heading_rad),
    )
}

fn gyro(t_s: f64, rate_rad_s: f64) -> Input {
    Input::Gyro(GyroSample { t_s, rate_rad_s })
}

fn enc(t_s: f64, left_ticks: i64, right_ticks: i64) -> Input {
    Input::Encoders(EncoderSample {
        t_s,
        left_ticks,
        right_ticks,
        geometry: GEOMETRY,
    })
}

fn origin(sigma_xy_m: f64, sigma_theta_rad: f64) -> InitialPose {
    InitialPose {
        x_m: 0.0,
        y_m: 0.0,
        theta_rad: 0.0,
        sigma_xy_m,
        sigma_theta_rad,
    }
}

#[test]
fn ickon_akf_steps_match_hand_computation() {
    let params = IckonAkfParams {
        initial_pose: Some(origin(0.01, 1.0_f64.to_radians())),
        ..IckonAkfParams::default()
    };
    let mut e = build(&EstimatorConfig::IckonAkf(params)).unwrap();
    e.handle(&odo(0.0, 0.0, 0.0, 0.0)).unwrap();
    e.handle(&odo(0.1, 0.1, 0.0, 0.1)).unwrap();
    e.handle(&fix(0.1, 0.12, 0.02, Some(0.3))).unwrap();
    let p = e.pose().unwrap();

    // Heading: P = 1 + 4 deg^2, K = 5 / (5 + 900), gamma = 0.1 + K (0.3 - 0.1).
    let deg2 = (1.0_f64).to_radians().powi(2);
    let kh = 5.0 / 905.0;
    assert!((p.theta_rad - (0.1 + kh * 0.2)).abs() < 1e-12);
    assert!((p.covariance[(2, 2)] - (1.0 - kh) * 5.0 * deg2).abs() < 1e-15);

    // Position: dd = 0.1 along gamma = 0.1 (eq. 9-11); P = 100 + 4 mm^2;
    // R = 0.025 r^2 per axis (eq. 19).
    let (px, py) = (0.1 * 0.1_f64.cos(), 0.1 * 0.1_f64.sin());
    let (rx, ry) = (0.12 - px, 0.02 - py);
    let prior = 104e-6;
    let kx = prior / (prior + 0.025 * rx * rx);
    let ky = prior / (prior + 0.025 * ry * ry);
    assert!((p.x_m - (px + kx * rx)).abs() < 1e-12);
    assert!((p.y_m - (py + ky * ry)).abs() < 1e-12);
    assert!((p.covariance[(0, 0)] - (1.0 - kx) * prior).abs() < 1e-15);
    assert!((p.covariance[(1, 1)] - (1.0 - ky) * prior).abs() < 1e-15);
}

#[test]
fn gyro_ckf_steps_match_hand_computation() {
    let params = GyroCkfParams {
        initial_pose: Some(origin(0.01, 0.1)),
        ..GyroCkfParams::default()
    };
    let mut e = build(&EstimatorConfig::GyroCkf(params)).unwrap();
    let dt = 0.01;
    e.handle(&gyro(0.0, 0.2)).unwrap();
    e.handle(&gyro(dt, 0.2)).unwrap();
    e.handle(&fix(dt, 0.0, 0.0, Some(0.05))).unwrap();
    e.handle(&gyro(2.0 * dt, 0.2)).unwrap();
    let p = e.pose().unwrap();

    // Error state [d_theta, d_omega], A = [[1, -dt], [0, 1]] (eq. 11).
    let p00 = 0.1_f64.powi(2);
    let p11 = 1.0_f64.to_radians().powi(2);
    let qt = 0.05_f64.to_radians().powi(2) * dt;
    // Predicted P00 and P01; P11 (= p11 + qb) does not enter the gain.
    let (a00, a01) = (p00 + dt * dt * p11 + qt, -dt * p11);
    let theta = 0.2 * dt;
    let innovation = 0.05 - theta;
    let s = a00 + 30.0_f64.to_radians().powi(2);
    let (k0, k1) = (a00 / s, a01 / s);
    let theta = theta + k0 * innovation;
    let bias = k1 * innovation;
    let theta = theta + (0.2 - bias) * dt;
    assert!(
        (p.theta_rad - theta).abs() < 1e-12,
        "{} vs {theta}",
        p.theta_rad
    );
    assert!(
        bias < 0.0,
        "a heading above the gyro's means the bias was overestimated"
    );
}

#[test]
fn two_sensor_heading_matches_the_igps_papers_eq_1() {
    // Sensor 2 on the right of sensor 1 when facing +x.
    assert!(two_sensor_heading(0.0, 0.2, 0.0, -0.2).abs() < 1e-12);
    let h = two_sensor_heading(0.0, 0.0, 1.0, 0.0);
    assert!((h - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn late_fixes_give_the_same_pose_as_fixes_in_time_order() {
    let circle = Circle {
        v_m_s: 0.3,
        omega_rad_s: 0.4,
        rest_s: 1.0,
    };
    let noise = Noise {
        gyro_bias_rad_s: 0.01,
        fix_sigma_m: 0.02,
        ..Noise::default()
    };
    let in_order = circling_run(&circle, 20.0, noise, 7);
    let late = circling_run(
        &circle,
        20.0,
        Noise {
            fix_latency_s: 0.25,
            ..noise
        },
        7,
    );
    for name in names() {
        let mut a = build(&config(name)).unwrap();
        let mut b = build(&config(name)).unwrap();
        for i in feed_for(name, &in_order) {
            a.handle(&i).unwrap();
        }
        for i in feed_for(name, &late) {
            b.handle(&i).unwrap();
        }
        let (pa, pb) = (a.pose().unwrap(), b.pose().unwrap());
        assert!((pa.x_m - pb.x_m).abs() < 1e-9, "{name}: {pa:?} vs {pb:?}");
        assert!((pa.y_m - pb.y_m).abs() < 1e-9, "{name}");
        assert!((pa.theta_rad - pb.theta_rad).abs() < 1e-9, "{name}");
    }
}

#[test]
fn input_older_than_the_history_is_rejected_and_changes_nothing() {
    let mut e = build(&config("ickon-akf")).unwrap();
    e.handle(&fix(0.0, 1.0, 1.0, Some(0.0))).unwrap();
    for k in 0..=50 {
        e.handle(&odo(f64::from(k) * 0.1, 0.0, 0.0, 0.0)).unwrap();
    }
    let before = e.pose();
    let err = e.handle(&fix(1.0, 3.0, 3.0, None)).unwrap_err();
    assert!(matches!(err, EstimatorError::TooLate { .. }), "{err}");
    assert_eq!(e.pose(), before);
}

#[test]
fn non_finite_inputs_are_rejected_and_change_nothing() {
    let bad = [
        odo(1.0, f64::NAN, 0.0, 0.0),
        odo(f64::INFINITY, 0.0, 0.0, 0.0),
        gyro(1.0, f64::NAN),
        fix(1.0, 0.0, f64::NEG_INFINITY, None),
        fix(1.0, 0.0, 0.0, Some(f64::NAN)),
        Input::Range(RangeSample {
            t_s: 1.0,
            left_ultrasonic_m: Some(f64::NAN),
            ..RangeSample::default()
        }),
        Input::Encoders(EncoderSample {
            t_s: 1.0,
            left_ticks: 0,
            right_ticks: 0,
            geometry: crate::estimator::WheelGeometry {
                wheel_base_m: 0.0,
                ..GEOMETRY
            },
        }),
        Input::RangeDifference(crate::estimator::RangeDifferenceSample {
            a_t_s: None,
            t_s: 1.0,
            a_m: [0.0, 0.0, 2.5],
            b_m: [10.0, 0.0, 2.5],
            d_m: f64::NAN,
            sigma_m: 0.02,
            clocks: None,
            speed_rel_sigma: None,
        }),
    ];
    for name in names() {
        let mut e = build(&config(name)).unwrap();
        e.handle(&fix(0.0, 1.0, 1.0, Some(0.0))).unwrap();
        e.handle(&odo(0.0, 0.0, 0.0, 0.0)).unwrap();
        let before = e.pose();
        for input in &bad {
            assert!(e.handle(input).is_err(), "{name} accepted {input:?}");
            assert_eq!(e.pose(), before, "{name} changed on {input:?}");
        }
    }
}

#[test]
fn reset_returns_every_estimator_to_its_constructed_state() {
    let circle = Circle {
        v_m_s: 0.2,
        omega_rad_s: 0.3,
        rest_s: 1.0,
    };
    let inputs = circling_run(&circle, 10.0, Noise::default(), 3);
    for name in names() {
        let fresh = build(&config(name)).unwrap();
        let mut e = build(&config(name)).unwrap();
        for i in feed_for(name, &inputs) {
            e.handle(&i).unwrap();
        }
        e.reset();
        assert_eq!(e.pose(), fresh.pose(), "{name}");
        // And it runs again from scratch, including old timestamps.
        for i in feed_for(name, &inputs) {
            e.handle(&i).unwrap();
        }
    }
}

#[test]
fn fix_after_a_long_gap_reinitialises_the_position() {
    for name in ["ickon-akf", "gyro-ckf", "cda-msu"] {
        let mut e = build(&config(name)).unwrap();
        e.handle(&fix(0.0, 1.0, 1.0, Some(0.0))).unwrap();
        e.handle(&odo(0.0, 0.0, 0.0, 0.0)).unwrap();
        e.handle(&enc(0.0, 0, 0)).unwrap();
        // 30 s without fixes while odometry claims 3 m forward.
        for k in 1..=300 {
            let t = f64::from(k) * 0.1;
            e.handle(&odo(t, 0.01 * f64::from(k), 0.0, 0.0)).unwrap();
            e.handle(&enc(t, 20 * i64::from(k), 20 * i64::from(k)))
                .unwrap();
        }
        let drifted = e.pose().unwrap();
        assert!((drifted.x_m - 4.0).abs() < 0.01, "{name}: {drifted:?}");
        e.handle(&fix(30.0, 2.0, 5.0, None)).unwrap();
        let p = e.pose().unwrap();
        assert!(
            (p.x_m - 2.0).abs() < 1e-9 && (p.y_m - 5.0).abs() < 1e-9,
            "{name}: {p:?}"
        );
    }
}

fn cda(params: CdaParams) -> LateInputHistory<Cda> {
    LateInputHistory::new(Cda::new(&params), params.history_s)
}

#[test]
fn cda_calibrates_gyro_offset_and_noise_at_rest() {
    let mut e = cda(CdaParams {
        calibration_samples: 3,
        ..CdaParams::default()
    });
    e.handle(&enc(0.0, 0, 0)).unwrap();
    for (k, rate) in [0.01, 0.03, 0.02].into_iter().enumerate() {
        e.handle(&gyro(0.01 * (k + 1) as f64, rate)).unwrap();
    }
    e.handle(&enc(0.1, 0, 0)).unwrap();
    assert_eq!(
        e.core().chain().gyro_calibration(),
        None,
        "not yet confirmed at rest by the next step"
    );
    e.handle(&enc(0.2, 0, 0)).unwrap();
    let (offset, noise) = e.core().chain().gyro_calibration().unwrap();
    // Eq. 7: mean 0.02; eq. 8: max |w - offset| = 0.01.
    assert!((offset - 0.02).abs() < 1e-15 && (noise - 0.01).abs() < 1e-15);
}

#[test]
fn cda_readings_while_moving_are_not_calibration() {
    let mut e = cda(CdaParams::default());
    e.handle(&enc(0.0, 0, 0)).unwrap();
    e.handle(&gyro(0.05, 0.5)).unwrap();
    e.handle(&enc(0.1, 100, 120)).unwrap();
    assert_eq!(e.core().chain().gyro_calibration(), Some((0.0, 0.0)));
}

#[test]
fn cda_reading_just_before_motion_is_kept_out_of_calibration() {
    let mut e = cda(CdaParams::default());
    e.handle(&enc(0.0, 0, 0)).unwrap();
    e.handle(&gyro(0.05, 0.01)).unwrap();
    e.handle(&enc(0.1, 0, 0)).unwrap();
    // The robot starts turning at 0.2 s: the encoders see it one step late.
    e.handle(&gyro(0.15, 0.01)).unwrap();
    e.handle(&gyro(0.2, 0.5)).unwrap();
    e.handle(&enc(0.2, 0, 0)).unwrap();
    e.handle(&enc(0.3, 100, 120)).unwrap();
    assert_eq!(e.core().chain().gyro_calibration(), Some((0.01, 0.0)));
}

#[test]
fn cda_switches_to_gyro_in_a_turn_and_back_on_a_straight() {
    let mut e = cda(CdaParams {
        calibration_samples: 1,
        ..CdaParams::default()
    });
    e.handle(&enc(0.0, 0, 0)).unwrap();
    e.handle(&gyro(0.05, 0.0)).unwrap();
    e.handle(&enc(0.1, 0, 0)).unwrap();
    e.handle(&enc(0.2, 0, 0)).unwrap();
    let source = |e: &LateInputHistory<Cda>| e.core().chain().source();
    let (mut l, mut r, mut t) = (0_i64, 0_i64, 0.2);
    let mut drive = |e: &mut LateInputHistory<Cda>, dl: i64, dr: i64, rate: f64| {
        for k in 1..=10 {
            e.handle(&gyro(t + 0.01 * f64::from(k), rate)).unwrap();
        }
        t += 0.1;
        l += dl;
        r += dr;
        e.handle(&enc(t, l, r)).unwrap();
    };
    drive(&mut e, 100, 100, 0.0);
    assert_eq!(source(&e), HeadingSource::Encoders);
    // 40 ticks of difference: 0.02 m / 0.33 m = 3.5 deg per step > mu1.
    drive(&mut e, 80, 120, 0.6);
    assert_eq!(
        source(&e),
        HeadingSource::Encoders,
        "decided on the past step"
    );
    drive(&mut e, 80, 120, 0.6);
    assert_eq!(source(&e), HeadingSource::Gyro);
    drive(&mut e, 100, 100, 0.0);
    drive(&mut e, 100, 100, 0.0);
    assert_eq!(source(&e), HeadingSource::Encoders);
}

#[test]
fn cda_complementary_filter_weights_planned_heading_by_one_minus_alpha() {
    let mut e = cda(CdaParams::default());
    e.handle(&enc(0.0, 0, 0)).unwrap();
    e.handle(&Input::Range(RangeSample {
        t_s: 0.05,
        planned_heading_rad: Some(0.2),
        ..RangeSample::default()
    }))
    .unwrap();
    // Eq. 18: theta = 0.95 * 0 + 0.05 * 0.2.
    assert!((e.pose().unwrap().theta_rad - 0.01).abs() < 1e-15);
}

#[test]
fn cda_ignores_msu_fixes() {
    let mut e = build(&config("cda")).unwrap();
    let before = e.pose();
    e.handle(&fix(0.0, 3.0, 3.0, Some(1.0))).unwrap();
    assert_eq!(e.pose(), before);
}

#[test]
fn cda_complementary_filter_crosses_180_degrees_the_short_way() {
    let mut e = cda(CdaParams {
        initial_pose: InitialPose {
            theta_rad: 179.0_f64.to_radians(),
            ..origin(0.01, 0.01)
        },
        ..CdaParams::default()
    });
    e.handle(&Input::Range(RangeSample {
        t_s: 0.05,
        planned_heading_rad: Some((-179.0_f64).to_radians()),
        ..RangeSample::default()
    }))
    .unwrap();
    // -179 deg is re-expressed as 181 deg: 0.95 * 179 + 0.05 * 181 = 179.1.
    let theta = e.pose().unwrap().theta_rad.to_degrees();
    assert!((theta - 179.1).abs() < 1e-9, "{theta}");
}
