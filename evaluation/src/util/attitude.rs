//! Scoring the attitude of an estimator against the motion-capture
//! orientation: the angle of the rotation between the two (all three axes)
//! and the tilt (the angle between the two body z axes, what roll and
//! pitch errors amount to), truth interpolated (normalised linear, the
//! samples are 4 ms apart) at each estimate's time.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Truth gaps longer than this are not interpolated across, seconds.
const MAX_TRUTH_GAP_S: f64 = 0.1;

/// Attitude error statistics, degrees.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AttitudeSummary {
    /// Estimates scored.
    pub scored: u64,
    /// RMS of the full rotation error, degrees.
    pub rmse_deg: f64,
    /// Largest full rotation error, degrees.
    pub max_deg: f64,
    /// RMS of the tilt error, degrees.
    pub tilt_rmse_deg: f64,
    /// RMS of the yaw error, degrees.
    pub yaw_rmse_deg: f64,
}

/// Attitude estimates and truth of one flight.
#[derive(Debug, Clone, Default)]
pub struct AttitudeTrack {
    estimates: Vec<(f64, [f64; 4])>,
    truth: Vec<(f64, [f64; 4])>,
}

fn unit(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

impl AttitudeTrack {
    /// Adds an estimate `[x, y, z, w]` (times non-decreasing).
    pub fn push_estimate(&mut self, t_s: f64, q: [f64; 4]) {
        self.estimates.push((t_s, q));
    }

    /// Adds a truth orientation (times non-decreasing).
    pub fn push_truth(&mut self, t_s: f64, q: [f64; 4]) {
        self.truth.push((t_s, q));
    }

    fn truth_at(&self, t_s: f64) -> Option<UnitQuaternion<f64>> {
        let i = self.truth.partition_point(|r| r.0 <= t_s);
        let (t0, q0) = *self.truth.get(i.checked_sub(1)?)?;
        let (t1, q1) = *self.truth.get(i)?;
        if t1 - t0 > MAX_TRUTH_GAP_S {
            return None;
        }
        let w = (t_s - t0) / (t1 - t0);
        Some(unit(q0).nlerp(&unit(q1), w))
    }

    /// The statistics, `None` when nothing could be scored.
    pub fn summary(&self) -> Option<AttitudeSummary> {
        let (mut n, mut sum2, mut max, mut tilt2, mut yaw2) = (0_u64, 0.0, 0.0_f64, 0.0, 0.0);
        for &(t, q) in &self.estimates {
            let Some(truth) = self.truth_at(t) else {
                continue;
            };
            let est = unit(q);
            let e = (truth.inverse() * est).angle().to_degrees();
            let z = Vector3::z();
            let tilt = (truth * z).angle(&(est * z)).to_degrees();
            let yaw = (est.euler_angles().2 - truth.euler_angles().2 + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            n += 1;
            sum2 += e * e;
            max = max.max(e);
            tilt2 += tilt * tilt;
            yaw2 += yaw.to_degrees().powi(2);
        }
        (n > 0).then(|| {
            let nf = n as f64;
            AttitudeSummary {
                scored: n,
                rmse_deg: (sum2 / nf).sqrt(),
                max_deg: max,
                tilt_rmse_deg: (tilt2 / nf).sqrt(),
                yaw_rmse_deg: (yaw2 / nf).sqrt(),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_yaw_offset_is_scored_as_yaw_not_tilt() {
        let mut track = AttitudeTrack::default();
        track.push_truth(0.0, [0.0, 0.0, 0.0, 1.0]);
        track.push_truth(0.01, [0.0, 0.0, 0.0, 1.0]);
        let half = 5f64.to_radians() / 2.0;
        track.push_estimate(0.005, [0.0, 0.0, half.sin(), half.cos()]);
        let s = track.summary().unwrap();
        assert!((s.rmse_deg - 5.0).abs() < 1e-9, "{s:?}");
        assert!((s.yaw_rmse_deg - 5.0).abs() < 1e-9, "{s:?}");
        assert!(s.tilt_rmse_deg < 1e-9, "{s:?}");
    }
}
