//! One fuzz target per message type decoded from the network: random
//! bytes (with and without a valid header) and mutated valid encodings
//! (bit flips, truncation, extension, length fields set huge). Decoding
//! never panics, and what it accepts re-encodes to a stable canonical form.

use proptest::prelude::*;
use proptest::strategy::ValueTree;
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::mutate::{apply, mutations};
use super::values::draw;
use super::{config, entropy};
use crate::msg::{admin, control, robot, ros};
use crate::{decode, encode};

/// A payload for type `T`: random bytes, or a drawn `T` encoded and mutated.
fn payload<T: DeserializeOwned + Serialize>() -> impl Strategy<Value = Vec<u8>> {
    let random = proptest::collection::vec(any::<u8>(), 0..512);
    let headed = proptest::collection::vec(any::<u8>(), 0..512).prop_map(|mut b| {
        b.splice(0..0, [0, 1, 0, 0]);
        b
    });
    let mutated = (entropy(), mutations()).prop_filter_map("refused draw", |(e, m)| {
        let mut bytes = encode(&draw::<T>(&e)?).ok()?;
        apply(&mut bytes, &m);
        Some(bytes)
    });
    prop_oneof![1 => random, 2 => headed, 5 => mutated]
}

/// The invariants of decoding `bytes` as `T`.
fn check<T: DeserializeOwned + Serialize>(bytes: &[u8]) -> Result<(), TestCaseError> {
    let Ok(value) = decode::<T>(bytes) else {
        return Ok(());
    };
    // Accepted: its canonical encoding decodes and encodes to itself.
    let canonical = encode(&value).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert!(canonical.len() <= bytes.len(), "re-encoding grew");
    let again: T = decode(&canonical).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(encode(&again).ok(), Some(canonical));
    Ok(())
}

/// Drawn values round-trip exactly (bit for bit, NaN included).
fn round_trip<T: DeserializeOwned + Serialize>(e: &[u8]) -> Result<(), TestCaseError> {
    let Some(value) = draw::<T>(e) else {
        return Ok(());
    };
    let Ok(bytes) = encode(&value) else {
        // Only a huge draw may be too large to send.
        return Ok(());
    };
    let back: T = decode(&bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(encode(&back).ok(), Some(bytes));
    Ok(())
}

macro_rules! targets {
    ($($name:ident: $t:ty,)*) => {$(
        proptest! {
            #![proptest_config(config())]
            #[test]
            fn $name(bytes in payload::<$t>(), e in entropy()) {
                check::<$t>(&bytes)?;
                round_trip::<$t>(&e)?;
            }
        }
    )*};
}

targets! {
    fuzz_decode_site_info: control::SiteInfo,
    fuzz_decode_schedule: control::Schedule,
    fuzz_decode_cycle_trigger: control::CycleTrigger,
    fuzz_decode_clock_request: control::ClockRequest,
    fuzz_decode_clock_reply: control::ClockReply,
    fuzz_decode_burst: control::Burst,
    fuzz_decode_cell_status: control::CellStatus,
    fuzz_decode_air_temperature: control::AirTemperature,
    fuzz_decode_router_link: control::RouterLink,
    fuzz_decode_survey_calibration: control::SurveyCalibration,
    fuzz_decode_ultrasound_arrivals: robot::UltrasoundArrivals,
    fuzz_decode_odometry: robot::Odometry,
    fuzz_decode_imu: robot::Imu,
    fuzz_decode_obstacle_ranges: robot::ObstacleRanges,
    fuzz_decode_fix: robot::Fix,
    fuzz_decode_robot_pose: robot::RobotPose,
    fuzz_decode_truth: robot::Truth,
    fuzz_decode_status_report: admin::StatusReport,
    fuzz_decode_coverage_request: admin::CoverageRequest,
    fuzz_decode_coverage_report: admin::CoverageReport,
    fuzz_decode_reload_request: admin::ReloadRequest,
    fuzz_decode_admin_ack: admin::AdminAck,
    fuzz_decode_links_report: admin::LinksReport,
    fuzz_decode_ros_pose_with_covariance_stamped: ros::PoseWithCovarianceStamped,
    fuzz_decode_ros_odometry: ros::Odometry,
    fuzz_decode_ros_imu: ros::Imu,
    fuzz_decode_ros_tf_message: ros::TfMessage,
    fuzz_decode_sequence_number: u64,
}

proptest! {
    #![proptest_config(config())]

    /// `central/survey` as the MSU reads it: either layout (the current,
    /// or the one before each transmitter carried its lateness). What it
    /// accepts re-encodes in the current layout to a stable form.
    #[test]
    fn fuzz_decode_survey_calibration_either_layout(
        older in payload::<control::survey_before_lateness::CalibrationWithoutLateness>(),
        current in payload::<control::SurveyCalibration>(),
    ) {
        for bytes in [older, current] {
            let Ok(value) = control::SurveyCalibration::decode(&bytes) else {
                continue;
            };
            let canonical = encode(&value).map_err(|e| TestCaseError::fail(e.to_string()))?;
            let again = control::SurveyCalibration::decode(&canonical)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(encode(&again).ok(), Some(canonical));
        }
    }

    /// The rmw_zenoh attachment of every ROS 2 sample.
    #[test]
    fn fuzz_decode_ros_attachment(
        bytes in proptest::collection::vec(any::<u8>(), 0..64),
        m in mutations(),
        valid in any::<bool>(),
    ) {
        let mut bytes = bytes;
        if valid {
            bytes = crate::ros::Attachment { sequence_number: 7, source_timestamp_ns: 1, gid: [3; 16] }.to_bytes().to_vec();
            apply(&mut bytes, &m);
        }
        if let Ok(a) = crate::ros::Attachment::parse(&bytes) {
            prop_assert_eq!(crate::ros::Attachment::parse(&a.to_bytes()).ok(), Some(a));
        }
    }
}

#[test]
fn drawn_values_are_varied_and_reach_the_extremes() {
    // The generator is only worth its targets if it gives more than zeros.
    let mut rng = proptest::test_runner::TestRunner::deterministic();
    let mut nan = 0;
    let mut long = 0;
    let mut ids = std::collections::BTreeSet::new();
    for _ in 0..2_000 {
        let e = entropy().new_tree(&mut rng).unwrap().current();
        if let Some(p) = draw::<robot::RobotPose>(&e) {
            nan += usize::from(p.x_m.is_nan());
            ids.insert(p.estimator);
        }
        if let Some(s) = draw::<control::Schedule>(&e) {
            long += usize::from(s.emissions.len() > 8);
        }
    }
    assert!(nan > 20, "{nan} NaN positions");
    assert!(long > 5, "{long} long schedules");
    assert!(ids.contains("c1") && ids.len() > 20, "{ids:?}");
}

#[test]
fn mutated_encodings_are_sometimes_accepted_so_the_checks_run() {
    let mut rng = proptest::test_runner::TestRunner::deterministic();
    let accepted = (0..1_000)
        .filter(|_| {
            let bytes = payload::<control::Schedule>()
                .new_tree(&mut rng)
                .unwrap()
                .current();
            decode::<control::Schedule>(&bytes).is_ok()
        })
        .count();
    assert!(accepted > 50, "{accepted} of 1000 accepted");
}

proptest! {
    #![proptest_config(config())]

    /// Key expressions of received samples: parsed, never trusted.
    #[test]
    fn fuzz_parse_key(
        tail in prop_oneof![
            "\\PC{0,40}",
            "(central|alive|cell|robot|sim)/[a-z0-9/*_$-]{0,30}",
            "(robot/r1/(pose|fix|odom|imu|range|arrivals)|cell/c1/burst|alive/cell/c2)[/a-z*]{0,6}",
        ],
        ros in "[a-z0-9/_:%*-]{0,60}",
    ) {
        let keys = crate::keys::Keys::new("lab").map_err(|e| TestCaseError::fail(e.to_string()))?;
        let key = format!("{}/{tail}", keys.prefix());
        if let Ok(parsed) = keys.parse(&key) {
            use crate::keys::Key;
            match parsed {
                Key::AliveCell(id) | Key::AliveRobot(id) | Key::CellBurst(id)
                | Key::CellStatus(id) | Key::CellAir(id) | Key::Robot(id, _) | Key::SimTruth(id) | Key::SimKit(id) | Key::RobotStatus(id) | Key::RobotSummary(id) => {
                    prop_assert!(crate::keys::validate_id(&id).is_ok(), "{key} gave {id:?}");
                }
                _ => {}
            }
        }
        let _ = keys.parse(&tail);
        let _ = crate::ros::keys::split_type_and_hash(&ros);
    }
}
