//! Scoring the attitude of an estimator against the motion-capture
//! orientation: the angle of the rotation between the two (all three axes)
//! and the tilt (the angle between the two body z axes, what roll and
//! pitch errors amount to), truth interpolated (normalised linear, the
//! samples are 4 ms apart) at each estimate's time.

use std::collections::VecDeque;

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

/// Attitude estimates scored against the truth while both stream in:
/// only the estimates waiting for the truth after them and the truth
/// they may need are kept.
#[derive(Debug, Clone)]
pub struct AttitudeTrack {
    pending: VecDeque<(f64, [f64; 4])>,
    truth: VecDeque<(f64, [f64; 4])>,
    /// Time of the newest estimate.
    newest_s: f64,
    /// No estimate to come is older than this (the caller's promise).
    floor_s: f64,
    sums: Sums,
}

impl Default for AttitudeTrack {
    fn default() -> Self {
        Self {
            pending: VecDeque::new(),
            truth: VecDeque::new(),
            newest_s: f64::NEG_INFINITY,
            floor_s: f64::NEG_INFINITY,
            sums: Sums::default(),
        }
    }
}

/// The running sums of the scored errors.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    n: u64,
    sum2: f64,
    max: f64,
    tilt2: f64,
    yaw2: f64,
}

fn unit(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

impl AttitudeTrack {
    /// Adds an estimate `[x, y, z, w]` (times non-decreasing).
    pub fn push_estimate(&mut self, t_s: f64, q: [f64; 4]) {
        self.pending.push_back((t_s, q));
        self.newest_s = self.newest_s.max(t_s);
        self.resolve(false);
    }

    /// Adds a truth orientation (times non-decreasing), scores what it
    /// covers and forgets the truth no estimate to come needs.
    pub fn push_truth(&mut self, t_s: f64, q: [f64; 4]) {
        self.truth.push_back((t_s, q));
        self.resolve(false);
        let horizon = self
            .pending
            .front()
            .map_or(self.newest_s.max(self.floor_s), |e| e.0);
        while self.truth.len() > 2 && self.truth[1].0 <= horizon {
            self.truth.pop_front();
        }
    }

    /// Promises that no estimate to come is older than `t_s`.
    pub fn set_floor(&mut self, t_s: f64) {
        self.floor_s = self.floor_s.max(t_s);
    }

    /// The end of the truth: scores what it can of the rest.
    pub fn finish(&mut self) {
        self.resolve(true);
    }

    fn resolve(&mut self, ended: bool) {
        let newest = self.truth.back().map_or(f64::NEG_INFINITY, |r| r.0);
        while let Some(&(t, q)) = self.pending.front() {
            if t > newest && !ended {
                break;
            }
            self.pending.pop_front();
            if let Some(truth) = self.truth_at(t) {
                self.score(&truth, &unit(q));
            }
        }
    }

    fn score(&mut self, truth: &UnitQuaternion<f64>, est: &UnitQuaternion<f64>) {
        let e = (truth.inverse() * est).angle().to_degrees();
        let z = Vector3::z();
        let tilt = (truth * z).angle(&(est * z)).to_degrees();
        let yaw = (est.euler_angles().2 - truth.euler_angles().2 + std::f64::consts::PI)
            .rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        let s = &mut self.sums;
        s.n += 1;
        s.sum2 += e * e;
        s.max = s.max.max(e);
        s.tilt2 += tilt * tilt;
        s.yaw2 += yaw.to_degrees().powi(2);
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

    /// The statistics of what was scored, `None` when nothing was.
    pub fn summary(&self) -> Option<AttitudeSummary> {
        let s = self.sums;
        (s.n > 0).then(|| {
            let nf = s.n as f64;
            AttitudeSummary {
                scored: s.n,
                rmse_deg: (s.sum2 / nf).sqrt(),
                max_deg: s.max,
                tilt_rmse_deg: (s.tilt2 / nf).sqrt(),
                yaw_rmse_deg: (s.yaw2 / nf).sqrt(),
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
        track.finish();
        let s = track.summary().unwrap();
        assert!((s.rmse_deg - 5.0).abs() < 1e-9, "{s:?}");
        assert!((s.yaw_rmse_deg - 5.0).abs() < 1e-9, "{s:?}");
        assert!(s.tilt_rmse_deg < 1e-9, "{s:?}");
    }
}
