//! A ROS 2 robot drives an MSU agent with no code of ours: `ickon node msu
//! --ros2` (a separate process, with the central unit) reads
//! `nav_msgs/msg/Odometry` and `sensor_msgs/msg/Imu` whose bytes `rosbags`
//! (PyPI) made, put on the rmw_zenoh keys with the attachment, and its pose
//! (ICKON key and ROS 2 topic) follows them. Bad samples in between
//! (truncated, without attachment, of the wrong type, NaN covariance,
//! stamps going backwards) change nothing and end nothing.

use std::process::Command;
use std::time::Duration;

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::robot::RobotPose;
use ickon_proto::msg::ros::PoseWithCovarianceStamped;
use ickon_proto::ros::SampleStamper;
use ickon_testkit::{ChildGuard, Observer, Rosbags, poll_until};
use serde_json::json;
use support::ICKON;
use zenoh::Wait;

const START_TIMEOUT: Duration = Duration::from_secs(90);
const WAIT: Duration = Duration::from_secs(30);
const ODOM_KEY: &str = "0/r1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0";
const IMU_KEY: &str = "0/r1/imu/sensor_msgs::msg::dds_::Imu_/RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b";
const ROS_POSE_KEY: &str = "0/r1/pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";
/// Odometry samples: 2 s at 50 Hz.
const SAMPLES: usize = 100;
/// Forward speed and turn rate the robot reports.
const V_M_S: f64 = 0.5;
const W_RAD_S: f64 = 0.2;

fn hex_samples(rosbags: &Rosbags, kind: &str, samples: &serde_json::Value) -> Vec<Vec<u8>> {
    let out = rosbags.run(&[kind], &samples.to_string());
    let hex: Vec<String> = serde_json::from_str(&out).expect("hex list");
    hex.iter()
        .map(|h| {
            (0..h.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&h[i..i + 2], 16).expect("hex"))
                .collect()
        })
        .collect()
}

#[test]
fn msu_pose_follows_ros2_odometry_and_imu_made_by_rosbags() {
    let Some(rosbags) = Rosbags::find() else {
        return;
    };
    // The robot's report: an arc from the origin of its odom frame, stamps
    // from 100 s on the robot's clock.
    let t0 = 100.0;
    let (mut odom, mut imu) = (Vec::new(), Vec::new());
    for k in 0..SAMPLES {
        let t = k as f64 * 0.02;
        let yaw = W_RAD_S * t;
        let r = V_M_S / W_RAD_S;
        let stamp = t0 + t;
        let (sec, nanosec) = (stamp.floor() as i64, ((stamp.fract()) * 1e9).round() as i64);
        odom.push(json!({"sec": sec, "nanosec": nanosec, "x": r * yaw.sin(), "y": r * (1.0 - yaw.cos()), "yaw": yaw, "vx": V_M_S, "wz": W_RAD_S}));
        imu.push(json!({"sec": sec, "nanosec": nanosec, "wz": W_RAD_S}));
    }
    let odom_bytes = hex_samples(&rosbags, "odom", &json!(odom));
    let imu_bytes = hex_samples(&rosbags, "imu", &json!(imu));

    let dir = tempfile::tempdir().expect("temp dir");
    let site = format!("ros2-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(dir.path(), &site);
    let central_endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", "central", "--no-multicast-scouting", "--listen"])
        .arg(&central_endpoint)
        .args(["--site-name", &site])
        .arg("--site")
        .arg(&file);
    let _central = ChildGuard::spawn("central", cmd, dir.path()).expect("central starts");
    let mut cmd = Command::new(ICKON);
    cmd.args([
        "node",
        "msu",
        "--robot",
        "r1",
        "--estimator",
        "odometry",
        "--ros2",
        // No fix ever comes here: the start pose carried by odometry.
        "--ros2-unconfirmed-poses",
        "true",
    ])
    .args(["--no-multicast-scouting", "--listen", "tcp/127.0.0.1:0"])
    .args(["--connect", &central_endpoint, "--site-name", &site])
    .arg("--site")
    .arg(&file)
    .env("RUST_LOG", "info");
    let mut msu = ChildGuard::spawn("msu", cmd, dir.path()).expect("msu starts");

    let observer = Observer::open(std::slice::from_ref(&central_endpoint)).expect("observer");
    let keys = Keys::new(&site).expect("keys");
    let poses = observer
        .session()
        .declare_subscriber(keys.robot("r1", RobotTopic::Pose).unwrap())
        .wait()
        .expect("pose subscriber");
    let ros_poses = observer
        .session()
        .declare_subscriber(ROS_POSE_KEY)
        .wait()
        .expect("ROS pose subscriber");
    // The MSU is ready when its ROS 2 odometry subscriber is announced.
    let tokens = observer
        .session()
        .liveliness()
        .declare_subscriber("@ros2_lv/0/**")
        .history(true)
        .wait()
        .expect("tokens");
    poll_until(START_TIMEOUT, "the MSU's odometry subscriber token", || {
        if let Some(status) = msu.exit_status() {
            panic!("msu {status}:\n{}", msu.log());
        }
        while let Ok(Some(s)) = tokens.try_recv() {
            if s.key_expr()
                .as_str()
                .contains("/MS/%/%r1/ickon_msu/%r1%odom/")
            {
                return Some(());
            }
        }
        None
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", msu.log()));
    // Matching takes a moment after the token.
    std::thread::sleep(Duration::from_millis(500));

    let session = observer.session();
    let mut odom_stamper = SampleStamper::new(ODOM_KEY);
    let mut imu_stamper = SampleStamper::new(IMU_KEY);
    let put = |key: &str, bytes: &[u8], stamper: Option<&mut SampleStamper>| {
        let p = session.put(key, bytes.to_vec());
        match stamper {
            Some(s) => p.attachment(s.next(1).to_bytes().to_vec()).wait(),
            None => p.wait(),
        }
        .expect("put")
    };
    for k in 0..SAMPLES {
        put(IMU_KEY, &imu_bytes[k], Some(&mut imu_stamper));
        put(ODOM_KEY, &odom_bytes[k], Some(&mut odom_stamper));
        if k == SAMPLES / 2 {
            // Bad input in the middle: none of it may move the pose.
            let good = &odom_bytes[k];
            put(ODOM_KEY, &good[..good.len() / 2], Some(&mut odom_stamper));
            put(ODOM_KEY, good, None);
            put(ODOM_KEY, &odom_bytes[0], Some(&mut odom_stamper)); // backwards
            let wrong = ODOM_KEY.replace(
                "nav_msgs::msg::dds_::Odometry_",
                "sensor_msgs::msg::dds_::Imu_",
            );
            put(&wrong, &imu_bytes[k], Some(&mut odom_stamper));
            let mut nan = good.clone();
            // The pose covariance starts after header (stamp 8 + frame
            // "odom": 4 + 5, padded), child frame and pose (7 doubles).
            let cov_at = nan.len() - 36 * 8 - 6 * 8 - 36 * 8;
            nan[cov_at..cov_at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
            put(ODOM_KEY, &nan, Some(&mut odom_stamper));
        }
        std::thread::sleep(Duration::from_millis(20));
    }

    // The last pose: the start pose of r1 moved by the reported arc.
    let start = ickon_proto::site::Site::from_toml(ickon_proto::site::DEFAULT_SITE_TOML, "lab")
        .expect("site")
        .robots
        .iter()
        .find(|r| r.id == "r1")
        .expect("r1")
        .start;
    let t_end = (SAMPLES - 1) as f64 * 0.02;
    let (yaw, r) = (W_RAD_S * t_end, V_M_S / W_RAD_S);
    let (dx, dy) = (r * yaw.sin(), r * (1.0 - yaw.cos()));
    let (s, c) = start[2].sin_cos();
    let want = [
        start[0] + c * dx - s * dy,
        start[1] + s * dx + c * dy,
        start[2] + yaw,
    ];
    let last: RobotPose = poll_until(WAIT, "the pose at the end of the arc", || {
        let mut last = None;
        while let Ok(Some(s)) = poses.try_recv() {
            last = Some(ickon_proto::decode::<RobotPose>(&s.payload().to_bytes()).expect("pose"));
        }
        last.filter(|p| (p.stamp.as_secs_f64() - (t0 + t_end)).abs() < 1e-6)
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", msu.log()));
    let err_m = (last.x_m - want[0]).hypot(last.y_m - want[1]);
    assert!(
        err_m < 0.01,
        "pose {last:?}, expected {want:?} ({err_m} m off)\n{}",
        msu.log()
    );
    let dth = (last.theta_rad - want[2])
        .sin()
        .atan2((last.theta_rad - want[2]).cos());
    assert!(
        dth.abs() < 0.01,
        "heading {} expected {}",
        last.theta_rad,
        want[2]
    );

    // The same pose on ROS 2.
    let mut ros_last = None;
    while let Ok(Some(s)) = ros_poses.try_recv() {
        assert_eq!(s.attachment().map(|a| a.len()), Some(33));
        ros_last = Some(
            ickon_proto::decode::<PoseWithCovarianceStamped>(&s.payload().to_bytes())
                .expect("ROS pose"),
        );
    }
    let ros_last = ros_last.expect("poses on ROS 2");
    assert!((ros_last.pose.pose.position.x - last.x_m).abs() < 1e-9);
    assert_eq!(ros_last.header.frame_id, "map");
    assert!(ros_last.pose.covariance.iter().all(|v| v.is_finite()));

    // The bad input was seen, counted and survived.
    assert!(msu.exit_status().is_none(), "msu died:\n{}", msu.log());
    let log = msu.log();
    for what in [
        "undecodable CDR",
        "without the rmw_zenoh attachment",
        "stamp going backwards",
        "wrong message type",
        "NaN or infinite",
    ] {
        assert!(log.contains(what), "no report of {what:?}:\n{log}");
    }
}
