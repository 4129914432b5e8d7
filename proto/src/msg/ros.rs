//! ROS 2 message layouts, so that ROS tools can read what ICKON publishes
//! through `zenoh-bridge-ros2dds` (which maps a topic to a key with the plain
//! CDR payload).

use serde::{Deserialize, Serialize};
use serde_big_array::BigArray;

use crate::msg::robot::RobotPose;
use crate::time::Time;

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RosTime {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl From<Time> for RosTime {
    fn from(t: Time) -> Self {
        let ns = t.as_nanos();
        let sec = ns.div_euclid(1_000_000_000);
        RosTime {
            sec: sec.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// Stamp.
    pub stamp: RosTime,
    /// Frame id.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub frame_id: String,
}

/// `geometry_msgs/msg/Point`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// z, metres.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// Pose.
    pub pose: Pose,
    /// 6x6 row-major covariance of (x, y, z, roll, pitch, yaw).
    #[serde(with = "BigArray")]
    pub covariance: [f64; 36],
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// Header.
    pub header: Header,
    /// Pose and covariance.
    pub pose: PoseWithCovariance,
}

/// Variance given to the unobserved z, roll and pitch: large, so that ROS
/// consumers know they carry no information.
const UNOBSERVED_VARIANCE: f64 = 1e6;

impl PoseWithCovarianceStamped {
    /// The ROS view of a fused planar pose.
    pub fn from_robot_pose(pose: &RobotPose, frame_id: &str) -> Self {
        let half = pose.theta_rad / 2.0;
        let mut covariance = [0.0; 36];
        // (x, y, yaw) of ours sit at rows/columns (0, 1, 5) of the ROS 6x6.
        let map = [0usize, 1, 5];
        for (i, &ri) in map.iter().enumerate() {
            for (j, &rj) in map.iter().enumerate() {
                covariance[ri * 6 + rj] = pose.covariance[i * 3 + j];
            }
        }
        for k in [2usize, 3, 4] {
            covariance[k * 6 + k] = UNOBSERVED_VARIANCE;
        }
        PoseWithCovarianceStamped {
            header: Header {
                stamp: pose.stamp.into(),
                frame_id: frame_id.to_string(),
            },
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point {
                        x: pose.x_m,
                        y: pose.y_m,
                        z: 0.0,
                    },
                    orientation: Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: half.sin(),
                        w: half.cos(),
                    },
                },
                covariance,
            },
        }
    }
}
