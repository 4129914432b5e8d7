//! Proprioceptive and obstacle sensors: gyro, wheel encoders, and the
//! left/right ultrasonic and infrared rangers of the CDA paper.

use ickon_proto::site::{Site, geometry};
use rand_chacha::ChaCha8Rng;

use crate::profile::{GyroNoise, ObstacleNoise};
use crate::rng;

/// A yaw-rate gyro with a power-up bias, a bias random walk, white noise and a scale error.
#[derive(Debug, Clone)]
pub struct Gyro {
    noise: GyroNoise,
    bias_rad_s: f64,
    rng: ChaCha8Rng,
}

impl Gyro {
    /// Draws the power-up bias from `rng` and keeps the stream for later samples.
    pub fn new(noise: GyroNoise, mut rng: ChaCha8Rng) -> Self {
        let bias_rad_s = rng::normal(&mut rng, noise.bias_sigma_deg_s).to_radians();
        Self {
            noise,
            bias_rad_s,
            rng,
        }
    }

    /// Current bias, rad/s.
    pub fn bias_rad_s(&self) -> f64 {
        self.bias_rad_s
    }

    /// One reading of the true rate `omega_rad_s`, `dt_s` after the previous one.
    pub fn sample(&mut self, omega_rad_s: f64, dt_s: f64) -> f64 {
        self.bias_rad_s += rng::normal(&mut self.rng, self.noise.bias_walk_deg_s_sqrt_s)
            .to_radians()
            * dt_s.sqrt();
        omega_rad_s * (1.0 + self.noise.scale_error)
            + self.bias_rad_s
            + rng::normal(&mut self.rng, self.noise.white_sigma_deg_s).to_radians()
    }
}

/// Encoder count of a wheel turned by `rotation_rad` (truncated like a counter).
pub fn ticks(rotation_rad: f64, ticks_per_turn: f64) -> i64 {
    (rotation_rad / (2.0 * std::f64::consts::PI) * ticks_per_turn).floor() as i64
}

/// Mounting of the obstacle sensors on the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangerMount {
    /// Direction of the left sensors from the heading, radians (the right ones are mirrored).
    pub angle_rad: f64,
    /// Ultrasonic reach, metres: `[min, max]` (MB1230: 0.2-7.6 m).
    pub ultrasonic_m: [f64; 2],
    /// Infrared reach, metres: `[min, max]` (GP2Y0A41SK0F: 0.04-0.3 m).
    pub ir_m: [f64; 2],
}

impl Default for RangerMount {
    fn default() -> Self {
        Self {
            angle_rad: 30f64.to_radians(),
            ultrasonic_m: [0.2, 7.6],
            ir_m: [0.04, 0.3],
        }
    }
}

/// Readings of one sample: `None` when nothing is within reach (or the reading dropped out).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Ranges {
    /// Left ultrasonic, metres.
    pub left_ultrasonic_m: Option<f64>,
    /// Right ultrasonic, metres.
    pub right_ultrasonic_m: Option<f64>,
    /// Left infrared, metres.
    pub left_ir_m: Option<f64>,
    /// Right infrared, metres.
    pub right_ir_m: Option<f64>,
}

/// Distance from `p` along direction `dir_rad` to the nearest wall or column edge, metres.
pub fn ray_cast(site: &Site, p: [f64; 2], dir_rad: f64, max_m: f64) -> Option<f64> {
    let q = [p[0] + max_m * dir_rad.cos(), p[1] + max_m * dir_rad.sin()];
    let walls = site.walls.iter().map(|w| (w.from, w.to));
    let columns = site
        .columns
        .iter()
        .flat_map(|c| geometry::polyline_segments(&c.polygon, true));
    walls
        .chain(columns)
        .filter_map(|(a, b)| geometry::segment_crossing(p, q, a, b))
        .map(|t| t * max_m)
        .fold(None, |best: Option<f64>, d| {
            Some(best.map_or(d, |b| b.min(d)))
        })
}

/// One sample of the four rangers at pose `(x, y, theta)`.
pub fn sample_ranges(
    site: &Site,
    mount: &RangerMount,
    noise: &ObstacleNoise,
    pose: [f64; 3],
    rng: &mut ChaCha8Rng,
) -> Ranges {
    let p = [pose[0], pose[1]];
    let mut read = |side: f64, reach: [f64; 2], sigma: f64, resolution: f64| {
        let d = ray_cast(site, p, pose[2] + side * mount.angle_rad, reach[1])?;
        let mut d = d + rng::normal(rng, sigma);
        if resolution > 0.0 {
            d = (d / resolution).round() * resolution;
        }
        let dropped = rng::chance(rng, noise.dropout_probability);
        (d >= reach[0] && d <= reach[1] && !dropped).then_some(d)
    };
    Ranges {
        left_ultrasonic_m: read(1.0, mount.ultrasonic_m, noise.ultrasonic_sigma_m, 0.01),
        right_ultrasonic_m: read(-1.0, mount.ultrasonic_m, noise.ultrasonic_sigma_m, 0.01),
        left_ir_m: read(1.0, mount.ir_m, noise.ir_sigma_m, 0.0),
        right_ir_m: read(-1.0, mount.ir_m, noise.ir_sigma_m, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::NoiseProfile;
    use rand::SeedableRng;

    #[test]
    fn gyro_noise_statistics_match_the_profile() {
        let mut noise = NoiseProfile::paper().gyro;
        noise.bias_walk_deg_s_sqrt_s = 0.0;
        noise.scale_error = 0.0;
        let mut g = Gyro::new(noise, ChaCha8Rng::seed_from_u64(7));
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|_| g.sample(0.0, 0.01)).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!((mean - g.bias_rad_s()).abs() < 3.0 * sd / (n as f64).sqrt() + 1e-12);
        let want = noise.white_sigma_deg_s.to_radians();
        assert!((sd / want - 1.0).abs() < 0.03, "sd {sd} want {want}");
    }

    #[test]
    fn gyro_bias_walk_grows_like_the_square_root_of_time() {
        let mut noise = NoiseProfile::ideal().gyro;
        noise.bias_walk_deg_s_sqrt_s = 0.1;
        let runs = 400;
        let mut sq = 0.0;
        for seed in 0..runs {
            let mut g = Gyro::new(noise, ChaCha8Rng::seed_from_u64(seed));
            for _ in 0..1000 {
                g.sample(0.0, 0.01);
            }
            sq += g.bias_rad_s().powi(2);
        }
        // After 10 s: sigma = 0.1 deg/s * sqrt(10).
        let sd = (sq / f64::from(runs as u32)).sqrt();
        let want = 0.1f64.to_radians() * 10f64.sqrt();
        assert!((sd / want - 1.0).abs() < 0.15, "sd {sd} want {want}");
    }

    #[test]
    fn rangers_see_the_corridor_walls_and_nothing_beyond_reach() {
        let site = Site::default_site();
        let noise = NoiseProfile::ideal().obstacles;
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        // Facing east in the middle of the corridor: 30 deg left hits y = 2.5 at 1.25/sin 30.
        let r = sample_ranges(
            &site,
            &RangerMount::default(),
            &noise,
            [4.0, 1.25, 0.0],
            &mut rng,
        );
        let want = (1.25f64 / 0.5 / 0.01).round() * 0.01;
        assert!((r.left_ultrasonic_m.unwrap() - want).abs() < 1e-9);
        assert!((r.right_ultrasonic_m.unwrap() - want).abs() < 1e-9);
        assert_eq!(r.left_ir_m, None);
    }

    #[test]
    fn encoder_counts_whole_ticks() {
        assert_eq!(ticks(2.0 * std::f64::consts::PI, 500.0), 500);
        assert_eq!(ticks(-0.001, 500.0), -1);
    }
}
