//! The MSU agent fed random and mutated inputs (fuzz targets, see
//! `ickon_proto::fuzz`): its core under every estimator with sequences of
//! schedules, arrivals, odometry, gyro and range samples with extreme
//! fields and stamps that jump both ways; its configuration file parser;
//! and the ROS 2 decoders of `--ros2` mode. Nothing panics, and what the
//! core publishes is finite.

use crate::beacons::{BeaconDistance, BeaconDistances, KitPosition};
use crate::ros2::inputs::{InputDecoder, InputTopic};
use crate::{Event, MsuConfig, MsuCore, MsuTuning, Output};
use ickon_fusion::estimator::{WheelGeometry, build_by_name, names};
use ickon_proto::fuzz::extreme::offset_ns;
use ickon_proto::fuzz::mutate::{apply, apply_text, mutations, text_mutations};
use ickon_proto::fuzz::values::draw;
use ickon_proto::fuzz::{config, config_for, entropy};
use ickon_proto::msg::control::{Emission, Schedule, TransmitterEntry};
use ickon_proto::msg::robot::{Imu, ObstacleRanges, Odometry, UltrasoundArrivals};
use ickon_proto::msg::ros;
use ickon_proto::ros::keys::{RosKeys, Transport};
use ickon_proto::time::{Duration, Time};
use proptest::prelude::*;

const TX: [(u32, [f64; 3]); 5] = [
    (1, [0.0, 0.0, 2.8]),
    (2, [5.0, 0.0, 2.6]),
    (3, [5.0, 4.0, 2.8]),
    (4, [0.0, 4.0, 2.6]),
    (5, [2.5, 2.0, 2.7]),
];

fn msu_config() -> MsuConfig {
    MsuConfig {
        speed_of_sound_m_s: 343.0,
        height_m: 0.5,
        receiver_angles_rad: (0..6).map(|i| f64::from(i) * 60f64.to_radians()).collect(),
        transmitters: TX
            .iter()
            .map(|(id, p)| TransmitterEntry {
                tx_id: *id,
                cell_id: "a".into(),
                x_m: p[0],
                y_m: p[1],
                z_m: p[2],
            })
            .collect(),
        wheels: WheelGeometry {
            wheel_base_m: 0.33,
            left_m_per_tick: 1e-4,
            right_m_per_tick: 1e-4,
        },
        timing_sigma_s: 10e-6,
        residual_gate_m: 0.05,
        floor_bounds_m: Some([[0.0, 0.0], [5.0, 4.0]]),
        max_fix_sigma_m: 0.5,
        walls: Vec::new(),
        columns: Vec::new(),
    }
}

fn schedule() -> Schedule {
    Schedule {
        version: 1,
        effective_cycle: 0,
        cycle_period: Duration::from_millis(200),
        slot_length: Duration::from_millis(40),
        emissions: TX
            .iter()
            .enumerate()
            .map(|(i, (id, _))| Emission {
                tx_id: *id,
                cell_id: "a".into(),
                offset: Duration::from_millis(40 * i as i64),
                slot: i as u32,
            })
            .collect(),
        active_cells: vec!["a".into()],
        epoch: 1,
    }
}

#[derive(Debug, Clone)]
struct Act {
    kind: u8,
    at: i64,
    e: Vec<u8>,
}

fn act() -> impl Strategy<Value = Act> {
    (any::<u8>(), offset_ns(2_000_000_000), entropy()).prop_map(|(kind, at, e)| Act { kind, at, e })
}

/// The arrivals of a robot at (2, 2) in cycle `k`, possibly with drawn ones mixed in.
fn arrivals(stamp: Time, a: &Act) -> Option<UltrasoundArrivals> {
    let mut m = draw::<UltrasoundArrivals>(&a.e)?;
    if a.e.first().is_some_and(|b| *b < 160) {
        for (i, (id, p)) in TX.iter().enumerate() {
            let d = ((2.0 - p[0]).powi(2) + (2.0 - p[1]).powi(2) + (0.5 - p[2]).powi(2)).sqrt();
            m.arrivals.push(ickon_proto::msg::robot::Arrival {
                tx_id: *id,
                receiver_id: a.kind % 6,
                t_arrival: stamp + Duration::from_secs_f64(0.04 * i as f64 + d / 343.0),
            });
        }
    }
    Some(m)
}

/// Distances to the site's transmitters from a robot at (2, 2) when
/// plausible; otherwise ids and distances straight from the entropy's bytes
/// (unknown ids, NaN, infinities, negatives, huge values, many of them).
fn beacon_distances(stamp: Time, a: &Act) -> BeaconDistances {
    let plausible = a.e.first().is_some_and(|b| *b < 160);
    let distances = if plausible {
        TX.iter()
            .map(|(id, p)| BeaconDistance {
                tx_id: *id,
                distance_m: ((2.0 - p[0]).powi(2) + (2.0 - p[1]).powi(2) + (0.5 - p[2]).powi(2))
                    .sqrt(),
                sigma_m: 0.02,
            })
            .collect()
    } else {
        a.e.chunks_exact(17)
            .map(|c| BeaconDistance {
                tx_id: u32::from(c[0]),
                distance_m: f64::from_le_bytes(c[1..9].try_into().expect("8 bytes")),
                sigma_m: f64::from_le_bytes(c[9..17].try_into().expect("8 bytes")),
            })
            .collect()
    };
    BeaconDistances { stamp, distances }
}

/// A ranging kit's own position: on the floor when plausible, otherwise
/// coordinates and sigma straight from the entropy's bytes.
fn kit_position(stamp: Time, a: &Act) -> KitPosition {
    let plausible = a.e.first().is_some_and(|b| *b < 160);
    let f = |i: usize| {
        a.e.get(8 * i..8 * i + 8).map_or(f64::NAN, |b| {
            f64::from_le_bytes(b.try_into().expect("8 bytes"))
        })
    };
    if plausible {
        KitPosition {
            stamp,
            x_m: 2.0,
            y_m: 2.0,
            sigma_m: 0.02,
        }
    } else {
        KitPosition {
            stamp,
            x_m: f(0),
            y_m: f(1),
            sigma_m: f(2),
        }
    }
}

fn event(now: Time, a: &Act) -> Option<Event> {
    let stamp = now + Duration::from_nanos(a.at);
    let plausible = a.e.first().is_some_and(|b| *b < 160);
    Some(match a.kind % 8 {
        0 => Event::Schedule(if plausible { schedule() } else { draw(&a.e)? }),
        1 | 2 => Event::Arrivals(arrivals(stamp, a)?),
        3 => Event::Odometry({
            let mut o = draw::<Odometry>(&a.e)?;
            if plausible {
                o.stamp = stamp;
            }
            o
        }),
        4 => Event::Imu({
            let mut o = draw::<Imu>(&a.e)?;
            if plausible {
                o.stamp = stamp;
            }
            o
        }),
        5 => Event::Trigger(draw::<ickon_proto::msg::control::CycleTrigger>(&a.e)?),
        6 if a.kind >= 128 => Event::KitPosition(kit_position(stamp, a)),
        6 => Event::BeaconDistances(beacon_distances(stamp, a)),
        _ => Event::Range({
            let mut o = draw::<ObstacleRanges>(&a.e)?;
            if plausible {
                o.stamp = stamp;
            }
            o
        }),
    })
}

fn run(estimator: usize, acts: &[Act]) -> Result<(), TestCaseError> {
    let name = names()[estimator % names().len()];
    let mut core = MsuCore::new(msu_config(), build_by_name(name).expect("known estimator"));
    let mut now = Time::from_nanos(10_000_000_000);
    for a in acts {
        now = now + Duration::from_millis(i64::from(a.kind / 6 % 8) * 25);
        let Some(ev) = event(now, a) else {
            continue;
        };
        for o in core.handle(ev) {
            match o {
                Output::Pose(p) => {
                    prop_assert!(
                        p.x_m.is_finite() && p.y_m.is_finite() && p.theta_rad.is_finite(),
                        "{name}: {p:?}"
                    );
                    prop_assert!(!p.covariance.iter().any(|v| v.is_nan()), "{name}: {p:?}");
                }
                Output::Fix(f) => {
                    prop_assert!(f.x_m.is_finite() && f.y_m.is_finite(), "{name}: {f:?}");
                }
                Output::Refused { .. } => {}
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config_for(48))]

    #[test]
    fn fuzz_msu_core(estimator in 0usize..16, acts in proptest::collection::vec(act(), 1..30)) {
        run(estimator, &acts)?;
    }
}

proptest! {
    #![proptest_config(config())]

    /// The MSU configuration file: random text and the shipped example mutated.
    #[test]
    fn fuzz_msu_config_file(
        text in prop_oneof![
            1 => "\\PC{0,200}",
            6 => text_mutations().prop_map(|m| apply_text(EXAMPLE, &m)),
        ],
    ) {
        if let Ok(t) = MsuTuning::from_toml(&text, "fuzz.toml") {
            // What it accepts names a real estimator.
            prop_assert!(names().contains(&t.estimator_name()));
        }
    }

    /// The `--ros2` decoders: odometry and IMU payloads (random, drawn and
    /// mutated), under both key conventions, with and without attachments.
    #[test]
    fn fuzz_ros2_inputs(
        samples in proptest::collection::vec(
            (any::<bool>(), entropy(), mutations(), any::<u8>(), proptest::collection::vec(any::<u8>(), 0..40)),
            1..12,
        ),
        rmw in any::<bool>(),
    ) {
        let keys = RosKeys::new(if rmw {
            Transport::RmwZenoh { domain: 0 }
        } else {
            Transport::Bridge { prefix: String::new() }
        });
        let wheels = msu_config().wheels;
        let mut decoder = InputDecoder::new(keys, wheels);
        for (odom, e, m, how, attachment) in samples {
            let mut payload = if odom {
                draw::<ros::Odometry>(&e).and_then(|v| ickon_proto::encode(&v).ok())
            } else {
                draw::<ros::Imu>(&e).and_then(|v| ickon_proto::encode(&v).ok())
            }
            .unwrap_or_default();
            if how & 1 == 0 {
                apply(&mut payload, &m);
            }
            let topic = if odom { InputTopic::Odom } else { InputTopic::Imu };
            let key = String::from_utf8_lossy(&attachment).into_owned();
            let attachment = (how & 2 == 0).then_some(attachment.as_slice());
            if let Ok(input) = decoder.decode(topic, &key, &payload, attachment) {
                match input {
                    crate::ros2::inputs::Ros2Input::Odometry(o) => {
                        prop_assert!(o.x_m.is_finite() && o.y_m.is_finite() && o.theta_rad.is_finite(), "{o:?}");
                    }
                    crate::ros2::inputs::Ros2Input::Imu(i) => {
                        prop_assert!(i.gyro_z_rad_s.is_finite(), "{i:?}");
                    }
                }
            }
        }
    }
}

/// The commented example configuration shipped with the agent.
const EXAMPLE: &str = include_str!("../../deploy/msu.toml");
