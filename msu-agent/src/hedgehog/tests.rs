//! The hedgehog's stream as a real kit writes it (frames built with the
//! layout of `ickon-marvelmind`), cut and corrupted as a serial line does.

use ickon_marvelmind::{
    BeaconDistance as Slot, BeaconPosition, HedgeTime, Packet, Position, RawDistances, encode_frame,
};

use super::*;

fn beacons() -> Vec<TransmitterEntry> {
    [
        (11, [0.0, 0.0, 2.5]),
        (12, [5.0, 0.0, 2.5]),
        (13, [5.0, 4.0, 2.5]),
        (14, [0.0, 4.0, 2.5]),
    ]
    .into_iter()
    .map(|(id, p)| TransmitterEntry {
        tx_id: id,
        cell_id: "c1".into(),
        x_m: p[0],
        y_m: p[1],
        z_m: p[2],
    })
    .collect()
}

fn distances(slots: [(u8, u32); 4], shift_ms: u16) -> Vec<u8> {
    Packet::RawDistances(RawDistances {
        hedge: 7,
        distances: slots.map(|(beacon, distance_mm)| Slot {
            beacon,
            distance_mm,
        }),
        time: HedgeTime::Counter(1234),
        time_shift_ms: shift_ms,
    })
    .encode()
    .expect("fits a frame")
}

fn reader(settings: MarvelmindSettings, site_speed_m_s: f64) -> HedgehogReader {
    HedgehogReader::new(settings, site_speed_m_s, &beacons())
}

const NOW: Time = Time::from_nanos(5_000_000_000);

#[test]
fn raw_distances_become_a_reading_at_the_sites_speed_of_sound_before_the_time_shift() {
    let settings = MarvelmindSettings {
        speed_of_sound_m_s: 340.0,
        ..MarvelmindSettings::default()
    };
    let mut r = reader(settings, 346.8);
    let (inputs, problems) = r.feed(
        NOW,
        &distances([(11, 2000), (12, 3400), (0, 0), (0, 0)], 40),
    );
    assert!(problems.is_empty(), "{problems:?}");
    let [HedgehogInput::Distances(d)] = inputs.as_slice() else {
        panic!("{inputs:?}");
    };
    assert_eq!(d.stamp, NOW - Duration::from_millis(40));
    assert_eq!(d.distances.len(), 2, "empty slots are not distances");
    assert_eq!(d.distances[0].tx_id, 11);
    // 2.000 m measured at 340 m/s is 2.040 m at 346.8 m/s.
    assert!((d.distances[0].distance_m - 2.04).abs() < 1e-9, "{d:?}");
    assert!((d.distances[1].distance_m - 3.468).abs() < 1e-9, "{d:?}");
    assert_eq!(d.distances[0].sigma_m, DEFAULT_KIT_SIGMA_M);
    assert_eq!(r.counters().distances, 2);
}

#[test]
fn unknown_beacons_and_zero_distances_are_counted_not_used() {
    let mut r = reader(MarvelmindSettings::default(), 343.0);
    let (inputs, problems) = r.feed(
        NOW,
        &distances([(11, 2000), (99, 3000), (12, 0), (0, 0)], 0),
    );
    let [HedgehogInput::Distances(d)] = inputs.as_slice() else {
        panic!("{inputs:?}");
    };
    assert_eq!(
        d.distances.iter().map(|x| x.tx_id).collect::<Vec<_>>(),
        vec![11]
    );
    let c = r.counters();
    assert_eq!((c.unknown_beacons, c.absurd_distances), (1, 1));
    let kinds: Vec<_> = problems.iter().map(|p| p.0).collect();
    assert_eq!(kinds, vec!["unknown beacon", "absurd distance"]);
    // Nothing usable: no reading at all.
    let (inputs, _) = r.feed(NOW, &distances([(99, 2000), (0, 0), (0, 0), (0, 0)], 0));
    assert!(inputs.is_empty());
}

#[test]
fn a_time_shift_beyond_a_second_refuses_the_reading() {
    let mut r = reader(MarvelmindSettings::default(), 343.0);
    let (inputs, problems) = r.feed(
        NOW,
        &distances([(11, 2000), (12, 2000), (0, 0), (0, 0)], 60_000),
    );
    assert!(inputs.is_empty());
    assert_eq!(problems[0].0, "absurd distance");
    assert_eq!(r.counters().absurd_distances, 2);
}

#[test]
fn garbage_and_corrupt_frames_are_counted_and_the_stream_goes_on() {
    let mut r = reader(MarvelmindSettings::default(), 343.0);
    let good = distances([(11, 2000), (12, 2000), (13, 2000), (14, 2000)], 0);
    let mut bad = good.clone();
    bad[10] ^= 0xA5;
    let mut bytes = b"\x00\xFF garbage from a half-open port".to_vec();
    bytes.extend_from_slice(&bad);
    bytes.extend_from_slice(&good);
    // A frame of a code nobody reads, skipped by its length.
    bytes.extend_from_slice(&encode_frame(0x0201, &[1, 2, 3]).expect("short"));
    let mut inputs = Vec::new();
    for chunk in bytes.chunks(7) {
        inputs.extend(r.feed(NOW, chunk).0);
    }
    assert_eq!(inputs.len(), 1, "{inputs:?}");
    let c = r.counters();
    assert_eq!((c.frames, c.bad_crc, c.skipped), (2, 1, 1), "{c:?}");
    assert!(c.garbage_bytes >= 30, "{c:?}");
}

#[test]
fn the_kits_positions_are_inputs_only_when_asked_for_and_available() {
    let position = |flags| {
        Packet::Position(Position {
            time: HedgeTime::Counter(1),
            x_mm: 1500,
            y_mm: -250,
            z_mm: 300,
            flags,
            address: 7,
            heading_raw: 0,
        })
        .encode()
        .expect("fits")
    };
    let mut off = reader(MarvelmindSettings::default(), 343.0);
    assert!(off.feed(NOW, &position(0)).0.is_empty());
    assert_eq!(off.counters().kit_positions_unused, 1);

    let on = MarvelmindSettings {
        use_kit_positions: true,
        kit_position_sigma_m: 0.05,
        ..MarvelmindSettings::default()
    };
    let mut r = reader(on, 343.0);
    let (inputs, _) = r.feed(NOW, &position(0));
    assert_eq!(
        inputs,
        vec![HedgehogInput::KitPosition(KitPosition {
            stamp: NOW,
            x_m: 1.5,
            y_m: -0.25,
            sigma_m: 0.05
        })]
    );
    assert!(
        r.feed(NOW, &position(1)).0.is_empty(),
        "flag bit 0: not available"
    );
}

#[test]
fn the_raw_gyro_is_the_robots_only_with_a_stated_scale() {
    let imu = Packet::RawImu(ickon_marvelmind::RawImu {
        accel: [0, 0, 1000],
        gyro: [7, -3, -400],
        compass: [0, 0, 0],
        time: HedgeTime::Counter(10),
    })
    .encode()
    .expect("fits");
    let mut unscaled = reader(MarvelmindSettings::default(), 343.0);
    assert!(unscaled.feed(NOW, &imu).0.is_empty());
    assert_eq!(unscaled.counters().gyro_samples, 0);
    let scaled = MarvelmindSettings {
        gyro_rad_s_per_count: Some(0.001),
        ..MarvelmindSettings::default()
    };
    let mut r = reader(scaled, 343.0);
    let (inputs, problems) = r.feed(NOW, &imu);
    assert!(problems.is_empty(), "{problems:?}");
    assert_eq!(
        inputs,
        vec![HedgehogInput::Gyro(Imu {
            stamp: NOW,
            gyro_z_rad_s: -0.4
        })]
    );
    assert_eq!(r.counters().gyro_samples, 1);
}

#[test]
fn beacon_positions_that_disagree_with_the_site_are_warned_about() {
    let mut r = reader(MarvelmindSettings::default(), 343.0);
    let at = |address, x_mm, y_mm, z_mm| BeaconPosition {
        address,
        x_mm,
        y_mm,
        z_mm,
    };
    let frame = Packet::BeaconPositions(vec![
        at(11, 20, 0, 2500),
        at(12, 5000, 300, 2500),
        at(40, 0, 0, 0),
    ])
    .encode()
    .expect("fits");
    let (inputs, problems) = r.feed(NOW, &frame);
    assert!(inputs.is_empty());
    assert_eq!(problems.len(), 2, "{problems:?}");
    assert!(problems[0].1.contains("beacon 12"), "{problems:?}");
    assert!(problems[1].1.contains("beacon 40"), "{problems:?}");
}

proptest::proptest! {
    /// Whatever the line carries (random bytes around real frames, cut
    /// anywhere, forged distances and time shifts), the reader neither
    /// panics nor hands on a distance the site cannot have.
    #[test]
    fn any_bytes_are_read_without_panic_or_foreign_beacons(
        noise in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..600),
        slots in proptest::collection::vec((proptest::prelude::any::<u8>(), proptest::prelude::any::<u32>()), 4),
        shift in proptest::prelude::any::<u16>(),
        cut in 1usize..64,
    ) {
        let mut r = reader(MarvelmindSettings::default(), 343.0);
        let frame = distances(std::array::from_fn(|i| slots[i]), shift);
        let mut bytes = noise.clone();
        bytes.extend_from_slice(&frame);
        bytes.extend_from_slice(&noise);
        for chunk in bytes.chunks(cut) {
            for input in r.feed(NOW, chunk).0 {
                if let HedgehogInput::Distances(d) = input {
                    for x in d.distances {
                        proptest::prop_assert!((11..=14).contains(&x.tx_id));
                        proptest::prop_assert!(x.distance_m > 0.0 && x.distance_m.is_finite());
                    }
                    proptest::prop_assert!(d.stamp <= NOW);
                }
            }
        }
        proptest::prop_assert!(r.counters().frames >= 1);
    }
}
