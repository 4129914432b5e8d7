//! What a Zenoh key becomes in a recording: its ROS topic, its schema, the
//! bytes stored (the wire bytes, or the pose as a standard ROS type), and
//! the message's own event time (the MCAP publish time).

use std::collections::BTreeMap;

use ickon_proto::keys::{Key, Keys, RobotTopic};
use ickon_proto::msg::control::{
    AirTemperature, Burst, CellStatus, CycleTrigger, Schedule, SiteInfo, SurveyCalibration,
};
use ickon_proto::msg::robot::{
    Fix, Imu, MsuStatus, ObstacleRanges, Odometry, RobotPose, RobotSummary, Truth,
    UltrasoundArrivals,
};
use ickon_proto::msg::ros::PoseWithCovarianceStamped;
use ickon_proto::msg::ros_msgs::{POSE_WITH_COVARIANCE_STAMPED_HASH, Recorded, recorded_as};
use ickon_proto::{DecodeError, EncodeError, Time, decode, encode};

/// The frame of every recorded pose (REP-105's fixed world frame).
pub const POSE_FRAME: &str = "map";

/// The QoS rosbag2 records for a reliable, volatile publisher (keep last 10),
/// as the `offered_qos_profiles` YAML `ros2 bag play` reads.
pub const OFFERED_QOS: &str = "- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n";

/// The ROS topic of a key: the key with a leading `/`
/// (`ickon/lab/robot/r1/pose` -> `/ickon/lab/robot/r1/pose`).
pub fn topic_of(key: &str) -> String {
    format!("/{key}")
}

/// The key of a ROS topic written by [`topic_of`].
pub fn key_of(topic: &str) -> &str {
    topic.strip_prefix('/').unwrap_or(topic)
}

/// How one key is recorded.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The parsed key.
    pub key: Key,
    /// How its messages are stored.
    pub recorded: Recorded,
}

/// Why one message was not recorded.
#[derive(Debug, thiserror::Error)]
pub enum Unrecordable {
    /// The payload is not a message of the key's type.
    #[error(transparent)]
    Undecodable(#[from] DecodeError),
    /// The converted message could not be encoded.
    #[error(transparent)]
    Unencodable(#[from] EncodeError),
}

/// How `key` is recorded; `None` for keys of no stream or not of this site.
pub fn plan(keys: &Keys, key: &str) -> Option<Plan> {
    let parsed = keys.parse(key).ok()?;
    let recorded = recorded_as(&parsed)?;
    Some(Plan {
        key: parsed,
        recorded,
    })
}

/// The channel metadata of a key's channel.
pub fn channel_metadata(key: &str, plan: &Plan) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    m.insert("offered_qos_profiles".into(), OFFERED_QOS.into());
    if plan.recorded == Recorded::Pose {
        m.insert(
            "topic_type_hash".into(),
            POSE_WITH_COVARIANCE_STAMPED_HASH.into(),
        );
    }
    m.insert("ickon_key".into(), key.into());
    m
}

/// A message ready to store: its bytes and its event time.
#[derive(Debug, Clone, PartialEq)]
pub struct Stored {
    /// The CDR bytes stored in the recording.
    pub data: Vec<u8>,
    /// The time of the event the message describes (its own stamp), or
    /// `None` for messages without one (the site, the schedule).
    pub event_time: Option<Time>,
}

/// Checks a payload against its key's type and returns what to store.
pub fn prepare(plan: &Plan, payload: &[u8]) -> Result<Stored, Unrecordable> {
    let own = |event_time: Option<Time>| Stored {
        data: payload.to_vec(),
        event_time,
    };
    Ok(match &plan.key {
        Key::CentralSite => {
            decode::<SiteInfo>(payload)?;
            own(None)
        }
        Key::CentralSchedule => {
            decode::<Schedule>(payload)?;
            own(None)
        }
        Key::CentralCycle => own(Some(decode::<CycleTrigger>(payload)?.start)),
        // Stored in the current layout, which the channel's schema
        // describes, also when a central unit of an older release sent the
        // layout before lateness.
        Key::CentralSurvey => Stored {
            data: encode(&SurveyCalibration::decode(payload)?)?,
            event_time: None,
        },
        Key::CellBurst(_) => own(Some(decode::<Burst>(payload)?.actual)),
        Key::CellStatus(_) => own(Some(decode::<CellStatus>(payload)?.stamp)),
        Key::CellAir(_) => own(Some(decode::<AirTemperature>(payload)?.stamp)),
        Key::RobotStatus(_) => own(Some(decode::<MsuStatus>(payload)?.stamp)),
        // An older MSU's layout is stored in the current one (the
        // channel's schema).
        Key::RobotSummary(_) => {
            let summary = RobotSummary::decode(payload)?;
            Stored {
                data: encode(&summary)?,
                event_time: Some(summary.stamp),
            }
        }
        // No master-time stamp: recorded at its receive time.
        Key::CellLink(_) | Key::RobotLink(_) => {
            decode::<ickon_proto::msg::control::RouterLink>(payload)?;
            own(None)
        }
        Key::SimTruth(_) | Key::SimKit(_) => own(Some(decode::<Truth>(payload)?.stamp)),
        Key::Robot(_, topic) => match topic {
            RobotTopic::Ultrasound => {
                // The cycle's event: its last arrival (the message cannot be
                // made before it).
                let m = decode::<UltrasoundArrivals>(payload)?;
                own(m.arrivals.iter().map(|a| a.t_arrival).max())
            }
            RobotTopic::Odom => own(Some(decode::<Odometry>(payload)?.stamp)),
            RobotTopic::Imu => own(Some(decode::<Imu>(payload)?.stamp)),
            RobotTopic::Range => own(Some(decode::<ObstacleRanges>(payload)?.stamp)),
            RobotTopic::Fix => {
                let fix = Fix::decode(payload)?;
                Stored {
                    data: encode(&fix)?,
                    event_time: Some(fix.stamp),
                }
            }
            RobotTopic::Pose => {
                let pose = decode::<RobotPose>(payload)?;
                Stored {
                    data: encode(&PoseWithCovarianceStamped::from_robot_pose(
                        &pose, POSE_FRAME,
                    ))?,
                    event_time: Some(pose.stamp),
                }
            }
        },
        // `plan` returns no plan for the other keys.
        _ => own(None),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_streams_of_the_site_are_planned() {
        let keys = Keys::new("lab").unwrap();
        assert!(plan(&keys, "ickon/lab/robot/r1/odom").is_some());
        assert!(plan(&keys, "ickon/lab/cell/c1/burst").is_some());
        for none in [
            "ickon/lab/sim/probe",
            "ickon/lab/central/clock",
            "ickon/other/robot/r1/odom",
            "ickon/lab/robot/r1/bogus",
            "something/else",
        ] {
            assert!(plan(&keys, none).is_none(), "{none}");
        }
    }

    #[test]
    fn a_pose_is_stored_as_the_standard_ros_type_with_its_own_stamp() {
        let keys = Keys::new("lab").unwrap();
        let p = plan(&keys, "ickon/lab/robot/r1/pose").unwrap();
        let pose = RobotPose {
            stamp: Time::from_nanos(1_700_000_000_500_000_000),
            x_m: 1.0,
            y_m: 2.0,
            theta_rad: 0.5,
            covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
            estimator: "tdoa-ekf".into(),
            fix_seq: 3,
            status: ickon_proto::msg::robot::PoseStatus::Tracking,
        };
        let stored = prepare(&p, &encode(&pose).unwrap()).unwrap();
        assert_eq!(stored.event_time, Some(pose.stamp));
        let ros: PoseWithCovarianceStamped = decode(&stored.data).unwrap();
        assert_eq!(ros.pose.pose.position.x, 1.0);
        assert_eq!(ros.header.frame_id, "map");
        assert_eq!(ros.header.stamp.sec, 1_700_000_000);
    }

    #[test]
    fn garbage_truncated_and_wrong_type_payloads_are_refused() {
        let keys = Keys::new("lab").unwrap();
        let p = plan(&keys, "ickon/lab/robot/r1/imu").unwrap();
        let good = encode(&Imu {
            stamp: Time::from_nanos(5),
            gyro_z_rad_s: 0.1,
        })
        .unwrap();
        assert!(prepare(&p, &good).is_ok());
        assert!(prepare(&p, &good[..good.len() - 1]).is_err());
        assert!(prepare(&p, &[]).is_err());
        assert!(prepare(&p, &[0xff; 64]).is_err());
        let schedule_bytes = encode(&CycleTrigger {
            cycle: 1,
            start: Time::from_nanos(9),
            schedule_version: 1,
            epoch: 1,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        })
        .unwrap();
        assert!(prepare(&p, &schedule_bytes).is_err());
    }

    #[test]
    fn a_fix_of_the_layout_before_unused_arrivals_is_stored_in_the_current_one() {
        // What an MSU sent before a fix carried its unused arrivals; the
        // channel's schema is the current layout.
        use ickon_proto::msg::robot::fix_before_unused::FixWithoutUnused;
        let old = encode(&FixWithoutUnused {
            stamp: Time::from_nanos(5_000_000_000),
            arrivals_seq: 12,
            x_m: 1.0,
            y_m: 2.0,
            z_m: 0.3,
            covariance: [0.0; 9],
            heading_rad: 0.0,
            heading_valid: false,
            used: vec![1, 2, 3],
            rejected: vec![4],
            residuals_m: vec![0.0; 3],
            quality: ickon_proto::msg::robot::FixQuality::Minimal,
            survey_version: 3,
        })
        .unwrap();
        let keys = Keys::new("lab").unwrap();
        let p = plan(&keys, "ickon/lab/robot/r1/fix").unwrap();
        let stored = prepare(&p, &old).unwrap();
        let read: Fix = decode(&stored.data).unwrap();
        assert_eq!((read.arrivals_seq, read.rejected.clone()), (12, vec![4]));
        assert!(read.unused.is_empty());
        assert_eq!(stored.event_time, Some(Time::from_nanos(5_000_000_000)));
    }

    #[test]
    fn a_calibration_of_the_layout_before_lateness_is_stored_in_the_current_one() {
        // What a central unit sent before transmitters carried their
        // lateness; the channel's schema is the current layout.
        use ickon_proto::msg::control::survey_before_lateness::{
            CalibrationWithoutLateness, OffsetWithoutLateness,
        };
        let old = encode(&CalibrationWithoutLateness {
            epoch: 2,
            version: 5,
            fixes_taken: 640,
            offsets: vec![OffsetWithoutLateness {
                tx_id: 4,
                offset_m: [0.01, 0.0, -0.02],
                sigma_m: [0.003; 3],
            }],
        })
        .unwrap();
        let keys = Keys::new("lab").unwrap();
        let p = plan(&keys, "ickon/lab/central/survey").unwrap();
        let stored = prepare(&p, &old).unwrap();
        let read: SurveyCalibration = decode(&stored.data).unwrap();
        assert_eq!((read.version, read.offsets[0].tx_id), (5, 4));
        assert_eq!(read.offsets[0].offset_m, [0.01, 0.0, -0.02]);
        assert_eq!(read.offsets[0].late_m, 0.0);
        let current = encode(&read).unwrap();
        assert_eq!(prepare(&p, &current).unwrap().data, current);
        assert!(prepare(&p, &old[..old.len() - 4]).is_err());
    }
}
