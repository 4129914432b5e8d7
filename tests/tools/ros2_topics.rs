//! What the MSU agent's ROS 2 side puts on Zenoh, read back by a session of
//! the test and checked against docs/ros2.md: the rmw_zenoh data keys
//! (domain, type, RIHS01 hash), the 33-byte attachment on every sample, the
//! liveliness tokens of the node and of each publisher and subscriber; and
//! every payload decoded by `rosbags` (PyPI), an implementation of ROS 2
//! CDR independent of ours. The bridge mode's keys carry no attachment.

use std::collections::BTreeSet;
use std::time::Duration;

use ickon_fusion::estimator::WheelGeometry;
use ickon_msu::ros2::{Ros2Link, Ros2Mode, Ros2Options, Ros2Plan};
use ickon_proto::msg::robot::{Fix, FixQuality, Odometry, RobotPose};
use ickon_proto::ros::Attachment;
use ickon_proto::time::Time;
use ickon_testkit::{Observer, Rosbags, poll_until};
use serde_json::Value;
use zenoh::Wait;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

const WAIT: Duration = Duration::from_secs(20);
const POSE_KEY: &str = "0/r1/pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";
const FIX_KEY: &str = "0/r1/ickon/fix/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";
const TF_KEY: &str = "0/tf/tf2_msgs::msg::dds_::TFMessage_/RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087";
const POSE_TYPE: &str = "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";

const WHEELS: WheelGeometry = WheelGeometry {
    wheel_base_m: 0.33,
    left_m_per_tick: 1e-4,
    right_m_per_tick: 1e-4,
};

fn pose() -> RobotPose {
    RobotPose {
        stamp: Time::from_nanos(12_250_000_000),
        x_m: 3.25,
        y_m: -1.5,
        theta_rad: 0.75,
        covariance: [4e-4, 1e-5, 0.0, 1e-5, 9e-4, 0.0, 0.0, 0.0, 2e-3],
        estimator: "tdoa-ekf".into(),
        fix_seq: 7,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    }
}

fn fix() -> Fix {
    Fix {
        stamp: Time::from_nanos(12_200_000_000),
        arrivals_seq: 7,
        x_m: 3.2,
        y_m: -1.45,
        z_m: 0.3,
        covariance: [1e-3, 0.0, 0.0, 0.0, 2e-3, 0.0, 0.0, 0.0, 0.0],
        heading_rad: 0.5,
        heading_valid: true,
        used: vec![1, 2, 3, 4],
        rejected: vec![],
        residuals_m: vec![0.0; 4],
        quality: FixQuality::Good,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    }
}

/// Publishes one pose (with odometry noted, so `map -> odom` goes too) and
/// one fix through a link of `options` on `session`.
fn publish_once(session: &zenoh::Session, options: &Ros2Options) {
    let plan = Ros2Plan::new(options, "r1", None).expect("plan");
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(async {
        let mut link = Ros2Link::open(session, plan, WHEELS).await.expect("link");
        // Let the subscriber of the test meet the publishers.
        tokio::time::sleep(Duration::from_millis(500)).await;
        link.note_odometry(&Odometry {
            stamp: Time::from_nanos(12_000_000_000),
            x_m: 1.0,
            y_m: 0.5,
            theta_rad: 0.25,
            left_ticks: 0,
            right_ticks: 0,
        });
        // A pose no fix has confirmed (a restarted MSU's start pose) is
        // held back: neither it nor its transform goes out.
        let guess = RobotPose {
            status: ickon_proto::msg::robot::PoseStatus::Localising,
            x_m: 9.0,
            ..pose()
        };
        link.publish_pose(&guess, true).await;
        link.publish_pose(&pose(), true).await;
        link.publish_fix(&fix()).await;
        // Keep the tokens alive while the test looks at them.
        tokio::time::sleep(Duration::from_millis(1500)).await;
        assert_eq!(link.counters().published, 3, "{:?}", link.counters());
        assert_eq!(link.counters().withheld_localising, 1);
    });
}

/// Waits until `observer` sees a token of `node`: the two sessions are
/// connected and the observer's subscribers are known to the node.
fn wait_connected(observer: &Observer, node: &Observer) {
    let probe = "ickon_test/probe";
    let seen = observer
        .session()
        .liveliness()
        .declare_subscriber(probe)
        .history(true)
        .wait()
        .expect("probe subscriber");
    let _token = node
        .session()
        .liveliness()
        .declare_token(probe)
        .wait()
        .expect("probe token");
    poll_until(WAIT, "the two sessions to connect", || {
        seen.try_recv().ok().flatten().map(|_| ())
    })
    .expect("sessions connect");
}

fn collect(sub: &Subscriber<FifoChannelHandler<Sample>>, n: usize) -> Vec<Sample> {
    let mut got = Vec::new();
    poll_until(WAIT, "the ROS 2 samples", || {
        while let Ok(Some(s)) = sub.try_recv() {
            got.push(s);
        }
        (got.len() >= n).then_some(())
    })
    .expect("samples");
    got
}

fn decode(rosbags: &Rosbags, type_name: &str, payload: &[u8]) -> Value {
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("msg.cdr");
    std::fs::write(&file, payload).expect("write payload");
    let out = rosbags.run(&["decode", type_name, file.to_str().unwrap()], "");
    let doc: Value = serde_json::from_str(&out).expect("JSON from rosbags");
    doc["messages"][0].clone()
}

fn close(a: &Value, b: f64) -> bool {
    a.as_f64().is_some_and(|a| (a - b).abs() < 1e-9)
}

#[test]
fn rmw_zenoh_keys_attachments_tokens_and_payloads_are_what_ros2_expects() {
    let Some(rosbags) = Rosbags::find() else {
        return;
    };
    let observer = Observer::open(&[]).expect("observer");
    let node = Observer::open(&[observer.endpoint().to_string()]).expect("node session");
    let data = observer
        .session()
        .declare_subscriber("0/**")
        .wait()
        .expect("data subscriber");
    let tokens = observer
        .session()
        .liveliness()
        .declare_subscriber("@ros2_lv/**")
        .history(true)
        .wait()
        .expect("token subscriber");
    let options = Ros2Options {
        enabled: true,
        ..Ros2Options::default()
    };
    wait_connected(&observer, &node);
    publish_once(node.session(), &options);

    // Tokens: the node, three publishers, two subscribers (docs/ros2.md).
    let zid = node.session().zid().to_string();
    let mut seen = BTreeSet::new();
    while let Ok(Some(s)) = tokens.try_recv() {
        seen.insert(s.key_expr().as_str().to_string());
    }
    let p = format!("@ros2_lv/0/{zid}/0");
    let expected: BTreeSet<String> = [
        format!("{p}/0/NN/%/%r1/ickon_msu"),
        format!("{p}/1/MP/%/%r1/ickon_msu/%r1%pose/{POSE_TYPE}/::,10:,:,:,,"),
        format!("{p}/2/MP/%/%r1/ickon_msu/%r1%ickon%fix/{POSE_TYPE}/::,10:,:,:,,"),
        format!("{p}/3/MP/%/%r1/ickon_msu/%tf/tf2_msgs::msg::dds_::TFMessage_/RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087/::,100:,:,:,,"),
        format!("{p}/4/MS/%/%r1/ickon_msu/%r1%odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0/::,10:,:,:,,"),
        format!("{p}/5/MS/%/%r1/ickon_msu/%r1%imu/sensor_msgs::msg::dds_::Imu_/RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b/::,10:,:,:,,"),
    ]
    .into_iter()
    .collect();
    assert_eq!(seen, expected);

    let samples = collect(&data, 3);
    let by_key = |k: &str| {
        samples
            .iter()
            .find(|s| s.key_expr().as_str() == k)
            .unwrap_or_else(|| {
                let keys: Vec<_> = samples.iter().map(|s| s.key_expr().to_string()).collect();
                panic!("nothing on {k}; got {keys:?}")
            })
    };
    let mut gids = BTreeSet::new();
    for s in &samples {
        let a = s
            .attachment()
            .expect("every sample has the attachment")
            .to_bytes();
        assert_eq!(a.len(), 33, "{}", s.key_expr());
        assert_eq!(a[16], 0x10);
        let a = Attachment::parse(&a).expect("attachment");
        assert_eq!(a.sequence_number, 1, "first sample of each publisher");
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos() as i64;
        assert!((now_ns - a.source_timestamp_ns).abs() < 60_000_000_000);
        gids.insert(a.gid);
    }
    assert_eq!(gids.len(), 3, "one GID per publisher");

    // The pose, decoded by rosbags.
    let pose_msg = decode(
        &rosbags,
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        &by_key(POSE_KEY).payload().to_bytes(),
    );
    assert_eq!(pose_msg["header"]["frame_id"], "map");
    assert_eq!(pose_msg["header"]["stamp"]["sec"], 12);
    assert_eq!(pose_msg["header"]["stamp"]["nanosec"], 250_000_000);
    let pp = &pose_msg["pose"]["pose"];
    assert!(close(&pp["position"]["x"], 3.25) && close(&pp["position"]["y"], -1.5));
    assert!(close(&pp["orientation"]["z"], (0.375f64).sin()));
    assert!(close(&pp["orientation"]["w"], (0.375f64).cos()));
    let cov = pose_msg["pose"]["covariance"]
        .as_array()
        .expect("covariance");
    assert_eq!(cov.len(), 36);
    for (i, v) in [
        (0, 4e-4),
        (1, 1e-5),
        (5, 0.0),
        (6, 1e-5),
        (7, 9e-4),
        (35, 2e-3),
        (14, 1e6),
    ] {
        assert!(close(&cov[i], v), "covariance[{i}] = {}", cov[i]);
    }

    // The fix.
    let fix_msg = decode(
        &rosbags,
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        &by_key(FIX_KEY).payload().to_bytes(),
    );
    assert!(close(&fix_msg["pose"]["pose"]["position"]["z"], 0.3));
    assert!(close(&fix_msg["pose"]["covariance"][7], 2e-3));

    // map -> odom: composed with the odometry, it gives the pose.
    let tf = decode(
        &rosbags,
        "tf2_msgs/msg/TFMessage",
        &by_key(TF_KEY).payload().to_bytes(),
    );
    let t = &tf["transforms"][0];
    assert_eq!(t["header"]["frame_id"], "map");
    assert_eq!(t["child_frame_id"], "odom");
    assert_eq!(t["header"]["stamp"]["sec"], 13, "stamped ahead by 1 s");
    let (tx, ty) = (
        t["transform"]["translation"]["x"].as_f64().unwrap(),
        t["transform"]["translation"]["y"].as_f64().unwrap(),
    );
    let (qz, qw) = (
        t["transform"]["rotation"]["z"].as_f64().unwrap(),
        t["transform"]["rotation"]["w"].as_f64().unwrap(),
    );
    let th = 2.0 * qz.atan2(qw);
    assert!((th - 0.5).abs() < 1e-9, "map->odom yaw {th}");
    let (s, c) = th.sin_cos();
    assert!((tx + c * 1.0 - s * 0.5 - 3.25).abs() < 1e-9);
    assert!((ty + s * 1.0 + c * 0.5 + 1.5).abs() < 1e-9);
}

#[test]
fn bridge_mode_publishes_on_the_bare_topic_without_attachment_or_tokens() {
    let Some(rosbags) = Rosbags::find() else {
        return;
    };
    let observer = Observer::open(&[]).expect("observer");
    let node = Observer::open(&[observer.endpoint().to_string()]).expect("node session");
    let data = observer
        .session()
        .declare_subscriber("**")
        .wait()
        .expect("data subscriber");
    let tokens = observer
        .session()
        .liveliness()
        .declare_subscriber("@ros2_lv/**")
        .history(true)
        .wait()
        .expect("token subscriber");
    let options = Ros2Options {
        enabled: true,
        mode: Ros2Mode::Bridge,
        ..Ros2Options::default()
    };
    wait_connected(&observer, &node);
    publish_once(node.session(), &options);
    let samples = collect(&data, 3);
    let keys: BTreeSet<&str> = samples.iter().map(|s| s.key_expr().as_str()).collect();
    assert_eq!(keys, BTreeSet::from(["r1/pose", "r1/ickon/fix", "tf"]));
    assert!(samples.iter().all(|s| s.attachment().is_none()));
    assert!(matches!(tokens.try_recv(), Ok(None)), "no rmw_zenoh tokens");
    let pose = samples
        .iter()
        .find(|s| s.key_expr().as_str() == "r1/pose")
        .unwrap();
    let msg = decode(
        &rosbags,
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        &pose.payload().to_bytes(),
    );
    assert!(close(&msg["pose"]["pose"]["position"]["x"], 3.25));
}
