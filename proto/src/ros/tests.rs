//! The conventions against the examples of docs/ros2.md ("The conventions in detail").

use super::keys::split_type_and_hash;
use super::*;
use crate::msg::ros::{PoseWithCovarianceStamped, RosMessage};

const POSE_HASH: &str = "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";

#[test]
fn rmw_zenoh_data_key_matches_the_design_example() {
    let keys = RosKeys::new(Transport::RmwZenoh { domain: 0 });
    let topic = resolve_topic("/r1", "pose").unwrap();
    assert_eq!(topic, "/r1/pose");
    assert_eq!(
        keys.data_key(
            &topic,
            PoseWithCovarianceStamped::TYPE_NAME,
            PoseWithCovarianceStamped::TYPE_HASH
        )
        .unwrap(),
        format!("0/r1/pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/{POSE_HASH}")
    );
    assert_eq!(keys.subscription_key("/r1/odom").unwrap(), "0/r1/odom/*/*");
    assert_eq!(
        split_type_and_hash("0/r1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_ab"),
        Some(("nav_msgs::msg::dds_::Odometry_", "RIHS01_ab"))
    );
}

#[test]
fn bridge_keys_are_the_bare_topic_under_the_bridge_namespace() {
    let plain = RosKeys::new(Transport::Bridge {
        prefix: String::new(),
    });
    assert_eq!(
        plain.data_key("/r1/pose", "a/msg/B", "h").unwrap(),
        "r1/pose"
    );
    assert_eq!(plain.subscription_key("/r1/odom").unwrap(), "r1/odom");
    let prefixed = RosKeys::new(Transport::Bridge {
        prefix: "/robots/".into(),
    });
    assert_eq!(
        prefixed.data_key("/tf", "a/msg/B", "h").unwrap(),
        "robots/tf"
    );
}

#[test]
fn publisher_token_matches_the_design_example() {
    let node = NodeIdentity {
        domain: 0,
        zid: "abc123".into(),
        nid: 0,
        enclave: String::new(),
        namespace: "/r1".into(),
        node: "ickon_msu".into(),
    };
    assert_eq!(
        node.node_token(),
        "@ros2_lv/0/abc123/0/0/NN/%/%r1/ickon_msu"
    );
    let token = node
        .endpoint_token(
            1,
            EndpointKind::Publisher,
            "/r1/pose",
            PoseWithCovarianceStamped::TYPE_NAME,
            POSE_HASH,
            Qos::reliable(10),
        )
        .unwrap();
    assert_eq!(
        token,
        format!(
            "@ros2_lv/0/abc123/0/1/MP/%/%r1/ickon_msu/%r1%pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/{POSE_HASH}/::,10:,:,:,,"
        )
    );
    let root = NodeIdentity {
        namespace: "/".into(),
        ..node
    };
    assert!(root.node_token().ends_with("/NN/%/%/ickon_msu"));
}

#[test]
fn qos_fields_are_left_empty_at_rmw_zenoh_defaults() {
    assert_eq!(Qos::reliable(42).token_string(), "::,:,:,:,,");
    let best_effort_latched = Qos {
        reliable: false,
        transient_local: true,
        depth: 1,
    };
    assert_eq!(best_effort_latched.token_string(), "2:1:,1:,:,:,,");
}

#[test]
fn attachment_is_33_bytes_in_zenoh_ext_layout() {
    let a = Attachment {
        sequence_number: 1,
        source_timestamp_ns: 0x0102_0304_0506_0708,
        gid: [0xAB; 16],
    };
    let b = a.to_bytes();
    assert_eq!(b.len(), 33);
    assert_eq!(&b[0..8], &[1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(&b[8..16], &[8, 7, 6, 5, 4, 3, 2, 1]);
    assert_eq!(b[16], 0x10);
    assert_eq!(&b[17..], &[0xAB; 16]);
    assert_eq!(Attachment::parse(&b), Ok(a));
}

#[test]
fn malformed_attachments_are_refused() {
    let good = SampleStamper::new("x").next(5).to_bytes();
    assert_eq!(
        Attachment::parse(&good[..32]),
        Err(AttachmentError::Length(32))
    );
    assert_eq!(Attachment::parse(&[]), Err(AttachmentError::Length(0)));
    let mut bad = good;
    bad[16] = 15;
    assert_eq!(Attachment::parse(&bad), Err(AttachmentError::GidLength(15)));
}

#[test]
fn stamper_counts_from_one_with_a_stable_gid() {
    let mut s = SampleStamper::new("@ros2_lv/0/z/0/1/MP");
    let a = s.next(10);
    let b = s.next(20);
    assert_eq!((a.sequence_number, b.sequence_number), (1, 2));
    assert_eq!(a.gid, b.gid);
    assert_eq!(a.gid, gid_for("@ros2_lv/0/z/0/1/MP"));
    assert_ne!(a.gid, gid_for("@ros2_lv/0/z/0/2/MP"));
}

#[test]
fn names_resolve_and_bad_names_are_refused() {
    assert_eq!(resolve_topic("/r1", "/tf").unwrap(), "/tf");
    assert_eq!(resolve_topic("/r1", "ickon/fix").unwrap(), "/r1/ickon/fix");
    assert_eq!(resolve_topic("/", "pose").unwrap(), "/pose");
    for bad in ["", "a//b", "a/", "1a", "a b", "~/x", "{node}/x", "/"] {
        assert!(resolve_topic("/r1", bad).is_err(), "{bad:?} accepted");
    }
    for bad in ["", "r1", "/r1/", "/r 1", "/1r"] {
        assert!(validate_namespace(bad).is_err(), "{bad:?} accepted");
    }
    assert!(names::dds_type_name("nav_msgs/Odometry").is_err());
    assert_eq!(
        names::dds_type_name("nav_msgs/msg/Odometry").unwrap(),
        "nav_msgs::msg::dds_::Odometry_"
    );
}
