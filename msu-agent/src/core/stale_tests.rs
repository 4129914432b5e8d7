//! A robot whose fixes stall reports itself stale on its pose.

use super::*;
use crate::events::{Event, Output};
use ickon_fusion::estimator::WheelGeometry;
use ickon_fusion::estimator::build_by_name;

fn config() -> MsuConfig {
    MsuConfig {
        speed_of_sound_m_s: 343.0,
        height_m: 0.5,
        receiver_angles_rad: vec![0.0],
        transmitters: Vec::new(),
        wheels: WheelGeometry {
            wheel_base_m: 0.33,
            left_m_per_tick: 1e-4,
            right_m_per_tick: 1e-4,
        },
        timing_sigma_s: 1e-5,
        residual_gate_m: 0.1,
        floor_bounds_m: None,
        max_fix_sigma_m: 0.5,
        walls: Vec::new(),
        columns: Vec::new(),
    }
}

#[test]
fn without_fixes_the_pose_says_so_and_its_covariance_grows() {
    let mut core = MsuCore::new(config(), build_by_name("odometry").unwrap());
    let t0 = Time::from_nanos(1_000_000_000);
    let mut poses = Vec::new();
    for k in 0..600_i64 {
        let out = core.handle(Event::Odometry(Odometry {
            stamp: t0 + Duration::from_millis(10 * k),
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            left_ticks: 10 * k,
            right_ticks: 10 * k,
        }));
        if let [Output::Pose(p)] = out.as_slice() {
            poses.push(p.clone());
        }
    }
    let at = |s: f64| {
        poses
            .iter()
            .find(|p| p.stamp.since(t0).as_secs_f64() >= s)
            .unwrap()
    };
    // No fix ever: the start pose was never confirmed.
    assert_eq!(at(1.0).status, PoseStatus::Localising);
    assert_eq!(at(3.5).status, PoseStatus::Localising);
    let (early, late) = (at(3.5).covariance[0], at(5.9).covariance[0]);
    // Beyond the estimator's own growth: (0.05 m/s * 2.9 s)^2 at the end.
    assert!(late - early > 0.02, "variance {early} -> {late} m^2");
}

#[test]
fn a_confirmed_pose_tracks_and_says_when_its_fixes_stall() {
    let mut core = super::tests::core_with("ickon-akf");
    let odometry = |core: &mut MsuCore, t_s: f64| {
        core.handle(Event::Odometry(Odometry {
            stamp: Time::from_secs_f64(t_s),
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            left_ticks: 0,
            right_ticks: 0,
        }))
    };
    let status_at = |out: Vec<Output>| match out.as_slice() {
        [Output::Pose(p)] => p.status,
        other => panic!("one pose expected: {other:?}"),
    };
    // Without a start pose the filter waits for its first fix.
    assert!(odometry(&mut core, 9.9).is_empty());
    // The fixture's arrivals go out at 10 s; the first fix places the
    // filter, which then agrees with it.
    core.on_arrivals(&super::tests::arrivals([1.7, 2.9, 0.5], &[]))
        .unwrap()
        .expect("a valid fix");
    assert_eq!(status_at(odometry(&mut core, 10.5)), PoseStatus::Tracking);
    assert_eq!(status_at(odometry(&mut core, 12.0)), PoseStatus::Tracking);
    // Odometry goes on, fixes stop: stale after STALE_AFTER.
    assert_eq!(status_at(odometry(&mut core, 13.6)), PoseStatus::NoFixes);
}
