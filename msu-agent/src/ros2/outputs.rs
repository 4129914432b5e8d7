//! What the agent publishes on ROS 2, built from its own messages. Pure.
//!
//! - the fused pose as `PoseWithCovarianceStamped` in the map frame, stamped
//!   with the time of the measurement, its covariance the estimator's with a
//!   floor (never zeros) and nothing published at all if any value is not
//!   finite;
//! - the raw fix, the same type: position and its 3x3 covariance, and the
//!   receiver-id heading when the fix has one;
//! - `map -> odom` (REP-105) as AMCL computes it: the pose of the body in
//!   the map composed with the inverse of its pose in the odometry frame at
//!   the same time, stamped ahead by the tolerance.

use std::collections::VecDeque;

use ickon_proto::msg::robot::{Fix, Odometry, RobotPose};
use ickon_proto::msg::ros::{
    Header, Point, Pose, PoseWithCovariance, PoseWithCovarianceStamped, Quaternion, TfMessage,
    Transform, TransformStamped, Vector3,
};
use ickon_proto::time::{Duration, Time};

/// Smallest variance published for x and y, m^2 (1 mm): an estimator that
/// reports less is overconfident, and zeros make ROS consumers divide by zero.
pub const MIN_POSITION_VARIANCE_M2: f64 = 1e-6;
/// Smallest variance published for the heading, rad^2 (about 0.06 deg).
pub const MIN_HEADING_VARIANCE_RAD2: f64 = 1e-6;
/// Variance of what we do not observe (z, roll, pitch; a fix without heading).
pub const UNOBSERVED_VARIANCE: f64 = 1e6;
/// Variance of the receiver-id heading: uniform within +-30 deg (the ICKON paper).
pub const RECEIVER_HEADING_VARIANCE_RAD2: f64 =
    (std::f64::consts::PI / 6.0) * (std::f64::consts::PI / 6.0) / 3.0;
/// How much odometry history is kept to pair with late poses, seconds.
pub const ODOM_HISTORY_S: f64 = 2.0;

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// The fused pose for ROS, or `None` if it holds a non-finite value.
pub fn pose_message(pose: &RobotPose, map_frame: &str) -> Option<PoseWithCovarianceStamped> {
    if !all_finite(&[pose.x_m, pose.y_m, pose.theta_rad]) || !all_finite(&pose.covariance) {
        return None;
    }
    let mut msg = PoseWithCovarianceStamped::from_robot_pose(pose, map_frame);
    let c = &mut msg.pose.covariance;
    c[0] = c[0].max(MIN_POSITION_VARIANCE_M2);
    c[7] = c[7].max(MIN_POSITION_VARIANCE_M2);
    c[35] = c[35].max(MIN_HEADING_VARIANCE_RAD2);
    Some(msg)
}

/// The raw fix for ROS, or `None` if it holds a non-finite value.
pub fn fix_message(fix: &Fix, map_frame: &str) -> Option<PoseWithCovarianceStamped> {
    if !all_finite(&[fix.x_m, fix.y_m, fix.z_m]) || !all_finite(&fix.covariance) {
        return None;
    }
    let heading = fix.heading_valid && fix.heading_rad.is_finite();
    let mut covariance = [0.0; 36];
    for i in 0..3 {
        for j in 0..3 {
            covariance[i * 6 + j] = fix.covariance[i * 3 + j];
        }
    }
    for k in 0..3 {
        covariance[k * 6 + k] = covariance[k * 6 + k].max(MIN_POSITION_VARIANCE_M2);
    }
    covariance[3 * 6 + 3] = UNOBSERVED_VARIANCE;
    covariance[4 * 6 + 4] = UNOBSERVED_VARIANCE;
    covariance[5 * 6 + 5] = if heading {
        RECEIVER_HEADING_VARIANCE_RAD2
    } else {
        UNOBSERVED_VARIANCE
    };
    Some(PoseWithCovarianceStamped {
        header: Header {
            stamp: fix.stamp.into(),
            frame_id: map_frame.to_string(),
        },
        pose: PoseWithCovariance {
            pose: Pose {
                position: Point {
                    x: fix.x_m,
                    y: fix.y_m,
                    z: fix.z_m,
                },
                orientation: Quaternion::from_yaw(if heading { fix.heading_rad } else { 0.0 }),
            },
            covariance,
        },
    })
}

/// The body's recent poses in the odometry frame.
#[derive(Debug, Clone, Default)]
pub struct OdomHistory {
    samples: VecDeque<(Time, [f64; 3])>,
}

impl OdomHistory {
    /// Adds an odometry sample (ignored if older than the newest or not finite).
    pub fn push(&mut self, odom: &Odometry) {
        if !all_finite(&[odom.x_m, odom.y_m, odom.theta_rad]) {
            return;
        }
        if self.samples.back().is_some_and(|(t, _)| odom.stamp < *t) {
            return;
        }
        self.samples
            .push_back((odom.stamp, [odom.x_m, odom.y_m, odom.theta_rad]));
        let horizon = odom
            .stamp
            .as_nanos()
            .saturating_sub(Duration::from_secs_f64(ODOM_HISTORY_S).as_nanos());
        while self.samples.len() > 2
            && self
                .samples
                .front()
                .is_some_and(|(t, _)| t.as_nanos() < horizon)
        {
            self.samples.pop_front();
        }
    }

    /// The odometry pose at `t`: interpolated between the samples around
    /// it, the nearest end outside them; `None` with no sample.
    pub fn at(&self, t: Time) -> Option<[f64; 3]> {
        let (first_t, first) = *self.samples.front()?;
        if t <= first_t {
            return Some(first);
        }
        let mut prev = (first_t, first);
        for &(ts, p) in self.samples.iter().skip(1) {
            if t <= ts {
                let span = ts.since(prev.0).as_secs_f64();
                let f = if span > 0.0 {
                    t.since(prev.0).as_secs_f64() / span
                } else {
                    1.0
                };
                let lerp = |a: f64, b: f64| a + f * (b - a);
                return Some([
                    lerp(prev.1[0], p[0]),
                    lerp(prev.1[1], p[1]),
                    lerp(prev.1[2], p[2]),
                ]);
            }
            prev = (ts, p);
        }
        Some(prev.1)
    }
}

/// `map -> odom` from the body's pose in the map (`x, y, theta`) and in the
/// odometry frame at the same time.
pub fn map_to_odom(map_base: [f64; 3], odom_base: [f64; 3]) -> Transform {
    let th = map_base[2] - odom_base[2];
    let (s, c) = th.sin_cos();
    Transform {
        translation: Vector3 {
            x: map_base[0] - (c * odom_base[0] - s * odom_base[1]),
            y: map_base[1] - (s * odom_base[0] + c * odom_base[1]),
            z: 0.0,
        },
        rotation: Quaternion::from_yaw(th),
    }
}

/// The `/tf` message for `pose`, or `None` without odometry near it or with
/// a non-finite value.
pub fn tf_message(
    pose: &RobotPose,
    odom: &OdomHistory,
    map_frame: &str,
    odom_frame: &str,
    tolerance_s: f64,
) -> Option<TfMessage> {
    if !all_finite(&[pose.x_m, pose.y_m, pose.theta_rad]) {
        return None;
    }
    let odom_base = odom.at(pose.stamp)?;
    let transform = map_to_odom([pose.x_m, pose.y_m, pose.theta_rad], odom_base);
    let stamp = Time::from_nanos(
        pose.stamp
            .as_nanos()
            .saturating_add(Duration::from_secs_f64(tolerance_s).as_nanos()),
    );
    Some(TfMessage {
        transforms: vec![TransformStamped {
            header: Header {
                stamp: stamp.into(),
                frame_id: map_frame.to_string(),
            },
            child_frame_id: odom_frame.to_string(),
            transform,
        }],
    })
}
