//! A robot whose fixes stall reports itself stale on its pose.

use super::*;
use crate::events::{Event, Output};
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
    assert_eq!(at(1.0).status, PoseStatus::Tracking);
    assert_eq!(at(3.5).status, PoseStatus::NoFixes);
    let (early, late) = (at(3.5).covariance[0], at(5.9).covariance[0]);
    // Beyond the estimator's own growth: (0.05 m/s * 2.9 s)^2 at the end.
    assert!(late - early > 0.02, "variance {early} -> {late} m^2");
}
