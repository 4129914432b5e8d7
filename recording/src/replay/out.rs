//! `ickon replay mcap --out FILE`: the replayed poses as an MCAP file of the
//! ROS 2 profile, one `geometry_msgs/msg/PoseWithCovarianceStamped` channel
//! per robot and estimator (`/ickon/<site>/replay/<estimator>/robot/<id>/pose`),
//! each pose at the receive time of the input that made it (log time) and its
//! own stamp (publish time): opened beside the recording in Foxglove, the
//! replayed tracks line up with the recorded ones.

use std::collections::BTreeMap;
use std::path::Path;

use ickon_proto::msg::ros_msgs::Recorded;
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions};

use super::feed::{Published, pose_bytes};
use crate::record::channels::OFFERED_QOS;
use crate::record::create_output;
use ickon_proto::msg::ros_msgs::POSE_WITH_COVARIANCE_STAMPED_HASH;

/// Writes every track (robot, estimator, poses) into `path`.
pub fn write(path: &Path, site: &str, tracks: &[(&str, &str, &[Published])]) -> Result<(), String> {
    let fail = |e: mcap::McapError| format!("cannot write {}: {e}", path.display());
    let out = create_output(path)?;
    let mut w = WriteOptions::new()
        .profile("ros2")
        .compression(Some(Compression::Zstd))
        .create(out)
        .map_err(fail)?;
    let schema = Recorded::Pose.schema();
    let schema_id = w
        .add_schema(&schema.name, "ros2msg", schema.text.as_bytes())
        .map_err(fail)?;
    let metadata = BTreeMap::from([
        ("offered_qos_profiles".to_string(), OFFERED_QOS.to_string()),
        (
            "topic_type_hash".to_string(),
            POSE_WITH_COVARIANCE_STAMPED_HASH.to_string(),
        ),
    ]);
    for (robot, estimator, poses) in tracks {
        let topic = format!("/ickon/{site}/replay/{estimator}/robot/{robot}/pose");
        let channel_id = w
            .add_channel(schema_id, &topic, "cdr", &metadata)
            .map_err(fail)?;
        for (k, p) in poses.iter().enumerate() {
            w.write_to_known_channel(
                &MessageHeader {
                    channel_id,
                    sequence: k as u32 + 1,
                    log_time: p.log_time_ns,
                    publish_time: p.pose.stamp.as_nanos().max(0) as u64,
                },
                &pose_bytes(&p.pose),
            )
            .map_err(fail)?;
        }
    }
    w.finish().map_err(fail)?;
    let file = w
        .into_inner()
        .into_inner()
        .map_err(|e| format!("cannot write {}: {}", path.display(), e.error()))?;
    file.sync_all()
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}
