//! The pure parts of the ROS 2 side: inputs from ROS samples, bad input,
//! the published messages, the plan's names, keys and tokens.

use ickon_fusion::estimator::WheelGeometry;
use ickon_proto::encode;
use ickon_proto::msg::robot::{Fix, FixQuality, Odometry, RobotPose};
use ickon_proto::msg::ros::{self, RosMessage};
use ickon_proto::ros::{RosKeys, SampleStamper, Transport};
use ickon_proto::time::Time;

use super::bad_input::BadInputKind;
use super::inputs::{InputDecoder, InputTopic, Ros2Input};
use super::options::{Ros2Mode, Ros2Options};
use super::outputs::{OdomHistory, fix_message, map_to_odom, pose_message, tf_message};
use super::plan::Ros2Plan;

const WHEELS: WheelGeometry = WheelGeometry {
    wheel_base_m: 0.33,
    left_m_per_tick: 1e-4,
    right_m_per_tick: 1e-4,
};

fn rmw() -> RosKeys {
    RosKeys::new(Transport::RmwZenoh { domain: 0 })
}

fn odom_key() -> String {
    rmw()
        .data_key(
            "/r1/odom",
            ros::Odometry::TYPE_NAME,
            ros::Odometry::TYPE_HASH,
        )
        .unwrap()
}

fn attachment() -> Vec<u8> {
    SampleStamper::new("test").next(1).to_bytes().to_vec()
}

fn ros_odom(t_s: f64, pose: [f64; 3]) -> ros::Odometry {
    ros::Odometry::planar(
        Time::from_secs_f64(t_s),
        "odom",
        "base_link",
        pose,
        [0.0, 0.0],
        [1e-3; 3],
        [1e-4; 2],
    )
}

/// Dead reckoning from ticks as the simulated robots do it (midpoint arc).
fn integrate(ticks: &[(i64, i64)]) -> Vec<[f64; 3]> {
    let mut p = [1.0, 2.0, 0.3];
    let mut out = vec![p];
    for w in ticks.windows(2) {
        let dl = (w[1].0 - w[0].0) as f64 * WHEELS.left_m_per_tick;
        let dr = (w[1].1 - w[0].1) as f64 * WHEELS.right_m_per_tick;
        let dth = (dr - dl) / WHEELS.wheel_base_m;
        let mid = p[2] + 0.5 * dth;
        p[0] += 0.5 * (dl + dr) * mid.cos();
        p[1] += 0.5 * (dl + dr) * mid.sin();
        p[2] += dth;
        out.push(p);
    }
    out
}

#[test]
fn odometry_from_ticks_comes_back_as_the_same_ticks() {
    // Straight, turning on the spot, arcs both ways, reversing, across +-pi.
    let mut ticks = vec![(0i64, 0i64)];
    let steps = [
        (50, 50),
        (-30, 30),
        (80, 20),
        (10, 70),
        (-40, -40),
        (200, -200),
    ];
    for k in 0..400 {
        let (l, r) = steps[k % steps.len()];
        let last = *ticks.last().unwrap();
        ticks.push((last.0 + l, last.1 + r));
    }
    let poses = integrate(&ticks);
    let mut dec = InputDecoder::new(rmw(), WHEELS);
    for (k, p) in poses.iter().enumerate() {
        let bytes = encode(&ros_odom(k as f64 * 0.02, *p)).unwrap();
        let got = dec
            .decode(InputTopic::Odom, &odom_key(), &bytes, Some(&attachment()))
            .unwrap();
        let Ros2Input::Odometry(o) = got else {
            panic!("not odometry")
        };
        assert_eq!((o.left_ticks, o.right_ticks), ticks[k], "sample {k}");
        assert!(
            (o.theta_rad - p[2]).abs() < 1e-9,
            "unwrapped heading at {k}"
        );
        assert_eq!(o.stamp, Time::from_secs_f64(k as f64 * 0.02));
    }
}

#[test]
fn imu_z_rate_is_the_gyro() {
    let mut dec = InputDecoder::new(rmw(), WHEELS);
    let key = rmw()
        .data_key("/r1/imu", ros::Imu::TYPE_NAME, ros::Imu::TYPE_HASH)
        .unwrap();
    let msg = ros::Imu::from_gyro_z(Time::from_secs_f64(3.5), "imu", -0.25, 1e-5);
    let got = dec
        .decode(
            InputTopic::Imu,
            &key,
            &encode(&msg).unwrap(),
            Some(&attachment()),
        )
        .unwrap();
    assert_eq!(
        got,
        Ros2Input::Imu(ickon_proto::msg::robot::Imu {
            stamp: Time::from_secs_f64(3.5),
            gyro_z_rad_s: -0.25
        })
    );
}

#[test]
fn bad_samples_are_refused_by_kind() {
    let mut dec = InputDecoder::new(rmw(), WHEELS);
    let good = encode(&ros_odom(1.0, [0.0, 0.0, 0.0])).unwrap();
    let a = attachment();
    let key = odom_key();
    // Truncated CDR, at every length.
    for n in 0..good.len() {
        assert_eq!(
            dec.decode(InputTopic::Odom, &key, &good[..n], Some(&a)),
            Err(BadInputKind::Undecodable),
            "length {n}"
        );
    }
    // Garbage and trailing bytes.
    let mut long = good.clone();
    long.push(0);
    assert_eq!(
        dec.decode(InputTopic::Odom, &key, &long, Some(&a)),
        Err(BadInputKind::Undecodable)
    );
    // A huge sequence length in a TFMessage-shaped payload on the odom key.
    let huge = [0u8, 1, 0, 0, 0xff, 0xff, 0xff, 0xff];
    assert!(dec.decode(InputTopic::Odom, &key, &huge, Some(&a)).is_err());
    // Wrong type on the key, wrong hash, no type at all.
    let imu_key = rmw()
        .data_key("/r1/odom", ros::Imu::TYPE_NAME, ros::Imu::TYPE_HASH)
        .unwrap();
    assert_eq!(
        dec.decode(InputTopic::Odom, &imu_key, &good, Some(&a)),
        Err(BadInputKind::WrongType)
    );
    let bad_hash = key.replace("RIHS01_3c", "RIHS01_00");
    assert_eq!(
        dec.decode(InputTopic::Odom, &bad_hash, &good, Some(&a)),
        Err(BadInputKind::WrongType)
    );
    assert_eq!(
        dec.decode(InputTopic::Odom, "r1", &good, Some(&a)),
        Err(BadInputKind::WrongType)
    );
    // Attachment missing or malformed.
    assert_eq!(
        dec.decode(InputTopic::Odom, &key, &good, None),
        Err(BadInputKind::NoAttachment)
    );
    assert_eq!(
        dec.decode(InputTopic::Odom, &key, &good, Some(&a[..20])),
        Err(BadInputKind::BadAttachment)
    );
    // NaN in the covariance, in the pose; a zero quaternion.
    let mut nan_cov = ros_odom(1.0, [0.0, 0.0, 0.0]);
    nan_cov.pose.covariance[7] = f64::NAN;
    assert_eq!(dec.odometry(&nan_cov), Err(BadInputKind::NonFinite));
    let mut inf_pose = ros_odom(1.0, [0.0, 0.0, 0.0]);
    inf_pose.pose.pose.position.x = f64::INFINITY;
    assert_eq!(dec.odometry(&inf_pose), Err(BadInputKind::NonFinite));
    let mut zero_q = ros_odom(1.0, [0.0, 0.0, 0.0]);
    zero_q.pose.pose.orientation.w = 0.0;
    assert_eq!(dec.odometry(&zero_q), Err(BadInputKind::NonFinite));
    let mut nan_imu = ros::Imu::from_gyro_z(Time::from_secs_f64(1.0), "imu", 0.1, 1e-5);
    nan_imu.angular_velocity_covariance[4] = f64::NAN;
    assert_eq!(dec.imu(&nan_imu), Err(BadInputKind::NonFinite));
    // Malformed stamp.
    let mut bad_stamp = ros_odom(1.0, [0.0, 0.0, 0.0]);
    bad_stamp.header.stamp.nanosec = 1_000_000_000;
    assert_eq!(dec.odometry(&bad_stamp), Err(BadInputKind::BadStamp));
    // Going backwards after a good one.
    assert!(dec.odometry(&ros_odom(2.0, [0.0, 0.0, 0.0])).is_ok());
    assert_eq!(
        dec.odometry(&ros_odom(1.5, [0.0, 0.0, 0.0])),
        Err(BadInputKind::Backwards)
    );
    // A jump is refused, then the track continues from the new place
    // without the jump in its ticks.
    assert_eq!(
        dec.odometry(&ros_odom(2.1, [100.0, 0.0, 0.0])),
        Err(BadInputKind::Jump)
    );
    let after = dec.odometry(&ros_odom(2.2, [100.01, 0.0, 0.0])).unwrap();
    assert_eq!((after.left_ticks, after.right_ticks), (100, 100));
}

#[test]
fn bridge_mode_needs_no_attachment_and_no_typed_key() {
    let mut dec = InputDecoder::new(
        RosKeys::new(Transport::Bridge {
            prefix: String::new(),
        }),
        WHEELS,
    );
    let bytes = encode(&ros_odom(1.0, [0.5, 0.0, 0.0])).unwrap();
    assert!(
        dec.decode(InputTopic::Odom, "r1/odom", &bytes, None)
            .is_ok()
    );
}

fn robot_pose(x: f64, y: f64, theta: f64) -> RobotPose {
    RobotPose {
        stamp: Time::from_secs_f64(10.0),
        x_m: x,
        y_m: y,
        theta_rad: theta,
        covariance: [0.0; 9],
        estimator: "tdoa-ekf".into(),
        fix_seq: 3,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    }
}

#[test]
fn published_pose_has_a_floor_under_its_covariance_and_never_nan() {
    let msg = pose_message(&robot_pose(1.0, 2.0, 0.5), "map").unwrap();
    assert_eq!(msg.header.frame_id, "map");
    assert_eq!(
        msg.header.stamp,
        ros::RosTime {
            sec: 10,
            nanosec: 0
        }
    );
    for k in 0..6 {
        assert!(msg.pose.covariance[k * 6 + k] > 0.0, "diagonal {k} is zero");
    }
    assert!((msg.pose.pose.orientation.yaw_rad() - 0.5).abs() < 1e-12);
    let mut nan = robot_pose(f64::NAN, 2.0, 0.5);
    assert!(pose_message(&nan, "map").is_none());
    nan = robot_pose(1.0, 2.0, 0.5);
    nan.covariance[4] = f64::NAN;
    assert!(pose_message(&nan, "map").is_none());
}

#[test]
fn fix_without_heading_says_its_yaw_is_unobserved() {
    let fix = Fix {
        stamp: Time::from_secs_f64(1.0),
        arrivals_seq: 1,
        x_m: 1.0,
        y_m: 2.0,
        z_m: 0.3,
        covariance: [4e-4, 1e-5, 0.0, 1e-5, 5e-4, 0.0, 0.0, 0.0, 0.0],
        heading_rad: 0.0,
        heading_valid: false,
        used: vec![1, 2, 3],
        rejected: vec![],
        residuals_m: vec![0.0; 3],
        quality: FixQuality::Minimal,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    };
    let m = fix_message(&fix, "map").unwrap();
    assert_eq!(m.pose.pose.position.z, 0.3);
    assert_eq!(m.pose.covariance[1], 1e-5);
    assert!(m.pose.covariance[14] > 0.0, "z variance floored");
    assert_eq!(m.pose.covariance[35], 1e6);
    let with_heading = Fix {
        heading_valid: true,
        heading_rad: 1.0,
        ..fix
    };
    let m = fix_message(&with_heading, "map").unwrap();
    assert!(m.pose.covariance[35] < 1.0);
    assert!((m.pose.pose.orientation.yaw_rad() - 1.0).abs() < 1e-12);
}

#[test]
fn map_to_odom_composes_with_odometry_to_the_pose() {
    let map_base = [3.0, -1.0, 2.0];
    let odom_base = [0.7, 0.4, -2.5];
    let t = map_to_odom(map_base, odom_base);
    let th = t.rotation.yaw_rad();
    let (s, c) = th.sin_cos();
    let x = t.translation.x + c * odom_base[0] - s * odom_base[1];
    let y = t.translation.y + s * odom_base[0] + c * odom_base[1];
    let yaw = (th + odom_base[2]).sin().atan2((th + odom_base[2]).cos());
    assert!((x - 3.0).abs() < 1e-12 && (y + 1.0).abs() < 1e-12);
    assert!((yaw - 2.0).abs() < 1e-12);
}

#[test]
fn tf_pairs_the_pose_with_odometry_at_its_time_and_stamps_ahead() {
    let mut h = OdomHistory::default();
    let pose = robot_pose(1.0, 1.0, 0.0);
    assert!(tf_message(&pose, &h, "map", "odom", 1.0).is_none());
    for (t, x) in [(9.0, 0.0), (11.0, 2.0)] {
        h.push(&Odometry {
            stamp: Time::from_secs_f64(t),
            x_m: x,
            y_m: 0.0,
            theta_rad: 0.0,
            left_ticks: 0,
            right_ticks: 0,
        });
    }
    let tf = tf_message(&pose, &h, "map", "odom", 1.0).unwrap();
    let ts = &tf.transforms[0];
    assert_eq!(
        (ts.header.frame_id.as_str(), ts.child_frame_id.as_str()),
        ("map", "odom")
    );
    assert_eq!(
        ts.header.stamp,
        ros::RosTime {
            sec: 11,
            nanosec: 0
        }
    );
    // Odometry at 10 s is interpolated to x = 1: map and odom coincide in x.
    assert!(ts.transform.translation.x.abs() < 1e-12);
    assert!((ts.transform.translation.y - 1.0).abs() < 1e-12);
}

#[test]
fn plan_resolves_names_under_the_robot_namespace() {
    let opts = Ros2Options {
        enabled: true,
        ..Ros2Options::default()
    };
    let plan = Ros2Plan::new(&opts, "r1", None).unwrap();
    assert_eq!(plan.pose.name, "/r1/pose");
    assert_eq!(plan.fix.name, "/r1/ickon/fix");
    assert_eq!(plan.tf.as_ref().unwrap().name, "/tf");
    assert_eq!(plan.odom.as_ref().unwrap().key, "0/r1/odom/*/*");
    let tokens = plan.tokens("zid1");
    assert_eq!(tokens.len(), 6, "node, 3 publishers, 2 subscribers");
    assert_eq!(tokens[0], "@ros2_lv/0/zid1/0/0/NN/%/%r1/ickon_msu");
    assert!(tokens[3].starts_with(
        "@ros2_lv/0/zid1/0/3/MP/%/%r1/ickon_msu/%tf/tf2_msgs::msg::dds_::TFMessage_/"
    ));
    assert!(tokens[4].contains("/4/MS/%/%r1/ickon_msu/%r1%odom/nav_msgs::msg::dds_::Odometry_/"));
    // The environment's domain, and the flag over it.
    assert_eq!(Ros2Plan::new(&opts, "r1", Some("7")).unwrap().domain, 7);
    let flagged = Ros2Options {
        domain: Some(3),
        ..opts.clone()
    };
    assert_eq!(Ros2Plan::new(&flagged, "r1", Some("7")).unwrap().domain, 3);
    assert!(Ros2Plan::new(&opts, "r1", Some("x")).is_err());
    assert!(Ros2Plan::new(&opts, "r1", Some("999")).is_err());
    let bridge = Ros2Options {
        mode: Ros2Mode::Bridge,
        ..opts.clone()
    };
    let plan = Ros2Plan::new(&bridge, "r1", None).unwrap();
    assert_eq!(plan.pose.key, "r1/pose");
    assert!(plan.tokens("z").is_empty());
    for bad in [
        Ros2Options {
            pose_topic: "a//b".into(),
            ..opts.clone()
        },
        Ros2Options {
            namespace: Some("r1".into()),
            ..opts.clone()
        },
        Ros2Options {
            map_frame: "/map".into(),
            ..opts.clone()
        },
        Ros2Options {
            node_name: "a/b".into(),
            ..opts.clone()
        },
        Ros2Options {
            tf_tolerance_s: f64::NAN,
            ..opts.clone()
        },
    ] {
        assert!(Ros2Plan::new(&bad, "r1", None).is_err(), "{bad:?}");
    }
}

#[test]
fn options_deserialize_with_defaults_and_refuse_unknown_fields() {
    let o: Ros2Options =
        toml::from_str("enabled = true\nodom_topic = \"wheel/odom\"\nmode = \"bridge\"\n").unwrap();
    assert!(o.enabled);
    assert_eq!(o.odom_topic, "wheel/odom");
    assert_eq!(o.mode, Ros2Mode::Bridge);
    assert_eq!(o.pose_topic, "pose");
    assert!(toml::from_str::<Ros2Options>("pose_topics = \"x\"").is_err());
}

#[test]
fn clap_defaults_equal_the_config_defaults() {
    use clap::Parser;
    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        ros2: Ros2Options,
    }
    let cli = Cli::parse_from(["x"]);
    assert_eq!(cli.ros2, Ros2Options::default());
    let cli = Cli::parse_from(["x", "--ros2", "--ros2-domain", "5", "--ros2-tf", "false"]);
    assert!(cli.ros2.enabled && !cli.ros2.publish_tf);
    assert_eq!(cli.ros2.domain, Some(5));
}
