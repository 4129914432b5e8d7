//! The ROS 2 names and `ros2msg` schemas of every ICKON message, for MCAP
//! recordings that Foxglove and `ros2 bag` decode.
//!
//! Our own messages are the package `ickon_msgs`, one `.msg` file each in
//! `proto/msg/`, whose CDR layout is exactly what [`crate::encode`] writes
//! (`proto/src/msg_files_tests.rs` decodes every type by its `.msg` file alone and
//! compares): a recording stores the wire bytes as they are. Where a standard
//! ROS type fits, it is used instead: the fused pose is recorded as
//! `geometry_msgs/msg/PoseWithCovarianceStamped`
//! ([`PoseWithCovarianceStamped::from_robot_pose`](crate::msg::ros::PoseWithCovarianceStamped::from_robot_pose)).
//!
//! Times in `ickon_msgs` are `int64` nanoseconds since the epoch of the clock
//! each field names (the wire format's [`Time`](crate::Time)).

use crate::keys::{Key, RobotTopic};

/// The ROS package of our own message types.
pub const PACKAGE: &str = "ickon_msgs";

/// Every `.msg` file of [`PACKAGE`]: type name and text.
pub const MSG_FILES: &[(&str, &str)] = &[
    ("Arrival", include_str!("../../msg/Arrival.msg")),
    (
        "UltrasoundArrivals",
        include_str!("../../msg/UltrasoundArrivals.msg"),
    ),
    ("Odometry", include_str!("../../msg/Odometry.msg")),
    ("Imu", include_str!("../../msg/Imu.msg")),
    (
        "ObstacleRanges",
        include_str!("../../msg/ObstacleRanges.msg"),
    ),
    ("Fix", include_str!("../../msg/Fix.msg")),
    ("Truth", include_str!("../../msg/Truth.msg")),
    ("SiteInfo", include_str!("../../msg/SiteInfo.msg")),
    ("Emission", include_str!("../../msg/Emission.msg")),
    ("Schedule", include_str!("../../msg/Schedule.msg")),
    ("Firing", include_str!("../../msg/Firing.msg")),
    ("CycleTrigger", include_str!("../../msg/CycleTrigger.msg")),
    ("Burst", include_str!("../../msg/Burst.msg")),
    ("CellStatus", include_str!("../../msg/CellStatus.msg")),
    (
        "AirTemperature",
        include_str!("../../msg/AirTemperature.msg"),
    ),
    ("RouterLink", include_str!("../../msg/RouterLink.msg")),
    ("MsuStatus", include_str!("../../msg/MsuStatus.msg")),
    ("RobotSummary", include_str!("../../msg/RobotSummary.msg")),
    (
        "TransmitterOffset",
        include_str!("../../msg/TransmitterOffset.msg"),
    ),
    (
        "SurveyCalibration",
        include_str!("../../msg/SurveyCalibration.msg"),
    ),
];

/// The full name (`pkg/msg/Type`) of the standard pose type.
pub const POSE_WITH_COVARIANCE_STAMPED: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";

/// REP-2011 type hash of [`POSE_WITH_COVARIANCE_STAMPED`] (ROS 2 Jazzy), for
/// the `topic_type_hash` channel metadata `ros2 bag` reads.
pub const POSE_WITH_COVARIANCE_STAMPED_HASH: &str =
    "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";

/// The standard types the pose depends on, depth first, as rosbag2 lays them
/// out (`MSG:` name without `/msg/`, then the definition).
const POSE_DEPENDENCIES: &[(&str, &str)] = &[
    (
        "std_msgs/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    ),
    ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
    (
        "geometry_msgs/PoseWithCovariance",
        "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
    ),
    (
        "geometry_msgs/Pose",
        "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
    ),
    ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
    (
        "geometry_msgs/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    ),
];

/// The root of `geometry_msgs/msg/PoseWithCovarianceStamped`.
const POSE_ROOT: &str = "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n";

/// The line rosbag2 puts between a schema's definitions.
const SEPARATOR: &str =
    "================================================================================";

/// A ROS 2 message type as an MCAP schema (encoding `ros2msg`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RosSchema {
    /// Full name, `pkg/msg/Type`.
    pub name: String,
    /// The definition with its dependencies, as rosbag2 writes it.
    pub text: String,
}

/// How the messages of a key are stored in a recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Recorded {
    /// The wire bytes as they are, typed as `ickon_msgs/msg/<name>`.
    Own(&'static str),
    /// A [`RobotPose`](crate::msg::robot::RobotPose) converted to
    /// `geometry_msgs/msg/PoseWithCovarianceStamped` in frame `map`.
    Pose,
}

/// How a key's messages are recorded; `None` for keys that carry no
/// recordable stream (queries, liveliness, latency probes).
pub fn recorded_as(key: &Key) -> Option<Recorded> {
    let own = Recorded::Own;
    Some(match key {
        Key::CentralSite => own("SiteInfo"),
        Key::CentralSchedule => own("Schedule"),
        Key::CentralCycle => own("CycleTrigger"),
        Key::CentralSurvey => own("SurveyCalibration"),
        Key::CellBurst(_) => own("Burst"),
        Key::CellStatus(_) => own("CellStatus"),
        Key::CellAir(_) => own("AirTemperature"),
        Key::RobotStatus(_) => own("MsuStatus"),
        Key::RobotSummary(_) => own("RobotSummary"),
        Key::CellLink(_) | Key::RobotLink(_) => own("RouterLink"),
        Key::SimTruth(_) | Key::SimKit(_) => own("Truth"),
        Key::Robot(_, topic) => match topic {
            RobotTopic::Ultrasound => own("UltrasoundArrivals"),
            RobotTopic::Odom => own("Odometry"),
            RobotTopic::Imu => own("Imu"),
            RobotTopic::Range => own("ObstacleRanges"),
            RobotTopic::Fix => own("Fix"),
            RobotTopic::Pose => Recorded::Pose,
        },
        Key::CentralClock
        | Key::CentralAdmin(_)
        | Key::AliveCentral
        | Key::AliveWorld
        | Key::AliveCell(_)
        | Key::AliveRobot(_)
        | Key::SimProbe => return None,
    })
}

impl Recorded {
    /// The schema of this recording type.
    pub fn schema(self) -> RosSchema {
        match self {
            Recorded::Own(name) => own_schema(name).unwrap_or_else(|| RosSchema {
                // Unreachable for the names above (a test checks every one).
                name: format!("{PACKAGE}/msg/{name}"),
                text: String::new(),
            }),
            Recorded::Pose => {
                let mut text = POSE_ROOT.to_string();
                for (name, body) in POSE_DEPENDENCIES {
                    push_dependency(&mut text, name, body);
                }
                RosSchema {
                    name: POSE_WITH_COVARIANCE_STAMPED.to_string(),
                    text,
                }
            }
        }
    }
}

/// The `.msg` text of one of our types.
pub fn msg_file(name: &str) -> Option<&'static str> {
    MSG_FILES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The MCAP schema of our type `name` (`UltrasoundArrivals`, ...): its
/// `.msg` text, then each `ickon_msgs` type it uses, depth first.
pub fn own_schema(name: &str) -> Option<RosSchema> {
    let root = msg_file(name)?;
    let mut text = root.to_string();
    let mut seen = vec![name];
    let mut stack = dependencies(root);
    stack.reverse();
    while let Some(dep) = stack.pop() {
        if seen.contains(&dep) {
            continue;
        }
        seen.push(dep);
        let body = msg_file(dep)?;
        push_dependency(&mut text, &format!("{PACKAGE}/{dep}"), body);
        let mut more = dependencies(body);
        more.reverse();
        stack.extend(more);
    }
    Some(RosSchema {
        name: format!("{PACKAGE}/msg/{name}"),
        text,
    })
}

fn push_dependency(text: &mut String, name: &str, body: &str) {
    if !text.ends_with('\n') {
        text.push('\n');
    }
    text.push_str(SEPARATOR);
    text.push_str("\nMSG: ");
    text.push_str(name);
    text.push('\n');
    text.push_str(body);
}

/// The `ickon_msgs` types a `.msg` text uses as fields, in order.
fn dependencies(text: &'static str) -> Vec<&'static str> {
    text.lines()
        .filter_map(|line| line.split('#').next()?.split_whitespace().next())
        .filter_map(|ty| ty.strip_prefix(PACKAGE)?.strip_prefix('/'))
        .map(|ty| ty.split('[').next().unwrap_or(ty))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dependencies_follow_the_root_once_each_with_rosbag2_separators() {
        let s = own_schema("Schedule").unwrap();
        assert_eq!(s.name, "ickon_msgs/msg/Schedule");
        assert_eq!(s.text.matches("MSG: ickon_msgs/Emission").count(), 1);
        assert!(
            s.text
                .contains(&format!("\n{SEPARATOR}\nMSG: ickon_msgs/Emission\n"))
        );
        let plain = own_schema("Imu").unwrap();
        assert!(!plain.text.contains("MSG:"));
    }

    #[test]
    fn the_pose_schema_carries_every_standard_dependency() {
        let s = Recorded::Pose.schema();
        assert_eq!(s.name, POSE_WITH_COVARIANCE_STAMPED);
        for dep in [
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
        ] {
            assert!(s.text.contains(&format!("MSG: {dep}\n")), "{dep}");
        }
    }
}
