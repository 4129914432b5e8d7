//! Standing still: while neither wheel moves the robot does not turn, so
//! what the gyro reads is its bias (a zero angular rate update).
//!
//! Without it the bias was observable only through the heading, and the
//! heading only once the robot drove between transmitters: a robot that
//! stood for its first seconds with a gyro bias of 0.6 deg/s turned its
//! heading 1.3 deg before it moved and drove off 7 deg wrong, 10 cm off
//! its corridor (`ickon sim --robots 3 --seed 2 --firing occupancy`,
//! replayed from the recording).
//!
//! Wheels that report nothing can still hide a slow turn: an encoder
//! tick or two. So the robot must have stood still for [`STILL_FOR_S`]
//! before the gyro is read as bias; a turn slow enough to hide from the
//! wheels for that long is a fraction of a degree per second, which a
//! gyro's turn-on bias (the data sheet's, in the noise profile) dwarfs.

use crate::estimator::dead_reckoning::Increment;

/// How long neither wheel may have moved before the gyro is taken to read
/// its bias alone, seconds.
pub(super) const STILL_FOR_S: f64 = 0.5;

/// An innovation of the bias beyond this many standard deviations is not
/// a bias: the robot was turned without its wheels (lifted, pushed).
pub(super) const GATE_SIGMAS: f64 = 5.0;

/// Since when the wheels have not moved.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Standstill {
    still_since_s: Option<f64>,
}

impl Standstill {
    /// Notes an increment of the wheels; whether, at its end, they have not
    /// moved for at least [`STILL_FOR_S`].
    pub(super) fn note(&mut self, inc: &Increment) -> bool {
        let still = inc.distance_m == 0.0 && inc.dtheta_rad == 0.0 && inc.dt_s > 0.0;
        if !still {
            self.still_since_s = None;
            return false;
        }
        let since = *self.still_since_s.get_or_insert(inc.t_s - inc.dt_s);
        inc.t_s - since >= STILL_FOR_S
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    use super::*;
    use crate::estimator::history::InOrderFilter;
    use crate::estimator::tdoa_ekf::{TdoaEkf, TdoaEkfParams};
    use crate::estimator::tests::sim::GEOMETRY;
    use crate::estimator::{EncoderSample, GyroSample, InitialPose, Input};

    /// A robot standing for 5 s with a gyro bias of 0.6 deg/s and the
    /// data sheet's 0.1 deg/s of noise at 100 Hz, nothing else heard: the
    /// heading holds (without the update it turned 3 deg), and the bias is
    /// found. A robot that turns in place is not standing: its gyro is
    /// followed.
    #[test]
    fn a_still_robots_heading_holds_and_its_gyro_bias_is_found() {
        let params = TdoaEkfParams {
            initial_pose: Some(InitialPose::default()),
            ..TdoaEkfParams::default()
        };
        let bias = 0.6f64.to_radians();
        let noise = Normal::new(0.0, 0.1f64.to_radians()).unwrap();
        let run = |turn_rad_s: f64| {
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut f = TdoaEkf::new(&params);
            let mut wheel_m = 0.0;
            for k in 0..=500 {
                let t_s = f64::from(k) * 0.01;
                f.step(&Input::Gyro(GyroSample {
                    t_s,
                    rate_rad_s: turn_rad_s + bias + noise.sample(&mut rng),
                }));
                if k % 2 == 0 {
                    let ticks = (wheel_m / GEOMETRY.left_m_per_tick).floor() as i64;
                    f.step(&Input::Encoders(EncoderSample {
                        t_s,
                        left_ticks: -ticks,
                        right_ticks: ticks,
                        geometry: GEOMETRY,
                    }));
                }
                wheel_m += 0.5 * GEOMETRY.wheel_base_m * turn_rad_s * 0.01;
            }
            f
        };
        let still = run(0.0);
        let heading_deg = still.pose().unwrap().theta_rad.to_degrees();
        assert!(heading_deg.abs() < 0.4, "heading {heading_deg} deg");
        let bias_deg_s = still.turn_bias_rad_s().unwrap().to_degrees();
        assert!((bias_deg_s - 0.6).abs() < 0.05, "bias {bias_deg_s} deg/s");
        // Turning in place at 10 deg/s for 5 s: 50 deg by the gyro.
        let turning = run(10f64.to_radians());
        let heading_deg = turning.pose().unwrap().theta_rad.to_degrees();
        assert!(
            (heading_deg - 50.0).abs() < 3.5,
            "heading {heading_deg} deg"
        );
    }

    /// A power of two, so that the times add up exactly.
    const STEP_S: f64 = 1.0 / 32.0;

    fn inc(t_s: f64, distance_m: f64) -> Increment {
        Increment {
            t_s,
            dt_s: STEP_S,
            distance_m,
            dtheta_rad: 0.0,
            from_encoders: false,
        }
    }

    #[test]
    fn only_wheels_still_for_long_enough_count_as_standing() {
        let mut s = Standstill::default();
        let mut t = 0.0;
        let mut standing = Vec::new();
        for k in 0..60 {
            t += STEP_S;
            // Moving for 0.25 s (8 steps), then still.
            standing.push(s.note(&inc(t, if k < 8 { 0.01 } else { 0.0 })));
        }
        // Still from 0.25 s: standing from 0.75 s (the 24th step) on.
        let first = standing.iter().position(|&b| b).unwrap();
        assert_eq!(first, 23);
        assert!(standing[first..].iter().all(|&b| b));
        // One tick of motion starts the wait again.
        assert!(!s.note(&inc(t + STEP_S, 0.0001)));
        assert!(!s.note(&inc(t + 2.0 * STEP_S, 0.0)));
    }
}
