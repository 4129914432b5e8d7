//! A cycle with as many reflections as direct signals: no majority agrees,
//! so the first solve gives no fix or a suspect one (here 0.7 m off); the
//! transmitters a wall hides from
//! where the last good fix put the robot can only be reflections, and
//! without them the cycle gives its fix.

use super::*;
use ickon_fusion::estimator::WheelGeometry;
use ickon_fusion::estimator::build_by_name;
use ickon_proto::msg::control::Emission;
use ickon_proto::msg::control::TransmitterEntry;
use ickon_proto::msg::robot::{Arrival, Odometry};
use ickon_proto::site::Wall;

const C: f64 = 343.0;
/// In the robot's room.
const DIRECT: [(u32, [f64; 3]); 5] = [
    (1, [1.0, 0.5, 2.8]),
    (2, [9.0, 0.5, 2.8]),
    (3, [1.0, 2.5, 2.6]),
    (4, [9.0, 2.5, 2.6]),
    (5, [5.0, 0.3, 2.7]),
];
/// Behind the wall at y = 4 (3 m high), each heard this much late.
const HIDDEN: [(u32, [f64; 3], f64); 5] = [
    (11, [1.0, 6.0, 2.8], 0.40),
    (12, [3.5, 6.0, 2.6], 0.70),
    (13, [6.5, 6.0, 2.8], 1.00),
    (14, [9.0, 6.0, 2.6], 0.55),
    (15, [5.0, 7.0, 2.7], 0.85),
];
const ROBOT: [f64; 3] = [5.0, 1.5, 0.5];

fn all() -> Vec<(u32, [f64; 3])> {
    DIRECT
        .iter()
        .copied()
        .chain(HIDDEN.iter().map(|&(id, p, _)| (id, p)))
        .collect()
}

fn core(with_wall: bool) -> MsuCore {
    let walls = vec![Wall {
        from: [-1.0, 4.0],
        to: [11.0, 4.0],
        height_m: 3.0,
    }];
    let config = MsuConfig {
        speed_of_sound_m_s: C,
        height_m: ROBOT[2],
        receiver_angles_rad: vec![0.0],
        transmitters: all()
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
        floor_bounds_m: Some([[0.0, 0.0], [10.0, 8.0]]),
        max_fix_sigma_m: 0.5,
        walls: if with_wall { walls } else { Vec::new() },
        columns: Vec::new(),
    };
    let mut core = MsuCore::new(config, build_by_name("msu-raw").unwrap());
    core.set_schedule(Schedule {
        version: 1,
        effective_cycle: 0,
        cycle_period: Duration::from_millis(500),
        slot_length: Duration::from_millis(40),
        emissions: all()
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
    })
    .unwrap();
    // A robot standing still: its odometry from 9.9 s to 11.5 s.
    for k in 0..=80 {
        core.on_odometry(&Odometry {
            stamp: Time::from_secs_f64(9.9 + 0.02 * f64::from(k)),
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            left_ticks: 0,
            right_ticks: 0,
        })
        .unwrap();
    }
    core
}

/// Distance from the robot's receiver to transmitter `t`, metres.
fn range_m(t: [f64; 3]) -> f64 {
    ((ROBOT[0] - t[0]).powi(2) + (ROBOT[1] - t[1]).powi(2) + (ROBOT[2] - t[2]).powi(2)).sqrt()
}

/// The cycle starting at `start_s`: the direct signals, and the hidden
/// transmitters' reflections when `reflections`.
fn cycle(seq: u64, start_s: f64, reflections: bool) -> UltrasoundArrivals {
    let late: Vec<(u32, [f64; 3], f64)> = DIRECT
        .iter()
        .map(|&(id, p)| (id, p, 0.0))
        .chain(HIDDEN.iter().copied().filter(|_| reflections))
        .collect();
    let slot = |id: u32| all().iter().position(|(k, _)| *k == id).unwrap() as f64;
    let arrivals = late
        .iter()
        .map(|&(id, t, extra)| {
            let d = range_m(t);
            Arrival {
                tx_id: id,
                receiver_id: 0,
                t_arrival: Time::from_secs_f64(start_s + 0.04 * slot(id) + (d + extra) / C),
            }
        })
        .collect();
    UltrasoundArrivals { seq, arrivals }
}

#[test]
fn without_the_hidden_transmitters_a_cycle_of_half_reflections_gives_its_fix() {
    // No wall known: half the cycle is reflections, no majority, no good fix.
    let mut blind = core(false);
    assert!(blind.on_arrivals(&cycle(1, 10.0, false)).unwrap().is_some());
    assert!(not_good(blind.on_arrivals(&cycle(2, 10.5, true)).unwrap()));

    let mut core = core(true);
    let first = core.on_arrivals(&cycle(1, 10.0, false)).unwrap().unwrap();
    assert_eq!(first.quality, ickon_proto::msg::robot::FixQuality::Good);
    let fix = core.on_arrivals(&cycle(2, 10.5, true)).unwrap().unwrap();
    assert!(
        (fix.x_m - ROBOT[0]).abs() < 1e-3 && (fix.y_m - ROBOT[1]).abs() < 1e-3,
        "{fix:?}"
    );
    let mut rejected = fix.rejected.clone();
    rejected.sort_unstable();
    assert_eq!(rejected, vec![11, 12, 13, 14, 15]);
    assert_eq!(fix.used.len(), 5);
}

#[test]
fn without_a_recent_good_fix_nothing_is_set_aside() {
    // The first cycle already carries the reflections: nothing says where
    // the robot is, so no transmitter counts as hidden.
    let mut core = core(true);
    assert!(not_good(core.on_arrivals(&cycle(1, 10.0, true)).unwrap()));
    // A good fix more than a second old places it no more.
    let mut core = super::hidden_tests::core(true);
    assert!(core.on_arrivals(&cycle(1, 10.0, false)).unwrap().is_some());
    assert!(not_good(core.on_arrivals(&cycle(2, 11.2, true)).unwrap()));
}

/// No fix, or a suspect one that set nothing aside.
fn not_good(fix: Option<Fix>) -> bool {
    fix.is_none_or(|f| {
        f.quality == ickon_proto::msg::robot::FixQuality::Suspect && f.rejected.is_empty()
    })
}

#[test]
fn the_tight_filter_never_gets_a_hidden_transmitters_arrival() {
    // The same cycle of half reflections, as range differences: with the
    // wall known, the hidden transmitters' arrivals are left out (the
    // direct ones are paired among themselves); without it, all are there.
    let hidden_m: Vec<[f64; 3]> = HIDDEN.iter().map(|&(_, p, _)| p).collect();
    for (with_wall, pairs) in [(true, DIRECT.len() - 1), (false, all().len() - 1)] {
        let mut core = core(with_wall);
        assert!(core.on_arrivals(&cycle(1, 10.0, false)).unwrap().is_some());
        let solved = core
            .solver
            .solve(&cycle(2, 10.5, true), None, &mut core.clock)
            .unwrap();
        let differences = &solved.range_differences;
        assert_eq!(differences.len(), pairs, "wall known: {with_wall}");
        let any_hidden = differences
            .iter()
            .any(|d| hidden_m.contains(&d.a_m) || hidden_m.contains(&d.b_m));
        assert_eq!(any_hidden, !with_wall);
        // Each difference is still exact for the direct pairs.
        for d in differences.iter().filter(|_| with_wall) {
            assert!(
                (d.d_m - (range_m(d.b_m) - range_m(d.a_m))).abs() < 1e-6,
                "{d:?}"
            );
        }
    }
}
