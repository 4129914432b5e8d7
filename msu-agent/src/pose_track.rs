//! A robot's velocity, from the poses its agent makes, for its summary
//! (the central unit predicts where a robot will be during the next cycle
//! instead of allowing for its top speed in every direction).
//!
//! The poses of `tdoa-ekf` come at the odometry rate (tens of hertz) and
//! are smooth over a fraction of a second, so the mean velocity over the
//! last [`VELOCITY_WINDOW`] of pose stamps is a good guess of the next
//! fraction of a second. The stamps are the MSU's own clock, so the
//! difference of two is exact whatever that clock's offset. Pure: fed
//! poses, asked for the velocity.

use std::collections::VecDeque;

use ickon_proto::msg::robot::{PoseStatus, RobotPose};
use ickon_proto::time::{Duration, Time};

/// Poses behind the velocity: those of the last half second (MSU stamps).
pub const VELOCITY_WINDOW: Duration = Duration::from_millis(500);
/// Least time between the two poses a velocity is taken from: over a
/// shorter span the poses' own noise would dominate.
pub const MIN_VELOCITY_SPAN: Duration = Duration::from_millis(200);
/// A gap in the stamps longer than this starts the track again (an MSU
/// that restarted or was stalled).
const MAX_GAP: Duration = Duration::from_millis(1_000);
/// Most poses kept: a robot publishing far above the odometry rate cannot
/// make the track grow without bound.
const MAX_POSES: usize = 256;

/// A robot's mean velocity over a span of its poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Velocity {
    /// Velocity in the site frame, m/s.
    pub v_m_s: [f64; 2],
    /// The span of pose stamps it is the mean over, seconds.
    pub span_s: f64,
}

impl Velocity {
    /// Its speed, m/s.
    pub fn speed_m_s(&self) -> f64 {
        self.v_m_s[0].hypot(self.v_m_s[1])
    }
}

/// The recent positions of one robot, by its own pose stamps.
#[derive(Debug, Clone, Default)]
pub struct PoseTrack {
    poses: VecDeque<(Time, [f64; 2])>,
}

impl PoseTrack {
    /// Takes a published pose. A pose no fix has confirmed, one with a
    /// position that is not a number, or a stamp far after or far before
    /// the last (an MSU that stalled, or whose clock was stepped) starts the
    /// track again; a stamp a little before the last, or equal to it, is
    /// ignored (a repeated or reordered message).
    pub fn push(&mut self, pose: &RobotPose) {
        let xy = [pose.x_m, pose.y_m];
        if pose.status == PoseStatus::Localising || !xy.iter().all(|v| v.is_finite()) {
            self.poses.clear();
            return;
        }
        if let Some(&(last, _)) = self.poses.back() {
            if pose.stamp.since(last) > MAX_GAP || last.since(pose.stamp) > MAX_GAP {
                self.poses.clear();
            } else if pose.stamp <= last {
                return;
            }
        }
        self.poses.push_back((pose.stamp, xy));
        while self.poses.len() > MAX_POSES
            || self
                .poses
                .front()
                .is_some_and(|&(t, _)| pose.stamp.since(t) > VELOCITY_WINDOW)
        {
            self.poses.pop_front();
        }
    }

    /// The mean velocity from the oldest pose of the window to the newest,
    /// when they are at least [`MIN_VELOCITY_SPAN`] apart.
    pub fn velocity(&self) -> Option<Velocity> {
        let (&(t0, a), &(t1, b)) = (self.poses.front()?, self.poses.back()?);
        let span = t1.since(t0);
        if span < MIN_VELOCITY_SPAN {
            return None;
        }
        let span_s = span.as_secs_f64();
        let v_m_s = [(b[0] - a[0]) / span_s, (b[1] - a[1]) / span_s];
        v_m_s
            .iter()
            .all(|v| v.is_finite())
            .then_some(Velocity { v_m_s, span_s })
    }

    /// Forgets every pose.
    pub fn clear(&mut self) {
        self.poses.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(t_ms: i64, x_m: f64, y_m: f64) -> RobotPose {
        RobotPose {
            stamp: Time(t_ms * 1_000_000),
            x_m,
            y_m,
            theta_rad: 0.0,
            covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
            estimator: "tdoa-ekf".into(),
            fix_seq: 1,
            status: PoseStatus::Tracking,
        }
    }

    #[test]
    fn the_velocity_is_the_mean_over_the_last_half_second() {
        let mut track = PoseTrack::default();
        // 1 m/s along x for a second, then 0.5 m/s along y.
        for k in 0..=50 {
            track.push(&pose(k * 20, k as f64 * 0.02, 0.0));
        }
        let v = track.velocity().unwrap();
        assert!((v.v_m_s[0] - 1.0).abs() < 1e-9 && v.v_m_s[1].abs() < 1e-9);
        assert!((v.span_s - 0.5).abs() < 1e-9, "{v:?}");
        for k in 1..=50 {
            track.push(&pose(1000 + k * 20, 1.0, k as f64 * 0.01));
        }
        let v = track.velocity().unwrap();
        assert!(v.v_m_s[0].abs() < 1e-9 && (v.v_m_s[1] - 0.5).abs() < 1e-9);
        assert!((v.speed_m_s() - 0.5).abs() < 1e-9);
    }

    #[test]
    fn too_short_a_span_gives_no_velocity() {
        let mut track = PoseTrack::default();
        assert_eq!(track.velocity(), None);
        for k in 0..10 {
            track.push(&pose(k * 20, k as f64 * 0.02, 0.0));
        }
        // 180 ms of poses.
        assert_eq!(track.velocity(), None);
        track.push(&pose(200, 0.2, 0.0));
        assert!(track.velocity().is_some());
    }

    #[test]
    fn repeats_gaps_garbage_and_unconfirmed_poses_never_make_a_velocity_up() {
        let mut track = PoseTrack::default();
        for k in 0..=25 {
            track.push(&pose(k * 20, k as f64 * 0.02, 0.0));
        }
        let v = track.velocity().unwrap();
        // A repeated or reordered pose (a forged one far away) is ignored.
        track.push(&pose(500, 100.0, 100.0));
        track.push(&pose(100, -100.0, 0.0));
        assert_eq!(track.velocity(), Some(v));
        // A stalled MSU: after a gap the track starts again.
        track.push(&pose(3_000, 40.0, 0.0));
        assert_eq!(track.velocity(), None);
        // An MSU clock stepped back by seconds: the track starts again from
        // the new stamps instead of ignoring them for good.
        for k in 0..=25 {
            track.push(&pose(k * 20, 40.0 + k as f64 * 0.01, 0.0));
        }
        let back = track.velocity().unwrap();
        assert!((back.v_m_s[0] - 0.5).abs() < 1e-9, "{back:?}");
        // Not a number, or not confirmed by a fix: nothing is kept.
        for k in 1..=25 {
            track.push(&pose(3_000 + k * 20, 40.0 + k as f64 * 0.02, 0.0));
        }
        assert!(track.velocity().is_some());
        track.push(&pose(3_600, f64::NAN, 0.0));
        assert_eq!(track.velocity(), None);
        for k in 0..=25 {
            track.push(&pose(4_000 + k * 20, k as f64 * 0.02, 0.0));
        }
        let mut unconfirmed = pose(4_600, 1.0, 0.0);
        unconfirmed.status = PoseStatus::Localising;
        track.push(&unconfirmed);
        assert_eq!(track.velocity(), None);
    }

    #[test]
    fn a_flood_of_poses_keeps_the_track_bounded() {
        let mut track = PoseTrack::default();
        // 100 kHz of poses, 1 m/s.
        for k in 0..100_000i64 {
            let mut p = pose(0, k as f64 * 1e-5, 0.0);
            p.stamp = Time(k * 10_000);
            track.push(&p);
        }
        assert!(track.poses.len() <= MAX_POSES);
        // 256 poses span 2.55 ms: too short for a velocity.
        assert_eq!(track.velocity(), None);
    }
}
