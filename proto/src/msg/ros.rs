//! ROS 2 message layouts (Jazzy), so that ROS 2 tools read what ICKON
//! publishes and ICKON reads what a ROS 2 robot publishes, through rmw_zenoh
//! or `zenoh-bridge-ros2dds` (see [`crate::ros`] for their keys). Each type
//! encodes with [`crate::encode`] to exactly the CDR of its `.msg`; each
//! implements [`RosMessage`] (its type name and RIHS01 hash).

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

impl RosTime {
    /// The same instant as a [`Time`] on the same time base, or `None` when
    /// `nanosec` is not below one second (malformed).
    pub fn to_time(self) -> Option<Time> {
        if self.nanosec >= 1_000_000_000 {
            return None;
        }
        Some(Time::from_nanos(
            i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec),
        ))
    }
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

/// A ROS 2 message type: its name and its REP-2011 type hash, which
/// rmw_zenoh puts in every data key and liveliness token.
pub trait RosMessage {
    /// `pkg/msg/Name`.
    const TYPE_NAME: &'static str;
    /// `RIHS01_<sha256 hex>` of the type description (ROS 2 Jazzy; checked
    /// against `rosbags`' `hash_rihs01`).
    const TYPE_HASH: &'static str;
}

impl RosMessage for PoseWithCovarianceStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/PoseWithCovarianceStamped";
    const TYPE_HASH: &'static str =
        "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";
}

impl RosMessage for Odometry {
    const TYPE_NAME: &'static str = "nav_msgs/msg/Odometry";
    const TYPE_HASH: &'static str =
        "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0";
}

impl RosMessage for Imu {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/Imu";
    const TYPE_HASH: &'static str =
        "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b";
}

impl RosMessage for TfMessage {
    const TYPE_NAME: &'static str = "tf2_msgs/msg/TFMessage";
    const TYPE_HASH: &'static str =
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087";
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Twist`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vector3,
    /// Angular velocity, rad/s.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// Twist.
    pub twist: Twist,
    /// 6x6 row-major covariance of (vx, vy, vz, wx, wy, wz).
    #[serde(with = "BigArray")]
    pub covariance: [f64; 36],
}

/// `nav_msgs/msg/Odometry`: the robot's dead reckoning, `header.frame_id`
/// (`odom`) to `child_frame_id` (`base_link`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and the odometry frame.
    pub header: Header,
    /// The robot's body frame.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub child_frame_id: String,
    /// Pose in the odometry frame.
    pub pose: PoseWithCovariance,
    /// Velocity in the body frame.
    pub twist: TwistWithCovariance,
}

/// `sensor_msgs/msg/Imu`. A covariance whose first element is -1 means
/// "not provided" (the `.msg`'s convention).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Stamp and the IMU frame.
    pub header: Header,
    /// Orientation.
    pub orientation: Quaternion,
    /// Its 3x3 row-major covariance.
    pub orientation_covariance: [f64; 9],
    /// Angular rate, rad/s.
    pub angular_velocity: Vector3,
    /// Its 3x3 row-major covariance.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration, m/s^2.
    pub linear_acceleration: Vector3,
    /// Its 3x3 row-major covariance.
    pub linear_acceleration_covariance: [f64; 9],
}

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation, metres.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`: `header.frame_id` to `child_frame_id`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and the parent frame.
    pub header: Header,
    /// The child frame.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub child_frame_id: String,
    /// The child frame's pose in the parent frame.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`, what `/tf` carries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl Quaternion {
    /// The rotation by `yaw_rad` about z.
    pub fn from_yaw(yaw_rad: f64) -> Self {
        let half = yaw_rad / 2.0;
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: half.sin(),
            w: half.cos(),
        }
    }

    /// The rotation about z of this quaternion (its yaw; ZYX convention).
    pub fn yaw_rad(&self) -> f64 {
        let siny = 2.0 * (self.w * self.z + self.x * self.y);
        let cosy = 1.0 - 2.0 * (self.y * self.y + self.z * self.z);
        siny.atan2(cosy)
    }
}

/// The ROS covariance "not provided" marker (first element -1).
pub const COVARIANCE_UNKNOWN: [f64; 9] = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

impl Imu {
    /// A yaw-rate-only IMU sample, as our gyro gives it: orientation and
    /// acceleration marked not provided.
    pub fn from_gyro_z(stamp: Time, frame_id: &str, rate_rad_s: f64, rate_variance: f64) -> Self {
        let mut angular_velocity_covariance = [0.0; 9];
        angular_velocity_covariance[8] = rate_variance;
        Imu {
            header: Header {
                stamp: stamp.into(),
                frame_id: frame_id.to_string(),
            },
            orientation: Quaternion::from_yaw(0.0),
            orientation_covariance: COVARIANCE_UNKNOWN,
            angular_velocity: Vector3 {
                x: 0.0,
                y: 0.0,
                z: rate_rad_s,
            },
            angular_velocity_covariance,
            linear_acceleration: Vector3::default(),
            linear_acceleration_covariance: COVARIANCE_UNKNOWN,
        }
    }
}

impl Odometry {
    /// A planar odometry sample: the body at `pose` (`x, y, theta` in
    /// `odom_frame`) moving at `twist` (`v` forward, `omega` about z), with
    /// the variances of those five values; the rest is marked unobserved.
    pub fn planar(
        stamp: Time,
        odom_frame: &str,
        base_frame: &str,
        pose: [f64; 3],
        twist: [f64; 2],
        pose_variance: [f64; 3],
        twist_variance: [f64; 2],
    ) -> Self {
        let mut pose_cov = [0.0; 36];
        pose_cov[0] = pose_variance[0];
        pose_cov[7] = pose_variance[1];
        pose_cov[35] = pose_variance[2];
        let mut twist_cov = [0.0; 36];
        twist_cov[0] = twist_variance[0];
        twist_cov[35] = twist_variance[1];
        for k in [2usize, 3, 4] {
            pose_cov[k * 6 + k] = UNOBSERVED_VARIANCE;
        }
        for k in [1usize, 2, 3, 4] {
            twist_cov[k * 6 + k] = UNOBSERVED_VARIANCE;
        }
        Odometry {
            header: Header {
                stamp: stamp.into(),
                frame_id: odom_frame.to_string(),
            },
            child_frame_id: base_frame.to_string(),
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point {
                        x: pose[0],
                        y: pose[1],
                        z: 0.0,
                    },
                    orientation: Quaternion::from_yaw(pose[2]),
                },
                covariance: pose_cov,
            },
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: Vector3 {
                        x: twist[0],
                        y: 0.0,
                        z: 0.0,
                    },
                    angular: Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: twist[1],
                    },
                },
                covariance: twist_cov,
            },
        }
    }
}
