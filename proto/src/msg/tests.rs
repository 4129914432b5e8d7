//! Round trips of every message, bytes written by hand from the CDR rules,
//! and malformed payloads.

use super::admin::*;
use super::control::*;
use super::robot::*;
use super::ros::PoseWithCovarianceStamped;
use crate::codec::{DecodeError, decode, encode};
use crate::time::{Duration, Time};
use serde::Serialize;
use serde::de::DeserializeOwned;

fn round_trip<T: Serialize + DeserializeOwned + PartialEq + std::fmt::Debug>(value: T) {
    let bytes = encode(&value).expect("encodes");
    assert_eq!(&bytes[..4], &[0, 1, 0, 0], "little-endian header");
    let back: T = decode(&bytes).expect("decodes");
    assert_eq!(back, value);
    // Every strict prefix is an error, never a panic or a wrong value.
    for cut in 0..bytes.len() {
        assert!(
            decode::<T>(&bytes[..cut]).is_err(),
            "prefix of {cut} bytes accepted"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert_eq!(decode::<T>(&longer), Err(DecodeError::TrailingBytes(1)));
}

fn sample_schedule() -> Schedule {
    Schedule {
        version: 3,
        effective_cycle: 120,
        cycle_period: Duration::from_millis(200),
        slot_length: Duration::from_millis(25),
        emissions: vec![
            Emission {
                tx_id: 11,
                cell_id: "c1".into(),
                offset: Duration::ZERO,
                slot: 0,
            },
            Emission {
                tx_id: 21,
                cell_id: "c2".into(),
                offset: Duration::from_millis(25),
                slot: 1,
            },
        ],
        active_cells: vec!["c1".into(), "c2".into()],
        epoch: 1_700_000_000_000_000_000,
    }
}

#[test]
fn control_messages_round_trip() {
    round_trip(SiteInfo {
        site: "lab".into(),
        version: 1,
        site_toml: "name = \"lab\"\n".into(),
    });
    round_trip(sample_schedule());
    round_trip(CycleTrigger {
        cycle: 7,
        start: Time(123_456_789),
        schedule_version: 2,
        epoch: 42,
        firing: Vec::new(),
        cycle_period: crate::time::Duration::ZERO,
    });
    round_trip(ClockRequest {
        cell_id: "c3".into(),
        t1: Time(-5),
    });
    round_trip(ClockReply {
        t1: Time(1),
        t2: Time(2),
        t3: Time(3),
        epoch: 42,
    });
    round_trip(Burst {
        cell_id: "c1".into(),
        tx_id: 12,
        cycle: 9,
        scheduled: Time(1_000),
        actual: Time(1_004),
        epoch: 42,
    });
    round_trip(RouterLink {
        node_id: "c4".into(),
        back_unix_ms: 1_796_000_000_123,
        losses: 3,
    });
    round_trip(LinksReport {
        cells: vec![RouterLink {
            node_id: "c1".into(),
            back_unix_ms: 0,
            losses: 0,
        }],
        robots: vec![RouterLink {
            node_id: "r2".into(),
            back_unix_ms: 1_796_000_000_999,
            losses: 1,
        }],
    });
    round_trip(AirTemperature {
        cell_id: "c4".into(),
        stamp: Time(98),
        temperature_c: -3.25,
    });
    round_trip(CellStatus {
        cell_id: "c4".into(),
        stamp: Time(99),
        offset_ns: -50_000_000,
        drift_ppb: 100_000,
        offset_sigma_ns: 12_000,
        sync_samples: 8,
        last_cycle_fired: 41,
        cycles_fired: 40,
        slots_skipped: 1,
        faults: vec!["late trigger".into()],
        inputs_refused: 3,
        device: String::new(),
    });
}

#[test]
fn robot_messages_round_trip() {
    round_trip(UltrasoundArrivals {
        seq: 5,
        arrivals: vec![
            Arrival {
                tx_id: 11,
                receiver_id: 0,
                t_arrival: Time(10_000),
            },
            Arrival {
                tx_id: 12,
                receiver_id: 5,
                t_arrival: Time(35_000),
            },
        ],
    });
    round_trip(Odometry {
        stamp: Time(1),
        x_m: 0.5,
        y_m: 0.25,
        theta_rad: -3.0,
        left_ticks: -12,
        right_ticks: 400_000,
    });
    round_trip(Imu {
        stamp: Time(2),
        gyro_z_rad_s: 0.01,
    });
    round_trip(ObstacleRanges {
        stamp: Time(3),
        left_m: 1.5,
        left_valid: true,
        right_m: 0.0,
        right_valid: false,
        left_ir_m: 0.1,
        left_ir_valid: true,
        right_ir_m: 0.0,
        right_ir_valid: false,
    });
    round_trip(Fix {
        stamp: Time(4),
        arrivals_seq: 5,
        x_m: 1.0,
        y_m: 2.0,
        z_m: 0.4,
        covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 0.0],
        heading_rad: 1.0,
        heading_valid: true,
        used: vec![11, 12, 13],
        rejected: vec![14],
        residuals_m: vec![0.001, -0.002, 0.0005],
        quality: FixQuality::Suspect,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    });
    round_trip(RobotPose {
        stamp: Time(5),
        x_m: 1.0,
        y_m: 2.0,
        theta_rad: 0.5,
        covariance: [0.0; 9],
        estimator: "ickon-akf".into(),
        fix_seq: 5,
        status: crate::msg::robot::PoseStatus::Tracking,
    });
    round_trip(Truth {
        stamp: Time(6),
        robot_clock: Time(-6),
        x_m: 1.0,
        y_m: 2.0,
        theta_rad: 0.5,
        v_m_s: 0.3,
        omega_rad_s: -0.1,
    });
}

fn sample_cell_health() -> CellHealth {
    CellHealth {
        id: "c1".into(),
        state: CellState::Idle,
        state_since_cycle: 4,
        sync_sigma_ns: 3_000,
        offset_ns: -10,
        drift_ppb: 95_000,
        residual_samples: 64,
        residual_max_ns: 41_000,
        residual_rms_ns: 17_000,
        last_cycle_fired: 10,
        cycles_fired: 10,
        cycles_missed: 0,
        slots_skipped: 1,
        inputs_refused: 0,
        device: String::new(),
    }
}

fn sample_coverage() -> CoverageReport {
    CoverageReport {
        schedule_version: 7,
        origin_x_m: 0.125,
        origin_y_m: -0.5,
        resolution_m: 0.25,
        height_m: 0.5,
        columns: 2,
        rows: 1,
        on_floor: vec![true, false],
        visible: vec![4, 0],
        hdop: vec![1.25, 0.0],
    }
}

#[test]
fn admin_messages_round_trip() {
    round_trip(StatusReport {
        site: "lab".into(),
        cycle: 10,
        stamp: Time(7),
        paused: false,
        schedule_version: 1,
        update_rate_hz: 5.0,
        cells: vec![sample_cell_health()],
        robots: vec![RobotHealth {
            id: "r1".into(),
            up: true,
            fixes_per_s: 4.9,
            estimator: "ickon-akf".into(),
            pose_valid: true,
            x_m: 1.0,
            y_m: 1.0,
            theta_rad: 0.0,
            stale: String::new(),
            fixes_over_rate: 0,
            survey_check: String::new(),
            fixes_quarantined: 0,
            survey_misfit_m: -1.0,
            survey_bound_m: -1.0,
            receivers: String::new(),
            summaries_dropped: 0,
        }],
        epoch: 42,
        foreign_control: 1,
        active: true,
        survey_publications: 3,
        survey_publish_mean_us: 410.0,
        survey_publish_max_us: 900.0,
        speed_of_sound_m_s: 345.5,
        speed_of_sound_sigma_m_s: 0.2,
        site_speed_of_sound_m_s: 343.2,
        transmitters_left_out: vec![12],
        robot_counts: Default::default(),
        robots_posed: 0,
    });
    round_trip(TransmittersReport {
        site: "lab".into(),
        stamp: Time(9),
        learning: true,
        fixes_taken: 77,
        speed_of_sound_m_s: 0.0,
        speed_of_sound_sigma_m_s: 0.0,
        site_speed_of_sound_m_s: 343.2,
        transmitters: vec![TransmitterStatus {
            tx_id: 12,
            cell_id: "c1".into(),
            condition: "dead".into(),
            left_out: true,
            evidence: "heard in none of 12 fixes near it".into(),
            due: 12.5,
            heard_pct: 0.0,
            expected_pct: 93.0,
            rejected_pct: -1.0,
            residuals_known: false,
            residual_mean_m: 0.0,
            residual_std_m: 0.0,
            last_heard_s_ago: -1.0,
            offset_m: [0.0, 0.001, -0.002],
        }],
        air_sensors: vec![BoardAirStatus {
            cell_id: "c1".into(),
            state: "used".into(),
            temperature_c: 21.5,
            accepted_s_ago: 0.4,
            accepted: 30,
            refused_not_a_number: 1,
            refused_out_of_range: 2,
            refused_stuck: 3,
            refused_jump: 4,
        }],
        air_sensor_speed_m_s: 344.1,
    });
    round_trip(sample_coverage());
    round_trip(CoverageRequest { resolution_m: 0.5 });
    round_trip(ReloadRequest {
        file_name: "lab.toml".into(),
        site_toml: "x".into(),
    });
    round_trip(AdminAck {
        ok: false,
        messages: vec!["line 3: bad".into(), "line 9: worse".into()],
    });
}

#[test]
fn coverage_report_matches_hand_written_cdr() {
    let mut expected = vec![0x00, 0x01, 0x00, 0x00]; // header; offsets count from here
    expected.extend_from_slice(&7u32.to_le_bytes()); // schedule_version (0)
    expected.extend_from_slice(&[0; 4]); // pad 4 -> 8 for the f64
    for v in [0.125f64, -0.5, 0.25, 0.5] {
        expected.extend_from_slice(&v.to_le_bytes()); // origin x, y, resolution, height (8..40)
    }
    expected.extend_from_slice(&2u32.to_le_bytes()); // columns (40)
    expected.extend_from_slice(&1u32.to_le_bytes()); // rows (44)
    expected.extend_from_slice(&2u32.to_le_bytes()); // on_floor length (48)
    expected.extend_from_slice(&[1, 0]); // bool octets (52, 53)
    expected.extend_from_slice(&[0; 2]); // pad 54 -> 56 for the u32 length
    expected.extend_from_slice(&2u32.to_le_bytes()); // visible length (56)
    expected.extend_from_slice(&4u32.to_le_bytes()); // (60)
    expected.extend_from_slice(&0u32.to_le_bytes()); // (64)
    expected.extend_from_slice(&2u32.to_le_bytes()); // hdop length (68)
    expected.extend_from_slice(&1.25f64.to_le_bytes()); // (72, already 8-aligned)
    expected.extend_from_slice(&0.0f64.to_le_bytes()); // (80)
    assert_eq!(encode(&sample_coverage()).unwrap(), expected);
    assert_eq!(
        decode::<CoverageReport>(&expected).unwrap(),
        sample_coverage()
    );
    // A bool octet other than 0 or 1 is malformed, not a silent `true`.
    let mut bad = expected.clone();
    bad[4 + 52] = 2;
    assert!(decode::<CoverageReport>(&bad).is_err());
}

#[test]
fn cell_health_matches_hand_written_cdr() {
    let mut expected = vec![0x00, 0x01, 0x00, 0x00];
    expected.extend_from_slice(&3u32.to_le_bytes()); // id length, NUL included (0)
    expected.extend_from_slice(b"c1\0"); // (4..7)
    expected.push(0); // pad 7 -> 8
    expected.extend_from_slice(&2u32.to_le_bytes()); // state: Idle, its index (8..12)
    expected.extend_from_slice(&[0; 4]); // pad 12 -> 16
    expected.extend_from_slice(&4u64.to_le_bytes()); // state_since_cycle (16)
    for v in [3_000i64, -10, 95_000] {
        expected.extend_from_slice(&v.to_le_bytes()); // sigma, offset, drift (24..48)
    }
    expected.extend_from_slice(&64u32.to_le_bytes()); // residual_samples (48)
    expected.extend_from_slice(&[0; 4]); // pad 52 -> 56
    for v in [41_000i64, 17_000] {
        expected.extend_from_slice(&v.to_le_bytes()); // residual max, rms (56..72)
    }
    for v in [10u64, 10, 0, 1, 0] {
        // last fired, fired, missed, skipped, refused
        expected.extend_from_slice(&v.to_le_bytes());
    }
    expected.extend_from_slice(&1u32.to_le_bytes()); // device: empty, NUL only (112)
    expected.push(0);
    assert_eq!(encode(&sample_cell_health()).unwrap(), expected);
    assert_eq!(
        decode::<CellHealth>(&expected).unwrap(),
        sample_cell_health()
    );
    // A state index past the last one is malformed.
    let mut bad = expected.clone();
    bad[4 + 8] = 3;
    assert!(decode::<CellHealth>(&bad).is_err());
}

#[test]
fn cycle_trigger_matches_hand_written_cdr() {
    let msg = CycleTrigger {
        cycle: 0x0102_0304_0506_0708,
        start: Time(-2),
        schedule_version: 0xAABB_CCDD,
        epoch: 0x1122_3344_5566_7788,
        firing: vec![crate::msg::control::Firing {
            tx_id: 5,
            offset: crate::time::Duration::from_nanos(3),
        }],
        cycle_period: crate::time::Duration::from_nanos(7),
    };
    #[rustfmt::skip]
    let expected: Vec<u8> = vec![
        0x00, 0x01, 0x00, 0x00,                         // encapsulation: CDR_LE
        0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01, // u64 cycle at offset 0
        0xFE, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, // i64 start = -2
        0xDD, 0xCC, 0xBB, 0xAA,                         // u32 schedule_version
        0x00, 0x00, 0x00, 0x00,                         // pad 20 -> 24 for the u64
        0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11, // u64 epoch at 24
        0x01, 0x00, 0x00, 0x00,                         // u32 length of firing at 32
        0x05, 0x00, 0x00, 0x00,                         // firing[0].tx_id at 36
        0x03, 0, 0, 0, 0, 0, 0, 0,                      // firing[0].offset at 40
        0x07, 0, 0, 0, 0, 0, 0, 0,                      // i64 cycle_period at 48
    ];
    assert_eq!(encode(&msg).unwrap(), expected);
    assert_eq!(decode::<CycleTrigger>(&expected).unwrap(), msg);
}

#[test]
fn burst_matches_hand_written_cdr() {
    let msg = Burst {
        cell_id: "c1".into(),
        tx_id: 12,
        cycle: 9,
        scheduled: Time(1_000),
        actual: Time(1_004),
        epoch: 7,
    };
    let mut expected = vec![0x00, 0x01, 0x00, 0x00]; // header; offsets count from here
    expected.extend_from_slice(&3u32.to_le_bytes()); // string length, NUL included (0)
    expected.extend_from_slice(b"c1\0"); // bytes and NUL (4..7)
    expected.push(0); // pad 7 -> 8 for the u32
    expected.extend_from_slice(&12u32.to_le_bytes()); // tx_id (8)
    expected.extend_from_slice(&[0; 4]); // pad 12 -> 16 for the u64
    expected.extend_from_slice(&9u64.to_le_bytes()); // cycle (16)
    expected.extend_from_slice(&1_000i64.to_le_bytes()); // scheduled (24)
    expected.extend_from_slice(&1_004i64.to_le_bytes()); // actual (32)
    expected.extend_from_slice(&7u64.to_le_bytes()); // epoch (40)
    assert_eq!(encode(&msg).unwrap(), expected);
    assert_eq!(decode::<Burst>(&expected).unwrap(), msg);
}

#[test]
fn ultrasound_arrivals_match_hand_written_cdr() {
    let msg = UltrasoundArrivals {
        seq: 1,
        arrivals: vec![
            Arrival {
                tx_id: 0x11,
                receiver_id: 2,
                t_arrival: Time(0x100),
            },
            Arrival {
                tx_id: 0x12,
                receiver_id: 3,
                t_arrival: Time(0x200),
            },
        ],
    };
    let mut expected = vec![0x00, 0x01, 0x00, 0x00];
    expected.extend_from_slice(&1u64.to_le_bytes()); // seq at 0
    expected.extend_from_slice(&2u32.to_le_bytes()); // sequence length at 8
    // element 0 at 12: u32 tx_id, u8 receiver, pad 17 -> 24, i64 t_arrival
    expected.extend_from_slice(&0x11u32.to_le_bytes());
    expected.push(2);
    expected.extend_from_slice(&[0; 7]);
    expected.extend_from_slice(&0x100i64.to_le_bytes());
    // element 1 at 32
    expected.extend_from_slice(&0x12u32.to_le_bytes());
    expected.push(3);
    expected.extend_from_slice(&[0; 3]); // 37 -> 40
    expected.extend_from_slice(&0x200i64.to_le_bytes());
    assert_eq!(encode(&msg).unwrap(), expected);
    assert_eq!(decode::<UltrasoundArrivals>(&expected).unwrap(), msg);
}

#[test]
fn ros_pose_with_covariance_has_the_ros2_layout() {
    let pose = RobotPose {
        stamp: Time(3_500_000_001),
        x_m: 1.5,
        y_m: -2.0,
        theta_rad: 0.0,
        covariance: [0.01, 0.0, 0.0, 0.0, 0.02, 0.0, 0.0, 0.0, 0.03],
        estimator: "ickon-akf".into(),
        fix_seq: 0,
        status: crate::msg::robot::PoseStatus::Tracking,
    };
    let ros = PoseWithCovarianceStamped::from_robot_pose(&pose, "map");
    let bytes = encode(&ros).unwrap();
    // docs/ros2.md: with frame_id "map" the message is 364 bytes.
    assert_eq!(bytes.len(), 364);
    let mut expected = vec![0x00, 0x01, 0x00, 0x00];
    expected.extend_from_slice(&3i32.to_le_bytes());
    expected.extend_from_slice(&500_000_001u32.to_le_bytes());
    expected.extend_from_slice(&4u32.to_le_bytes());
    expected.extend_from_slice(b"map\0");
    // offset 16 after the frame id: already 8-aligned, no padding
    for v in [1.5f64, -2.0, 0.0, 0.0, 0.0, 0.0, 1.0] {
        expected.extend_from_slice(&v.to_le_bytes());
    }
    for v in ros.pose.covariance {
        expected.extend_from_slice(&v.to_le_bytes());
    }
    assert_eq!(bytes, expected);
    assert_eq!(ros.pose.covariance[0], 0.01);
    assert_eq!(ros.pose.covariance[7], 0.02);
    assert_eq!(ros.pose.covariance[35], 0.03);
    assert_eq!(
        decode::<PoseWithCovarianceStamped>(&bytes)
            .unwrap()
            .header
            .frame_id,
        "map"
    );
}

#[test]
fn huge_length_prefixes_are_rejected_without_allocating_them() {
    // A string claiming 4 GiB, a sequence claiming 4 billion elements.
    let mut bad_string = vec![0x00, 0x01, 0x00, 0x00];
    bad_string.extend_from_slice(&u32::MAX.to_le_bytes());
    bad_string.extend_from_slice(b"c1\0");
    assert!(matches!(
        decode::<Burst>(&bad_string),
        Err(DecodeError::Truncated(_))
    ));
    let mut bad_seq = vec![0x00, 0x01, 0x00, 0x00];
    bad_seq.extend_from_slice(&1u64.to_le_bytes());
    bad_seq.extend_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        decode::<UltrasoundArrivals>(&bad_seq),
        Err(DecodeError::Truncated(_))
    ));
}

#[test]
fn garbage_is_an_error_not_a_panic() {
    assert_eq!(
        decode::<CycleTrigger>(&[]),
        Err(DecodeError::MissingHeader(0))
    );
    assert!(matches!(
        decode::<CycleTrigger>(&[0x7b, 0x22, 0x61, 0x22, 0, 0]),
        Err(DecodeError::BadHeader(_))
    ));
    // A string without its NUL, and one with invalid UTF-8.
    let mut no_nul = vec![0x00, 0x01, 0x00, 0x00];
    no_nul.extend_from_slice(&2u32.to_le_bytes());
    no_nul.extend_from_slice(b"c1");
    assert!(matches!(
        decode::<ClockRequest>(&no_nul),
        Err(DecodeError::Malformed(_))
    ));
    let mut bad_utf8 = vec![0x00, 0x01, 0x00, 0x00];
    bad_utf8.extend_from_slice(&3u32.to_le_bytes());
    bad_utf8.extend_from_slice(&[0xff, 0xfe, 0x00]);
    bad_utf8.extend_from_slice(&[0; 1 + 8]);
    assert!(matches!(
        decode::<ClockRequest>(&bad_utf8),
        Err(DecodeError::Malformed(_))
    ));
    // An enum tag out of range.
    let mut fix = encode(&Fix {
        stamp: Time(0),
        arrivals_seq: 0,
        x_m: 0.0,
        y_m: 0.0,
        z_m: 0.0,
        covariance: [0.0; 9],
        heading_rad: 0.0,
        heading_valid: false,
        used: vec![],
        rejected: vec![],
        residuals_m: vec![],
        quality: FixQuality::Good,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    })
    .unwrap();
    let n = fix.len();
    // The quality, before the survey version and the unused arrivals'
    // two (empty) arrays.
    fix[n - 16..n - 12].copy_from_slice(&77u32.to_le_bytes());
    assert!(matches!(
        decode::<Fix>(&fix),
        Err(DecodeError::Malformed(_))
    ));
}

#[test]
fn big_endian_payloads_decode_too() {
    let mut be = vec![0x00, 0x00, 0x00, 0x00];
    be.extend_from_slice(&7u64.to_be_bytes());
    be.extend_from_slice(&5i64.to_be_bytes());
    be.extend_from_slice(&1u32.to_be_bytes());
    be.extend_from_slice(&[0; 4]);
    be.extend_from_slice(&9u64.to_be_bytes()); // epoch
    be.extend_from_slice(&0u32.to_be_bytes()); // no firings named
    be.extend_from_slice(&[0; 4]);
    be.extend_from_slice(&11i64.to_be_bytes()); // cycle_period
    let t: CycleTrigger = decode(&be).unwrap();
    assert_eq!(t.cycle, 7);
    assert_eq!(t.start, Time(5));
    assert_eq!(t.epoch, 9);
    assert_eq!(t.cycle_period, crate::time::Duration::from_nanos(11));
}

mod random {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let _ = decode::<Schedule>(&bytes);
            let _ = decode::<Fix>(&bytes);
            let _ = decode::<StatusReport>(&bytes);
            let _ = decode::<CoverageReport>(&bytes);
            let mut with_header = vec![0, 1, 0, 0];
            with_header.extend_from_slice(&bytes);
            let _ = decode::<Schedule>(&with_header);
            let _ = decode::<UltrasoundArrivals>(&with_header);
            let _ = decode::<SiteInfo>(&with_header);
        }

        #[test]
        fn arrivals_round_trip(seq in any::<u64>(), raw in proptest::collection::vec((any::<u32>(), 0u8..6, any::<i64>()), 0..40)) {
            let msg = UltrasoundArrivals {
                seq,
                arrivals: raw.into_iter().map(|(tx_id, receiver_id, t)| Arrival { tx_id, receiver_id, t_arrival: Time(t) }).collect(),
            };
            let back: UltrasoundArrivals = decode(&encode(&msg).unwrap()).unwrap();
            prop_assert_eq!(back, msg);
        }

        #[test]
        fn strings_round_trip(s in "\\PC{0,40}") {
            let msg = ClockRequest { cell_id: s.replace('\0', ""), t1: Time(1) };
            let back: ClockRequest = decode(&encode(&msg).unwrap()).unwrap();
            prop_assert_eq!(back, msg);
        }
    }
}
