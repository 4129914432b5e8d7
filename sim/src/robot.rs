//! A differential-drive robot (Pioneer 3-DX-like) following a closed route
//! with pure pursuit, and the progress along the route that decides when a
//! reference point is passed.

use ickon_proto::site::{Route, geometry};
use rand_chacha::ChaCha8Rng;

use crate::profile::EncoderNoise;
use crate::rng;

/// Drive geometry and limits. Defaults: Pioneer 3-DX.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DriveSpec {
    /// Nominal distance between the wheels, metres.
    pub wheel_base_m: f64,
    /// Nominal wheel radius, metres.
    pub wheel_radius_m: f64,
    /// Encoder ticks per wheel turn (500-line encoder times the gear ratio).
    pub ticks_per_turn: f64,
    /// Top forward speed, m/s.
    pub max_speed_m_s: f64,
    /// Top turn rate, rad/s.
    pub max_turn_rate_rad_s: f64,
    /// Forward acceleration limit, m/s^2.
    pub max_accel_m_s2: f64,
    /// Turn acceleration limit, rad/s^2.
    pub max_turn_accel_rad_s2: f64,
    /// Pure-pursuit look-ahead distance, metres.
    pub lookahead_m: f64,
}

impl Default for DriveSpec {
    fn default() -> Self {
        Self {
            wheel_base_m: 0.33,
            wheel_radius_m: 0.0975,
            // 500 lines on the motor shaft, 38.3:1 gear (the 3-DX gearbox).
            ticks_per_turn: 500.0 * 38.3,
            max_speed_m_s: 1.2,
            max_turn_rate_rad_s: 1.2,
            max_accel_m_s2: 0.5,
            max_turn_accel_rad_s2: 3.0,
            lookahead_m: 0.3,
        }
    }
}

impl DriveSpec {
    /// Metres per tick of the nominal wheel.
    pub fn m_per_tick(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.wheel_radius_m / self.ticks_per_turn
    }

    /// The nominal geometry an MSU agent converts this drive's ticks with.
    pub fn geometry(&self) -> ickon_fusion::estimator::WheelGeometry {
        let m = self.m_per_tick();
        ickon_fusion::estimator::WheelGeometry {
            wheel_base_m: self.wheel_base_m,
            left_m_per_tick: m,
            right_m_per_tick: m,
        }
    }
}

/// True state of a robot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RobotState {
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians, continuous (not wrapped).
    pub theta_rad: f64,
    /// Forward speed, m/s.
    pub v_m_s: f64,
    /// Turn rate, rad/s.
    pub omega_rad_s: f64,
    /// Left wheel rotation since start, radians.
    pub left_wheel_rad: f64,
    /// Right wheel rotation since start, radians.
    pub right_wheel_rad: f64,
}

/// A robot on its route: true kinematics with the profile's wheel errors.
#[derive(Debug, Clone)]
pub struct Robot {
    spec: DriveSpec,
    errors: EncoderNoise,
    route: Route,
    route_len_m: f64,
    /// Current true state.
    pub state: RobotState,
    /// Distance travelled along the route (projected), metres, growing over tours.
    pub progress_m: f64,
    slip_rng: ChaCha8Rng,
    cruise_m_s: f64,
}

impl Robot {
    /// A robot at the route's first point, facing along its first segment.
    pub fn new(spec: DriveSpec, errors: EncoderNoise, route: &Route, slip_rng: ChaCha8Rng) -> Self {
        let p0 = route.points[0];
        let p1 = route.points[1 % route.points.len()];
        let theta = (p1[1] - p0[1]).atan2(p1[0] - p0[0]);
        Self {
            spec,
            errors,
            route_len_m: route.length_m().max(1e-9),
            route: route.clone(),
            state: RobotState {
                x_m: p0[0],
                y_m: p0[1],
                theta_rad: theta,
                ..RobotState::default()
            },
            progress_m: 0.0,
            slip_rng,
            cruise_m_s: route.speed_m_s.min(spec.max_speed_m_s),
        }
    }

    /// Length of one tour, metres.
    pub fn route_length_m(&self) -> f64 {
        self.route_len_m
    }

    /// Advances the robot by `dt_s`; `drive` false holds it still.
    pub fn step(&mut self, dt_s: f64, drive: bool) {
        let (v_cmd, w_cmd) = if drive { self.pursuit() } else { (0.0, 0.0) };
        let s = &self.spec;
        let dv =
            (v_cmd - self.state.v_m_s).clamp(-s.max_accel_m_s2 * dt_s, s.max_accel_m_s2 * dt_s);
        let dw = (w_cmd - self.state.omega_rad_s).clamp(
            -s.max_turn_accel_rad_s2 * dt_s,
            s.max_turn_accel_rad_s2 * dt_s,
        );
        let v = self.state.v_m_s + dv;
        let w = self.state.omega_rad_s + dw;
        // The motor controller turns the wheels as the nominal geometry says;
        // the ground moves as the true geometry and the slip say.
        let half_b = 0.5 * s.wheel_base_m;
        let left_rot = (v - w * half_b) / s.wheel_radius_m * dt_s;
        let right_rot = (v + w * half_b) / s.wheel_radius_m * dt_s;
        let slip_sigma = self.errors.slip_sigma + self.errors.slip_per_rad_s * w.abs();
        let slip_l = rng::normal(&mut self.slip_rng, slip_sigma);
        let slip_r = rng::normal(&mut self.slip_rng, slip_sigma);
        let left_ground =
            left_rot * s.wheel_radius_m * (1.0 + self.errors.left_radius_error) * (1.0 - slip_l);
        let right_ground =
            right_rot * s.wheel_radius_m * (1.0 + self.errors.right_radius_error) * (1.0 - slip_r);
        let true_base = s.wheel_base_m * (1.0 + self.errors.wheel_base_error);
        let ds = 0.5 * (left_ground + right_ground);
        let dth = (right_ground - left_ground) / true_base;
        let mid = self.state.theta_rad + 0.5 * dth;
        self.state.x_m += ds * mid.cos();
        self.state.y_m += ds * mid.sin();
        self.state.theta_rad += dth;
        self.state.v_m_s = v;
        self.state.omega_rad_s = w;
        self.state.left_wheel_rad += left_rot;
        self.state.right_wheel_rad += right_rot;
        self.update_progress();
    }

    /// Pure pursuit towards the point one look-ahead beyond the current progress.
    fn pursuit(&self) -> (f64, f64) {
        let s = &self.spec;
        let target = self.point_at(self.progress_m + s.lookahead_m);
        let (dx, dy) = (target[0] - self.state.x_m, target[1] - self.state.y_m);
        let (sn, cs) = self.state.theta_rad.sin_cos();
        let lateral = -sn * dx + cs * dy;
        let l2 = (dx * dx + dy * dy).max(1e-6);
        let curvature = 2.0 * lateral / l2;
        let forward = cs * dx + sn * dy;
        let mut v = self.cruise_m_s;
        if curvature.abs() * v > s.max_turn_rate_rad_s {
            v = s.max_turn_rate_rad_s / curvature.abs();
        }
        // Facing away from the target: turn in place first.
        if forward < 0.0 {
            v = 0.0;
            return (v, s.max_turn_rate_rad_s.copysign(lateral));
        }
        (v, v * curvature)
    }

    fn point_at(&self, progress_m: f64) -> [f64; 2] {
        let s = progress_m.rem_euclid(self.route_len_m);
        geometry::point_at_arc_length(&self.route.points, self.route.closed, s)
    }

    /// Projects the position on the route near the current progress; progress never decreases.
    fn update_progress(&mut self) {
        let p = [self.state.x_m, self.state.y_m];
        let base = self.progress_m;
        let mut best = (f64::INFINITY, base);
        // Search a window around the current progress in 1 cm steps, refined once.
        let mut ds = -0.2;
        while ds <= 0.6 {
            let q = self.point_at(base + ds);
            let d = (q[0] - p[0]).hypot(q[1] - p[1]);
            if d < best.0 {
                best = (d, base + ds);
            }
            ds += 0.01;
        }
        if best.1 > self.progress_m {
            self.progress_m = best.1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::site::Site;
    use rand::SeedableRng;

    #[test]
    fn robot_follows_every_default_route_within_fifteen_centimetres() {
        let site = Site::default_site();
        let none = crate::profile::NoiseProfile::ideal().encoders;
        for route in &site.routes {
            let mut r = Robot::new(
                DriveSpec::default(),
                none,
                route,
                ChaCha8Rng::seed_from_u64(1),
            );
            let mut worst: f64 = 0.0;
            let mut t = 0.0;
            while r.progress_m < route.length_m() && t < 1000.0 {
                r.step(0.01, true);
                t += 0.01;
                let dist = geometry::polyline_segments(&route.points, true)
                    .map(|(a, b)| geometry::distance_to_segment([r.state.x_m, r.state.y_m], a, b))
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(dist);
            }
            assert!(
                r.progress_m >= route.length_m(),
                "{} not completed",
                route.name
            );
            assert!(worst < 0.15, "{}: {worst} m off the route", route.name);
            let expected = route.length_m() / route.speed_m_s;
            assert!(t < 1.6 * expected, "{}: {t} s for a tour", route.name);
        }
    }

    #[test]
    fn wheel_slip_spreads_the_travelled_distance_by_the_profile_sigma() {
        let site = Site::default_site();
        let route = site.route("route-1").unwrap();
        let mut errors = crate::profile::NoiseProfile::ideal().encoders;
        errors.slip_sigma = 0.02;
        let mut r = Robot::new(
            DriveSpec::default(),
            errors,
            route,
            ChaCha8Rng::seed_from_u64(4),
        );
        let spec = DriveSpec::default();
        let mut ratios = Vec::new();
        for _ in 0..3000 {
            let before = r.state;
            r.step(0.01, true);
            let wheels = 0.5
                * ((r.state.left_wheel_rad - before.left_wheel_rad)
                    + (r.state.right_wheel_rad - before.right_wheel_rad))
                * spec.wheel_radius_m;
            let moved = (r.state.x_m - before.x_m).hypot(r.state.y_m - before.y_m);
            // slip_per_rad_s is 0 here, so turning steps count too.
            if wheels > 1e-3 {
                ratios.push(moved / wheels - 1.0);
            }
        }
        assert!(ratios.len() > 1000, "{} straight steps", ratios.len());
        let n = ratios.len() as f64;
        let mean = ratios.iter().sum::<f64>() / n;
        let sd = (ratios.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        // The mean of two independent slips: sigma / sqrt(2).
        let want = 0.02 / 2f64.sqrt();
        assert!(mean.abs() < 4.0 * want / n.sqrt(), "mean {mean}");
        assert!((sd / want - 1.0).abs() < 0.1, "sd {sd} want {want}");
    }
}
