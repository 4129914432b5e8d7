//! A deterministic differential-drive robot driving in circles, producing
//! the inputs an estimator sees (in delivery order) and the truth.

use nalgebra::Matrix2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::angle;
use crate::estimator::{
    EncoderSample, GyroSample, Input, OdometrySample, RangeDifferenceSample, WheelGeometry,
};
use crate::tdoa::Fix;

/// A Pioneer-like drive: 0.33 m wheel base, 0.5 mm per encoder tick.
pub(in crate::estimator) const GEOMETRY: WheelGeometry = WheelGeometry {
    wheel_base_m: 0.33,
    left_m_per_tick: 0.0005,
    right_m_per_tick: 0.0005,
};

/// Noise of a run; `Noise::default()` is noiseless.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Noise {
    pub gyro_bias_rad_s: f64,
    pub gyro_sigma_rad_s: f64,
    /// Relative error of the odometry heading rate (drift).
    pub odometry_turn_scale: f64,
    pub fix_sigma_m: f64,
    /// Fix delivery delay after its measurement time.
    pub fix_latency_s: f64,
    /// Fix heading noise; `None` quantises the heading to the 60 deg
    /// receiver sectors of the ICKON paper instead.
    pub two_sensor_heading_sigma_rad: Option<f64>,
    /// Every n-th fix is shifted by this many metres along x (a reflection).
    pub reflection_every: Option<(i64, f64)>,
    /// Noise of each range difference, metres.
    pub range_difference_sigma_m: f64,
}

/// Four transmitters on the ceiling of a 10 x 10 m room, around the circle.
pub(super) const TRANSMITTERS: [[f64; 3]; 4] = [
    [0.0, 0.0, 2.5],
    [10.0, 0.0, 2.5],
    [10.0, 10.0, 2.5],
    [0.0, 10.0, 2.5],
];

/// Height of the simulated receiver, metres (the `tdoa-ekf` default).
pub(super) const RECEIVER_HEIGHT_M: f64 = 0.5;

/// Truth at time `t_s`: at rest at (5, 5) heading 0 for `rest_s`, then on
/// a circle of radius `v/omega` turning left.
pub(super) struct Circle {
    pub v_m_s: f64,
    pub omega_rad_s: f64,
    pub rest_s: f64,
}

impl Circle {
    /// Time spent moving at `t_s`.
    pub fn moving_s(&self, t_s: f64) -> f64 {
        (t_s - self.rest_s).max(0.0)
    }

    pub fn truth(&self, t_s: f64) -> (f64, f64, f64) {
        let r = self.v_m_s / self.omega_rad_s;
        let th = self.omega_rad_s * self.moving_s(t_s);
        (5.0 + r * th.sin(), 5.0 + r * (1.0 - th.cos()), th)
    }
}

/// Inputs of a run of `duration_s`, sorted by delivery time.
pub(super) fn circling_run(
    circle: &Circle,
    duration_s: f64,
    noise: Noise,
    seed: u64,
) -> Vec<Input> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let mut events: Vec<(f64, Input)> = Vec::new();
    let steps = (duration_s * 100.0).round() as i64;
    for k in 0..=steps {
        let t = k as f64 * 0.01;
        let omega = if t < circle.rest_s {
            0.0
        } else {
            circle.omega_rad_s
        };
        let rate = omega + noise.gyro_bias_rad_s + noise.gyro_sigma_rad_s * unit.sample(&mut rng);
        events.push((
            t,
            Input::Gyro(GyroSample {
                t_s: t,
                rate_rad_s: rate,
            }),
        ));
        if k % 10 == 0 {
            let (_, _, th) = circle.truth(t);
            let drift = noise.odometry_turn_scale * th;
            // Odometry frame = world frame shifted to start at the origin,
            // with a heading that drifts; x_b, y_b integrate that heading.
            let (bx, by) =
                odometry_position(circle, circle.moving_s(t), 1.0 + noise.odometry_turn_scale);
            events.push((
                t,
                Input::Odometry(OdometrySample {
                    t_s: t,
                    x_m: bx,
                    y_m: by,
                    theta_rad: angle::wrap_pi(th + drift),
                }),
            ));
            let tm = circle.moving_s(t);
            let half = 0.5 * GEOMETRY.wheel_base_m * circle.omega_rad_s * tm;
            let left = circle.v_m_s * tm - half;
            let right = circle.v_m_s * tm + half;
            events.push((
                t,
                Input::Encoders(EncoderSample {
                    t_s: t,
                    left_ticks: (left / GEOMETRY.left_m_per_tick).round() as i64,
                    right_ticks: (right / GEOMETRY.right_m_per_tick).round() as i64,
                    geometry: GEOMETRY,
                }),
            ));
        }
        if k % 30 == 0 {
            let (x, y, _) = circle.truth(t);
            let p = nalgebra::Vector3::new(x, y, RECEIVER_HEIGHT_M);
            let range = |c: [f64; 3]| (p - nalgebra::Vector3::from(c)).norm();
            // One cycle: transmitter 0 is the reference of the three others.
            for b in &TRANSMITTERS[1..] {
                let sigma = noise.range_difference_sigma_m;
                events.push((
                    t + noise.fix_latency_s,
                    Input::RangeDifference(RangeDifferenceSample {
                        a_t_s: None,
                        t_s: t,
                        a_m: TRANSMITTERS[0],
                        b_m: *b,
                        d_m: range(*b) - range(TRANSMITTERS[0]) + sigma * unit.sample(&mut rng),
                        sigma_m: sigma.max(0.001),
                        clocks: None,
                        speed_rel_sigma: None,
                    }),
                ));
            }
            let (x, y, th) = circle.truth(t);
            let sector = std::f64::consts::FRAC_PI_3;
            let heading = match noise.two_sensor_heading_sigma_rad {
                Some(sigma) => th + sigma * unit.sample(&mut rng),
                None => (th / sector).round() * sector,
            };
            let reflected = match noise.reflection_every {
                Some((n, offset_m)) if (k / 30) % n == n - 1 => offset_m,
                _ => 0.0,
            };
            events.push((
                t + noise.fix_latency_s,
                Input::Fix(
                    Fix::from_position(
                        t,
                        x + reflected + noise.fix_sigma_m * unit.sample(&mut rng),
                        y + noise.fix_sigma_m * unit.sample(&mut rng),
                        Matrix2::from_diagonal_element(noise.fix_sigma_m.powi(2) + 1e-6),
                    )
                    .with_heading(Some(angle::wrap_pi(heading))),
                ),
            ));
        }
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    events.into_iter().map(|(_, i)| i).collect()
}

/// Odometry position with the heading rate scaled by `scale`, from the
/// origin: the arc of radius `v / (omega scale)`.
fn odometry_position(circle: &Circle, t_s: f64, scale: f64) -> (f64, f64) {
    let w = circle.omega_rad_s * scale;
    let r = circle.v_m_s / w;
    let th = w * t_s;
    (r * th.sin(), r * (1.0 - th.cos()))
}

/// Only the inputs of the given kinds.
pub(super) fn only(inputs: &[Input], keep: impl Fn(&Input) -> bool) -> Vec<Input> {
    inputs.iter().filter(|i| keep(i)).cloned().collect()
}
