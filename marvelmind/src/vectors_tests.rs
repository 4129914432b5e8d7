//! Byte sequences written by hand from Marvelmind's published layouts (see
//! the crate's documentation), one per packet code, and what they must
//! decode to. The frames are built here byte by byte, not by the crate's
//! encoder, so an encoder and decoder that agree on a wrong layout fail.

use crate::{
    BeaconDistance, BeaconPosition, Deframer, FrameError, FusedImu, HedgeTime, Packet, PacketError,
    Position, Quality, RawDistances, RawImu, Telemetry, crc16_modbus,
};

/// `0xFF 0x47`, the code, the length, `payload`, and the CRC.
fn frame(code: u16, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![
        0xFF,
        0x47,
        code as u8,
        (code >> 8) as u8,
        payload.len() as u8,
    ];
    f.extend_from_slice(payload);
    let crc = crc16_modbus(&f);
    f.push(crc as u8);
    f.push((crc >> 8) as u8);
    f
}

fn decode_all(bytes: &[u8]) -> (Vec<Packet>, Vec<String>) {
    let mut packets = Vec::new();
    let mut refused = Vec::new();
    Deframer::new().feed(bytes, |f| match f {
        Ok(frame) => match Packet::decode(&frame) {
            Ok(Some(p)) => packets.push(p),
            Ok(None) => refused.push(format!("skipped 0x{:04x}", frame.code)),
            Err(e) => refused.push(e.to_string()),
        },
        Err(e) => refused.push(e.to_string()),
    });
    (packets, refused)
}

fn only(bytes: &[u8]) -> Packet {
    let (packets, refused) = decode_all(bytes);
    assert!(refused.is_empty(), "{refused:?}");
    assert_eq!(packets.len(), 1);
    packets.into_iter().next().expect("one packet")
}

#[test]
fn position_in_centimetres() {
    // time 1000 ms, x = -150 cm, y = 320 cm, z = 45 cm, flags 0x02 (time in
    // ms), address 7, heading 123.4 degrees, 2 bytes unused.
    let payload = [
        0xE8, 0x03, 0x00, 0x00, 0x6A, 0xFF, 0x40, 0x01, 0x2D, 0x00, 0x02, 0x07, 0xD2, 0x04, 0x00,
        0x00,
    ];
    let p = only(&frame(0x0001, &payload));
    let expected = Position {
        time: HedgeTime::Counter(1000),
        x_mm: -1500,
        y_mm: 3200,
        z_mm: 450,
        flags: 0x02,
        address: 7,
        heading_raw: 1234,
    };
    assert_eq!(p, Packet::Position(expected));
    let Packet::Position(p) = p else {
        unreachable!()
    };
    assert!(p.available());
    assert!((p.heading_deg() - 123.4).abs() < 1e-9);
}

#[test]
fn position_in_millimetres_with_a_counter_and_with_real_time() {
    // x = 1234 mm, y = -5 mm, z = 2000 mm, flags 0x01 (not available).
    let coords = [
        0xD2, 0x04, 0x00, 0x00, 0xFB, 0xFF, 0xFF, 0xFF, 0xD0, 0x07, 0x00, 0x00, 0x01, 0x09, 0x00,
        0x00, 0x00, 0x00,
    ];
    let mut counter = vec![0x10, 0x00, 0x00, 0x00];
    counter.extend_from_slice(&coords);
    let mut real = 1_700_000_000_123i64.to_le_bytes().to_vec();
    real.extend_from_slice(&coords);
    let expected = |time| {
        Packet::Position(Position {
            time,
            x_mm: 1234,
            y_mm: -5,
            z_mm: 2000,
            flags: 0x01,
            address: 9,
            heading_raw: 0,
        })
    };
    assert_eq!(
        only(&frame(0x0011, &counter)),
        expected(HedgeTime::Counter(16))
    );
    assert_eq!(
        only(&frame(0x0081, &real)),
        expected(HedgeTime::RealTime(1_700_000_000_123))
    );
    let Packet::Position(p) = only(&frame(0x0011, &counter)) else {
        unreachable!()
    };
    assert!(!p.available());
}

#[test]
fn beacon_positions_in_centimetres_and_millimetres() {
    // Two beacons: 2 at (100, 200, 300) cm, 3 at (-100, 0, 250) cm.
    let cm = [
        0x02, 0x02, 0x64, 0x00, 0xC8, 0x00, 0x2C, 0x01, 0x00, 0x03, 0x9C, 0xFF, 0x00, 0x00, 0xFA,
        0x00, 0x00,
    ];
    let expected = vec![
        BeaconPosition {
            address: 2,
            x_mm: 1000,
            y_mm: 2000,
            z_mm: 3000,
        },
        BeaconPosition {
            address: 3,
            x_mm: -1000,
            y_mm: 0,
            z_mm: 2500,
        },
    ];
    assert_eq!(only(&frame(0x0002, &cm)), Packet::BeaconPositions(expected));
    // One beacon: 4 at (1001, -2, 2999) mm.
    let mm = [
        0x01, 0x04, 0xE9, 0x03, 0x00, 0x00, 0xFE, 0xFF, 0xFF, 0xFF, 0xB7, 0x0B, 0x00, 0x00, 0x00,
    ];
    assert_eq!(
        only(&frame(0x0012, &mm)),
        Packet::BeaconPositions(vec![BeaconPosition {
            address: 4,
            x_mm: 1001,
            y_mm: -2,
            z_mm: 2999
        }])
    );
}

#[test]
fn a_beacon_count_its_length_does_not_hold_is_refused() {
    // Says three beacons, holds two.
    let mut cm = vec![0x03];
    cm.extend_from_slice(&[0; 16]);
    let (packets, refused) = decode_all(&frame(0x0002, &cm));
    assert!(packets.is_empty());
    assert_eq!(
        refused,
        vec!["packet 0x0002 announces 3 beacon(s) but holds 2".to_string()]
    );
}

#[test]
fn raw_distances_with_a_counter_and_with_real_time() {
    // Hedgehog 9; beacon 2 at 4000 mm, beacon 3 at 5001 mm, two unused
    // slots; time 77; measured 25 ms before it.
    let mut p = vec![0x09];
    for (beacon, mm) in [(2u8, 4000u32), (3, 5001), (0, 0), (0, 0)] {
        p.push(beacon);
        p.extend_from_slice(&mm.to_le_bytes());
        p.push(0);
    }
    let mut counter = p.clone();
    counter.extend_from_slice(&77u32.to_le_bytes());
    counter.extend_from_slice(&25u16.to_le_bytes());
    counter.push(0);
    let mut real = p;
    real.extend_from_slice(&(-3i64).to_le_bytes());
    real.extend_from_slice(&25u16.to_le_bytes());
    real.push(0);
    let expected = |time| {
        Packet::RawDistances(RawDistances {
            hedge: 9,
            distances: [
                BeaconDistance {
                    beacon: 2,
                    distance_mm: 4000,
                },
                BeaconDistance {
                    beacon: 3,
                    distance_mm: 5001,
                },
                BeaconDistance::default(),
                BeaconDistance::default(),
            ],
            time,
            time_shift_ms: 25,
        })
    };
    assert_eq!(counter.len(), 32);
    assert_eq!(
        only(&frame(0x0004, &counter)),
        expected(HedgeTime::Counter(77))
    );
    assert_eq!(
        only(&frame(0x0084, &real)),
        expected(HedgeTime::RealTime(-3))
    );
}

#[test]
fn raw_imu() {
    let mut p = Vec::new();
    for v in [10i16, -20, 1000, 1, -2, 3, 300, 400, -500] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    p.extend_from_slice(&[0; 6]);
    p.extend_from_slice(&123_456u32.to_le_bytes());
    p.extend_from_slice(&[0; 4]);
    assert_eq!(
        only(&frame(0x0003, &p)),
        Packet::RawImu(RawImu {
            accel: [10, -20, 1000],
            gyro: [1, -2, 3],
            compass: [300, 400, -500],
            time: HedgeTime::Counter(123_456),
        })
    );
}

#[test]
fn fused_imu() {
    let mut p = Vec::new();
    for v in [1500i32, -2500, 300] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    for v in [10000i16, 0, 0, -1, 100, -200, 0, 5, 6, 7] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    p.extend_from_slice(&[0; 2]);
    p.extend_from_slice(&42u32.to_le_bytes());
    p.extend_from_slice(&[0; 4]);
    assert_eq!(p.len(), 42);
    assert_eq!(
        only(&frame(0x0005, &p)),
        Packet::FusedImu(FusedImu {
            position_mm: [1500, -2500, 300],
            quaternion: [10000, 0, 0, -1],
            velocity_mm_s: [100, -200, 0],
            accel_mm_s2: [5, 6, 7],
            time: HedgeTime::Counter(42),
        })
    );
}

#[test]
fn quality_and_telemetry() {
    let mut q = vec![0x05, 87];
    q.extend_from_slice(&[0; 14]);
    assert_eq!(
        only(&frame(0x0007, &q)),
        Packet::Quality(Quality {
            address: 5,
            percent: 87
        })
    );
    let mut t = vec![0xE4, 0x0C, 0xB5];
    t.extend_from_slice(&[0; 13]);
    assert_eq!(
        only(&frame(0x0006, &t)),
        Packet::Telemetry(Telemetry {
            battery_mv: 3300,
            rssi_dbm: -75
        })
    );
}

#[test]
fn unknown_codes_are_skipped_by_their_length() {
    let mut q = vec![0x05, 50];
    q.extend_from_slice(&[0; 14]);
    let mut bytes = frame(0x0201, &[0xFF, 0x47, 0x07, 0x00, 0x10, 1, 2, 3, 4, 5, 6, 7]);
    bytes.extend(frame(0x0007, &q));
    let (packets, refused) = decode_all(&bytes);
    assert_eq!(refused, vec!["skipped 0x0201".to_string()]);
    assert_eq!(
        packets,
        vec![Packet::Quality(Quality {
            address: 5,
            percent: 50
        })]
    );
}

#[test]
fn every_packet_survives_garbage_around_it() {
    let mut q = vec![0x01, 99];
    q.extend_from_slice(&[0; 14]);
    let good = frame(0x0007, &q);
    let mut bytes = vec![0x47, 0xFF, 0xFF, 0x00, 0x12];
    bytes.extend_from_slice(&good);
    bytes.extend_from_slice(&good[..9]); // truncated by a reset
    bytes.extend_from_slice(&good);
    bytes.extend_from_slice(&[0xFF, 0x47]); // a frame that never comes
    let (packets, refused) = decode_all(&bytes);
    assert_eq!(packets.len(), 2, "{refused:?}");
    assert!(refused.iter().any(|r| r.contains("garbage")), "{refused:?}");
}

#[test]
fn the_encoder_writes_the_layouts_the_decoder_reads() {
    let packets = [
        Packet::Position(Position {
            time: HedgeTime::RealTime(5),
            x_mm: -7,
            y_mm: 8,
            z_mm: 9,
            flags: 2,
            address: 3,
            heading_raw: 900,
        }),
        Packet::Position(Position {
            time: HedgeTime::Counter(5),
            x_mm: 70_000,
            y_mm: -8,
            z_mm: 0,
            flags: 0,
            address: 1,
            heading_raw: 0,
        }),
        Packet::BeaconPositions(vec![
            BeaconPosition {
                address: 2,
                x_mm: 1,
                y_mm: 2,
                z_mm: 3
            };
            18
        ]),
        Packet::RawDistances(RawDistances {
            hedge: 1,
            distances: [BeaconDistance {
                beacon: 4,
                distance_mm: 3210,
            }; 4],
            time: HedgeTime::RealTime(-1),
            time_shift_ms: 65535,
        }),
        Packet::RawImu(RawImu {
            accel: [1, 2, 3],
            gyro: [i16::MIN, 0, i16::MAX],
            compass: [0; 3],
            time: HedgeTime::RealTime(i64::MAX),
        }),
        Packet::FusedImu(FusedImu {
            position_mm: [i32::MIN, 0, i32::MAX],
            quaternion: [1, 2, 3, 4],
            velocity_mm_s: [5, 6, 7],
            accel_mm_s2: [8, 9, 10],
            time: HedgeTime::Counter(u32::MAX),
        }),
        Packet::Telemetry(Telemetry {
            battery_mv: 1,
            rssi_dbm: i8::MIN,
        }),
    ];
    for p in packets {
        let bytes = p.encode().expect("fits a frame");
        assert_eq!(only(&bytes), p);
    }
    let too_many = Packet::BeaconPositions(vec![
        BeaconPosition {
            address: 1,
            x_mm: 0,
            y_mm: 0,
            z_mm: 0
        };
        19
    ]);
    assert_eq!(
        too_many.encode(),
        Err(PacketError::TooLong {
            code: 0x0012,
            bytes: 1 + 14 * 19
        })
    );
}

#[test]
fn a_short_real_time_packet_is_refused_by_its_length() {
    let (packets, refused) = decode_all(&frame(0x0084, &[0; 34]));
    assert!(packets.is_empty());
    // The rest of the frame is garbage, reported when a frame ends it.
    assert_eq!(refused.len(), 1, "{refused:?}");
    let frame_err = FrameError::BadLength {
        code: 0x0084,
        len: 34,
    };
    assert_eq!(refused[0], frame_err.to_string());
}
