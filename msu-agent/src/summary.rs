//! The robot's summary for the central unit ([`RobotSummary`]): the newest
//! pose, the velocity over its last poses and the newest fixes, once every
//! [`SUMMARY_PERIOD`] of pose stamps. The central unit reads this instead
//! of every pose and fix, so what a robot costs it does not grow with the
//! pose or cycle rate.
//!
//! Pure: fed the poses and fixes the agent publishes, it says when a
//! summary is due by the poses' own stamps (no clock of its own).

use std::collections::VecDeque;

use ickon_proto::msg::robot::{Fix, MAX_SUMMARY_FIXES, RobotPose, RobotSummary, SUMMARY_PERIOD};
use ickon_proto::time::Time;

use crate::pose_track::PoseTrack;

/// Builds one robot's summaries.
#[derive(Debug, Clone, Default)]
pub struct SummaryMaker {
    track: PoseTrack,
    /// The stamp of the pose of the last summary made.
    last: Option<Time>,
    seq: u64,
    fixes: VecDeque<Fix>,
    fixes_solved: u32,
}

impl SummaryMaker {
    /// A fix the agent published: kept for the next summary (the newest
    /// [`MAX_SUMMARY_FIXES`]).
    pub fn on_fix(&mut self, fix: &Fix) {
        self.fixes_solved = self.fixes_solved.saturating_add(1);
        if self.fixes.len() == MAX_SUMMARY_FIXES {
            self.fixes.pop_front();
        }
        self.fixes.push_back(fix.clone());
    }

    /// A pose the agent published; the summary when one is due: the first
    /// pose, then the first one [`SUMMARY_PERIOD`] after the last summary's
    /// (or stamped that far before it: the MSU's clock was stepped back).
    pub fn on_pose(&mut self, pose: &RobotPose) -> Option<RobotSummary> {
        self.track.push(pose);
        let due = self.last.is_none_or(|last| {
            pose.stamp.since(last) >= SUMMARY_PERIOD || last.since(pose.stamp) >= SUMMARY_PERIOD
        });
        if !due {
            return None;
        }
        self.last = Some(pose.stamp);
        self.seq += 1;
        let (vx_m_s, vy_m_s, velocity_span_s) = match self.track.velocity() {
            Some(v) => (v.v_m_s[0], v.v_m_s[1], v.span_s),
            None => (0.0, 0.0, 0.0),
        };
        Some(RobotSummary {
            seq: self.seq,
            stamp: pose.stamp,
            x_m: pose.x_m,
            y_m: pose.y_m,
            theta_rad: pose.theta_rad,
            covariance: pose.covariance,
            estimator: pose.estimator.clone(),
            fix_seq: pose.fix_seq,
            status: pose.status,
            vx_m_s,
            vy_m_s,
            velocity_span_s,
            fixes_solved: std::mem::take(&mut self.fixes_solved),
            fixes: self.fixes.drain(..).collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::robot::{FixQuality, PoseStatus};

    fn pose(t_ms: i64, x_m: f64) -> RobotPose {
        RobotPose {
            stamp: Time(t_ms * 1_000_000),
            x_m,
            y_m: 1.0,
            theta_rad: 0.0,
            covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
            estimator: "tdoa-ekf".into(),
            fix_seq: 1,
            status: PoseStatus::Tracking,
        }
    }

    fn fix(seq: u64) -> Fix {
        Fix {
            stamp: Time(0),
            arrivals_seq: seq,
            x_m: 0.0,
            y_m: 0.0,
            z_m: 0.0,
            covariance: [0.0; 9],
            heading_rad: 0.0,
            heading_valid: false,
            used: vec![],
            rejected: vec![],
            residuals_m: vec![],
            quality: FixQuality::Good,
            survey_version: 0,
            unused: Vec::new(),
            unused_residuals_m: Vec::new(),
        }
    }

    #[test]
    fn poses_at_50_hz_make_a_summary_every_half_second_with_the_velocity() {
        let mut maker = SummaryMaker::default();
        let mut summaries = Vec::new();
        // 1 m/s along x for 2 s, 50 Hz.
        for k in 0..=100 {
            if let Some(s) = maker.on_pose(&pose(k * 20, k as f64 * 0.02)) {
                summaries.push(s);
            }
        }
        let stamps: Vec<i64> = summaries.iter().map(|s| s.stamp.0 / 1_000_000).collect();
        assert_eq!(stamps, [0, 500, 1000, 1500, 2000]);
        assert_eq!(
            summaries.iter().map(|s| s.seq).collect::<Vec<_>>(),
            [1, 2, 3, 4, 5]
        );
        // The first has no velocity yet; the later ones 1 m/s over 0.5 s.
        assert_eq!(summaries[0].velocity_span_s, 0.0);
        let last = summaries.last().unwrap();
        assert!((last.vx_m_s - 1.0).abs() < 1e-9 && last.vy_m_s.abs() < 1e-9);
        assert!((last.velocity_span_s - 0.5).abs() < 1e-9);
        assert!((last.x_m - 2.0).abs() < 1e-9);
    }

    #[test]
    fn a_summary_carries_the_newest_fixes_and_counts_them_all() {
        let mut maker = SummaryMaker::default();
        assert!(maker.on_pose(&pose(0, 0.0)).is_some());
        for seq in 1..=8 {
            maker.on_fix(&fix(seq));
        }
        assert!(maker.on_pose(&pose(100, 0.0)).is_none());
        let s = maker.on_pose(&pose(500, 0.0)).unwrap();
        assert_eq!(s.fixes_solved, 8);
        let seqs: Vec<u64> = s.fixes.iter().map(|f| f.arrivals_seq).collect();
        assert_eq!(seqs, [6, 7, 8]);
        // Sent once: the next summary has none.
        let next = maker.on_pose(&pose(1_000, 0.0)).unwrap();
        assert_eq!((next.fixes_solved, next.fixes.len()), (0, 0));
    }

    #[test]
    fn a_clock_stepped_back_does_not_silence_the_summaries() {
        let mut maker = SummaryMaker::default();
        assert!(maker.on_pose(&pose(10_000, 0.0)).is_some());
        assert!(maker.on_pose(&pose(10_100, 0.0)).is_none());
        // Stepped back by 9 s: a summary at once, then every half second again.
        assert!(maker.on_pose(&pose(1_000, 0.0)).is_some());
        assert!(maker.on_pose(&pose(1_200, 0.0)).is_none());
        assert!(maker.on_pose(&pose(1_500, 0.0)).is_some());
    }
}
