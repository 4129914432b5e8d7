//! The flight filters on synthetic flights with a known truth.

use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::estimator::RangeDifferenceSample;
use crate::estimator::guard::{FlightVolume, GuardParams, Guarded};

/// Eight anchors on the corners of a 6 x 6 x 3 m room.
pub(crate) fn corners() -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    for &z in &[0.2, 2.8] {
        for &(x, y) in &[(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (0.0, 6.0)] {
            v.push([x, y, z]);
        }
    }
    v
}

/// A circle of 1.5 m radius at 1.5 m height, 0.5 rad/s, level, facing +x.
fn circle(t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (r, w) = (1.5, 0.5);
    let p = Vector3::new(3.0 + r * (w * t).cos(), 3.0 + r * (w * t).sin(), 1.5);
    let a = Vector3::new(-r * w * w * (w * t).cos(), -r * w * w * (w * t).sin(), 0.0);
    (p, a)
}

fn range_difference(
    t_s: f64,
    p: Vector3<f64>,
    a: [f64; 3],
    b: [f64; 3],
    noise: f64,
) -> RangeDifferenceSample {
    RangeDifferenceSample {
        a_t_s: None,
        t_s,
        a_m: a,
        b_m: b,
        d_m: (p - Vector3::from(b)).norm() - (p - Vector3::from(a)).norm() + noise,
        sigma_m: 0.05,
        clocks: None,
        speed_rel_sigma: None,
    }
}

#[test]
fn imu_filter_tracks_a_circle_and_keeps_its_attitude() {
    let volume = FlightVolume::around(&corners(), 0.5).unwrap();
    let params = ImuParams {
        initial_yaw_rad: 5f64.to_radians(),
        ..ImuParams::default()
    };
    let mut g = Guarded::new(
        ImuFilter::new(params).unwrap(),
        volume,
        GuardParams::default(),
        None,
    );
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let acc_noise = Normal::new(0.0, 0.3).unwrap();
    let tx = corners();
    let (mut worst, mut k) = (0.0_f64, 0);
    for i in 0..30_000 {
        let t = f64::from(i) * 0.001;
        let (p, a) = circle(t);
        let f = a + Vector3::new(0.0, 0.0, 9.81);
        g.filter_mut().imu(&ImuSample {
            t_s: t,
            accel_m_s2: std::array::from_fn(|j| f[j] + acc_noise.sample(&mut rng)),
            gyro_rad_s: [0.0; 3],
        });
        if i % 5 == 0 {
            let m = range_difference(t, p, tx[k % 8], tx[(k + 1) % 8], noise.sample(&mut rng));
            k += 1;
            let step = g.step(&m);
            if let (Some(e), true) = (step.published_m, t > 10.0) {
                worst = worst.max((Vector3::from(e) - p).norm());
            }
        }
    }
    assert!(worst < 0.15, "{worst}");
    let q = g.filter().attitude_xyzw();
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]));
    assert!(q.angle().to_degrees() < 3.0, "{}", q.angle().to_degrees());
}

/// A quadrotor flying the circle: it tilts to accelerate, its rotors push
/// along its body z, and its accelerometer's horizontal channels carry a
/// quarter of a g of error (as the UTIL vehicle's do in flight). The
/// thrust-axis model ignores them, and yaw is not corrupted by the
/// position updates that cannot see it.
#[test]
fn thrust_axis_model_ignores_horizontal_accelerometer_errors() {
    let volume = FlightVolume::around(&corners(), 0.5).unwrap();
    let params = ImuParams {
        thrust_axis_only: true,
        ..ImuParams::default()
    };
    let mut g = Guarded::new(
        ImuFilter::new(params).unwrap(),
        volume,
        GuardParams::default(),
        None,
    );
    let attitude = |t: f64| {
        let (_, a) = circle(t);
        let f = a + Vector3::new(0.0, 0.0, 9.81);
        (
            UnitQuaternion::rotation_between(&Vector3::z(), &f).unwrap_or_default(),
            f.norm(),
        )
    };
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let tx = corners();
    let (mut worst, mut k) = (0.0_f64, 0);
    let dt = 0.001;
    for i in 0..30_000 {
        let t = f64::from(i) * dt;
        let (q, thrust) = attitude(t);
        let (q1, _) = attitude(t + dt);
        let w = (q.inverse() * q1).scaled_axis() / dt;
        // Level on the ground for the first half second (levelling), then
        // flying with the horizontal channels off by 0.25 g.
        let horizontal = if t < 0.5 { 0.0 } else { -2.45 };
        let accel = if t < 0.5 {
            q.inverse() * Vector3::new(0.0, 0.0, thrust)
        } else {
            Vector3::new(horizontal, 0.5 * horizontal, thrust)
        };
        g.filter_mut().imu(&ImuSample {
            t_s: t,
            accel_m_s2: accel.into(),
            gyro_rad_s: w.into(),
        });
        if i % 5 == 0 {
            let (p, _) = circle(t);
            let m = range_difference(t, p, tx[k % 8], tx[(k + 1) % 8], noise.sample(&mut rng));
            k += 1;
            let step = g.step(&m);
            if let (Some(e), true) = (step.published_m, t > 10.0) {
                worst = worst.max((Vector3::from(e) - p).norm());
            }
        }
    }
    assert!(worst < 0.15, "{worst}");
    let q = g.filter().attitude_xyzw();
    let est = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]));
    let (truth, _) = attitude(30.0 - 0.001);
    let error_deg = (truth.inverse() * est).angle().to_degrees();
    assert!(error_deg < 3.0, "{error_deg}");
}
