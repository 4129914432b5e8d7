//! What a user sets to run the MSU agent on ROS 2: `--ros2-*` flags, and the
//! same fields in the MSU configuration file (`[ros2]`, every field
//! optional: a missing one takes the default below).

use clap::{Args, ValueEnum};
use serde::Deserialize;

/// How ROS 2 topics travel over Zenoh.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ros2Mode {
    /// rmw_zenoh (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`, ROS 2 Jazzy and newer):
    /// typed keys, the sample attachment and liveliness tokens.
    #[default]
    RmwZenoh,
    /// Robots on DDS behind `zenoh-bridge-ros2dds`: the topic name as the
    /// key, no attachment, no tokens.
    Bridge,
}

/// Default node name.
pub const DEFAULT_NODE_NAME: &str = "ickon_msu";
/// Default fused pose topic (relative: under the namespace).
pub const DEFAULT_POSE_TOPIC: &str = "pose";
/// Default raw fix topic.
pub const DEFAULT_FIX_TOPIC: &str = "ickon/fix";
/// Default transform topic (absolute, as tf2 has it).
pub const DEFAULT_TF_TOPIC: &str = "/tf";
/// Default odometry input topic.
pub const DEFAULT_ODOM_TOPIC: &str = "odom";
/// Default IMU input topic.
pub const DEFAULT_IMU_TOPIC: &str = "imu";
/// REP-105 fixed frame.
pub const DEFAULT_MAP_FRAME: &str = "map";
/// REP-105 odometry frame.
pub const DEFAULT_ODOM_FRAME: &str = "odom";
/// How far ahead the `map -> odom` transform is stamped, seconds: nav2's
/// AMCL default `transform_tolerance`, so that nav2 finds the transform at
/// the times it asks for between two of our poses.
pub const DEFAULT_TF_TOLERANCE_S: f64 = 1.0;

/// The ROS 2 side of the MSU agent.
#[derive(Debug, Clone, PartialEq, Args, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Ros2Options {
    /// Speak ROS 2: publish the pose, the fix and `map -> odom`, and read
    /// odometry and IMU from ROS 2 topics.
    #[arg(id = "ros2", long = "ros2")]
    pub enabled: bool,
    /// rmw-zenoh (ROS 2 on Zenoh) or bridge (DDS behind zenoh-bridge-ros2dds).
    #[arg(id = "ros2_mode", long = "ros2-mode", value_enum, default_value_t = Ros2Mode::RmwZenoh)]
    pub mode: Ros2Mode,
    /// ROS domain id; default `ROS_DOMAIN_ID`, else 0.
    #[arg(id = "ros2_domain", long = "ros2-domain")]
    pub domain: Option<u32>,
    /// Namespace of the node and its relative topics; default `/<robot id>`.
    #[arg(id = "ros2_namespace", long = "ros2-namespace")]
    pub namespace: Option<String>,
    /// Node name (what `ros2 node list` shows).
    #[arg(id = "ros2_node_name", long = "ros2-node-name", default_value = DEFAULT_NODE_NAME)]
    pub node_name: String,
    /// The bridge's namespace (`zenoh-bridge-ros2dds --namespace`), bridge mode only.
    #[arg(
        id = "ros2_bridge_namespace",
        long = "ros2-bridge-namespace",
        default_value = ""
    )]
    pub bridge_namespace: String,
    /// Fused pose topic (`geometry_msgs/msg/PoseWithCovarianceStamped`).
    #[arg(id = "ros2_pose_topic", long = "ros2-pose-topic", default_value = DEFAULT_POSE_TOPIC)]
    pub pose_topic: String,
    /// Raw fix topic (same type).
    #[arg(id = "ros2_fix_topic", long = "ros2-fix-topic", default_value = DEFAULT_FIX_TOPIC)]
    pub fix_topic: String,
    /// Transform topic (`tf2_msgs/msg/TFMessage`).
    #[arg(id = "ros2_tf_topic", long = "ros2-tf-topic", default_value = DEFAULT_TF_TOPIC)]
    pub tf_topic: String,
    /// Odometry input topic (`nav_msgs/msg/Odometry`).
    #[arg(id = "ros2_odom_topic", long = "ros2-odom-topic", default_value = DEFAULT_ODOM_TOPIC)]
    pub odom_topic: String,
    /// IMU input topic (`sensor_msgs/msg/Imu`; its z rate is the gyro).
    #[arg(id = "ros2_imu_topic", long = "ros2-imu-topic", default_value = DEFAULT_IMU_TOPIC)]
    pub imu_topic: String,
    /// Fixed frame of the pose and parent of the transform.
    #[arg(id = "ros2_map_frame", long = "ros2-map-frame", default_value = DEFAULT_MAP_FRAME)]
    pub map_frame: String,
    /// Odometry frame, child of the transform.
    #[arg(id = "ros2_odom_frame", long = "ros2-odom-frame", default_value = DEFAULT_ODOM_FRAME)]
    pub odom_frame: String,
    /// Read odometry and IMU from ROS 2 (`false`: publish only).
    #[arg(id = "ros2_inputs", long = "ros2-inputs", action = clap::ArgAction::Set, default_value_t = true)]
    pub inputs: bool,
    /// Publish `map -> odom` on the transform topic.
    #[arg(id = "ros2_tf", long = "ros2-tf", action = clap::ArgAction::Set, default_value_t = true)]
    pub publish_tf: bool,
    /// How far ahead `map -> odom` is stamped, seconds (AMCL's `transform_tolerance`).
    #[arg(id = "ros2_tf_tolerance_s", long = "ros2-tf-tolerance-s", default_value_t = DEFAULT_TF_TOLERANCE_S)]
    pub tf_tolerance_s: f64,
    /// Publish poses no fix has confirmed yet (the start pose carried by
    /// odometry; `Localising` on ICKON's own pose key). Off by default: nav2
    /// would steer by a start pose the robot may not be at (an MSU restarted
    /// while its robot drove); on for a robot that starts at a known pose
    /// and drives on odometry before its first fix.
    #[arg(id = "ros2_unconfirmed_poses", long = "ros2-unconfirmed-poses", action = clap::ArgAction::Set, default_value_t = false)]
    pub unconfirmed_poses: bool,
}

impl Ros2Options {
    /// The options of a configuration file's `[ros2]` block (`file`) under
    /// the command line's (`flags`): a flag whose value differs from its
    /// default wins, every other field keeps the file's; `--ros2` or the
    /// file's `enabled` turns ROS 2 on. (A flag given with its default value
    /// cannot be told from one not given, so it does not override the file.)
    pub fn under_flags(file: &Self, flags: &Self) -> Self {
        let default = Self::default();
        macro_rules! pick {
            ($($field:ident),*) => {
                Self {
                    enabled: file.enabled || flags.enabled,
                    $($field: if flags.$field != default.$field {
                        flags.$field.clone()
                    } else {
                        file.$field.clone()
                    },)*
                }
            };
        }
        pick!(
            mode,
            domain,
            namespace,
            node_name,
            bridge_namespace,
            pose_topic,
            fix_topic,
            tf_topic,
            odom_topic,
            imu_topic,
            map_frame,
            odom_frame,
            inputs,
            publish_tf,
            tf_tolerance_s,
            unconfirmed_poses
        )
    }
}

impl Default for Ros2Options {
    fn default() -> Self {
        Self {
            enabled: false,
            mode: Ros2Mode::RmwZenoh,
            domain: None,
            namespace: None,
            node_name: DEFAULT_NODE_NAME.into(),
            bridge_namespace: String::new(),
            pose_topic: DEFAULT_POSE_TOPIC.into(),
            fix_topic: DEFAULT_FIX_TOPIC.into(),
            tf_topic: DEFAULT_TF_TOPIC.into(),
            odom_topic: DEFAULT_ODOM_TOPIC.into(),
            imu_topic: DEFAULT_IMU_TOPIC.into(),
            map_frame: DEFAULT_MAP_FRAME.into(),
            odom_frame: DEFAULT_ODOM_FRAME.into(),
            inputs: true,
            publish_tf: true,
            tf_tolerance_s: DEFAULT_TF_TOLERANCE_S,
            unconfirmed_poses: false,
        }
    }
}
