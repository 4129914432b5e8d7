//! Screening the motion-capture truth for samples the body cannot have
//! taken: a marker set mislabelled for a frame or two gives a pose
//! flipped by half a turn and shifted by centimetres, between poses that
//! agree with each other. Scored against, such a sample charges every
//! estimator with the motion capture's error (an attitude error of 175
//! degrees, a position error of centimetres), so it is dropped and the
//! truth interpolated across it.
//!
//! A sample is dropped when it is farther from the last kept one than the
//! vehicle can move in the time between them: [`MAX_SPEED_M_S`] plus
//! [`POSITION_SLACK_M`], or [`MAX_RATE_RAD_S`] plus [`ATTITUDE_SLACK_RAD`].
//! A run of drops longer than [`MAX_DROPPED_S`] means the kept sample was
//! the wrong one: the screen then starts again from the new sample.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::dataset::TruthRow;

/// Fastest the vehicle flies, m/s: a small multirotor indoors, the same
/// top speed the watch over the filters assumes.
const MAX_SPEED_M_S: f64 = 3.0;

/// Fastest the vehicle turns, rad/s: the full scale of a flight
/// controller's gyro (2000 deg/s); a body turning faster would saturate it.
const MAX_RATE_RAD_S: f64 = 2000.0 * std::f64::consts::PI / 180.0;

/// Position jitter allowed on top of the motion, metres: a motion
/// capture's noise is millimetres, its timestamps jitter by a millisecond.
const POSITION_SLACK_M: f64 = 0.03;

/// Attitude jitter allowed on top of the motion, radians (5 degrees).
const ATTITUDE_SLACK_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// Longest run of dropped samples before the last kept one is doubted,
/// seconds: longer than the truth gap the scoring interpolates across, so
/// a real jump is never bridged by interpolation.
const MAX_DROPPED_S: f64 = 0.1;

/// The screen over one truth stream.
#[derive(Debug, Clone, Default)]
pub struct TruthScreen {
    kept: Option<TruthRow>,
    first_dropped_s: Option<f64>,
    /// Samples dropped so far.
    pub dropped: u64,
}

impl TruthScreen {
    /// Whether `row` is kept (it then becomes the reference).
    pub fn keep(&mut self, row: &TruthRow) -> bool {
        let Some(kept) = self.kept else {
            self.kept = Some(*row);
            return true;
        };
        let dt = (row.t_s - kept.t_s).abs();
        let restart = self
            .first_dropped_s
            .is_some_and(|t0| row.t_s - t0 > MAX_DROPPED_S);
        if restart || reachable(&kept, row, dt) {
            self.kept = Some(*row);
            self.first_dropped_s = None;
            return true;
        }
        self.first_dropped_s.get_or_insert(row.t_s);
        self.dropped += 1;
        false
    }
}

fn reachable(from: &TruthRow, to: &TruthRow, dt: f64) -> bool {
    let moved_m = (Vector3::from(to.position_m) - Vector3::from(from.position_m)).norm();
    if moved_m > MAX_SPEED_M_S * dt + POSITION_SLACK_M {
        return false;
    }
    match (from.attitude_xyzw, to.attitude_xyzw) {
        (Some(a), Some(b)) => {
            unit(a).angle_to(&unit(b)) <= MAX_RATE_RAD_S * dt + ATTITUDE_SLACK_RAD
        }
        _ => true,
    }
}

fn unit(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t_s: f64, z_m: f64, roll_rad: f64) -> TruthRow {
        let q = UnitQuaternion::from_euler_angles(roll_rad, 0.0, 0.3).coords;
        TruthRow {
            t_s,
            position_m: [1.0, 0.5, z_m],
            attitude_xyzw: Some([q.x, q.y, q.z, q.w]),
        }
    }

    /// Two mislabelled frames in a hover (flipped by half a turn, 8 cm
    /// up, as the motion capture of one UTIL flight gives) are dropped;
    /// the samples around them are kept.
    #[test]
    fn a_flipped_frame_between_agreeing_ones_is_dropped() {
        let mut screen = TruthScreen::default();
        let mut kept = Vec::new();
        for k in 0..40 {
            let t = f64::from(k) * 0.004;
            let flipped = k == 20 || k == 21;
            let r = match flipped {
                true => row(t, 1.43, std::f64::consts::PI - 0.05),
                false => row(t, 1.35, 0.05),
            };
            kept.push(screen.keep(&r));
        }
        assert_eq!(screen.dropped, 2);
        assert!(!kept[20] && !kept[21]);
        assert!(
            kept.iter()
                .enumerate()
                .all(|(k, &x)| x || k == 20 || k == 21)
        );
    }

    /// A fast but possible turn (1000 deg/s) and a real jump of the
    /// reference are not screened out for long: the first is kept, the
    /// second restarts the screen after [`MAX_DROPPED_S`].
    #[test]
    fn a_fast_turn_is_kept_and_a_lasting_jump_restarts() {
        let mut screen = TruthScreen::default();
        let rate = 1000f64.to_radians();
        for k in 0..25 {
            let t = f64::from(k) * 0.004;
            assert!(screen.keep(&row(t, 1.0, rate * t)), "turn at {t}");
        }
        let mut screen = TruthScreen::default();
        assert!(screen.keep(&row(0.0, 0.5, 0.0)));
        let kept: Vec<bool> = (1..60)
            .map(|k| screen.keep(&row(f64::from(k) * 0.004, 1.5, 0.0)))
            .collect();
        let first = kept.iter().position(|&x| x).expect("restarted");
        let restarted_s = (first + 1) as f64 * 0.004;
        assert!(restarted_s > MAX_DROPPED_S && restarted_s < MAX_DROPPED_S + 0.01);
        assert!(kept[first..].iter().all(|&x| x));
    }
}
