//! Occupancy firing on the live path: the MSU hears the cycle triggers and
//! solves each cycle's arrivals with the firings that explain them.

use super::tests::{C, TX, core_with};
use crate::events::{Event, Output};
use ickon_proto::msg::control::{CellStatus, SurveyCalibration};
use ickon_proto::msg::robot::Arrival;
use ickon_proto::time::{Duration, Time};

use super::*;

/// A trigger of cycle `cycle` firing `(tx, offset ms)` in that order.
fn trigger(cycle: u64, firing: &[(u32, i64)]) -> CycleTrigger {
    // Epoch 1: the core fixture's schedule.
    crate::cycle_match::tests::trigger_in(1, cycle, firing)
}

/// What a receiver at `p` hears when `firing` fires from a cycle start of
/// `start_s` on its clock.
fn heard(p: [f64; 3], start_s: f64, firing: &[(u32, i64)]) -> UltrasoundArrivals {
    let arrivals = firing
        .iter()
        .map(|&(id, ms)| {
            let t = TX.iter().find(|(k, _)| *k == id).unwrap().1;
            let d = ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt();
            Arrival {
                tx_id: id,
                receiver_id: 0,
                t_arrival: Time::from_secs_f64(start_s + ms as f64 / 1e3 + d / C),
            }
        })
        .collect();
    UltrasoundArrivals { seq: 3, arrivals }
}

/// A core whose robot has been heard (a gyro sample at `t_s` on its
/// clock): triggers before the robot's first input are ignored.
fn listening(estimator: &str, t_s: f64) -> MsuCore {
    let mut core = core_with(estimator);
    core.on_imu(&ickon_proto::msg::robot::Imu {
        stamp: Time::from_secs_f64(t_s),
        gyro_z_rad_s: 0.0,
    })
    .unwrap();
    core
}

fn fix_of(out: &[Output]) -> Option<&Fix> {
    out.iter().find_map(|o| match o {
        Output::Fix(f) => Some(f),
        _ => None,
    })
}

#[test]
fn arrivals_of_a_packed_cycle_are_solved_with_its_trigger_not_the_schedule() {
    let p = [1.7, 2.9, 0.5];
    // Four transmitters packed 12 ms apart, in an order the schedule (40 ms
    // apart, by id) does not have.
    let packed = [(4, 0), (2, 12), (1, 24), (3, 36)];
    let msg = heard(p, 20.0, &packed);

    let mut blind = core_with("msu-raw");
    let wrong = fix_of(&blind.handle(Event::Arrivals(msg.clone())))
        .map(|f| (f.x_m - p[0]).hypot(f.y_m - p[1]));
    assert!(
        wrong.is_none_or(|e| e > 0.5),
        "without the trigger the schedule's offsets cannot explain it: {wrong:?}"
    );

    let mut core = listening("msu-raw", 19.9);
    core.handle(Event::Trigger(trigger(40, &packed)));
    // The next cycle's trigger is out before this cycle's arrivals are in.
    core.handle(Event::Trigger(trigger(41, &[(5, 0), (3, 12), (2, 24)])));
    let out = core.handle(Event::Arrivals(msg));
    let fix = fix_of(&out).expect("a fix");
    assert!(
        (fix.x_m - p[0]).abs() < 1e-4 && (fix.y_m - p[1]).abs() < 1e-4,
        "{fix:?}"
    );
    assert_eq!(fix.used.len(), 4);
}

#[test]
fn a_trigger_of_the_whole_schedule_brings_back_the_schedule_offsets() {
    let p = [3.2, 1.1, 0.5];
    let mut core = core_with("msu-raw");
    core.handle(Event::Trigger(trigger(5, &[(1, 0), (2, 12)])));
    core.handle(Event::Trigger(CycleTrigger {
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
        ..trigger(6, &[])
    }));
    let all: Vec<(u32, i64)> = TX
        .iter()
        .enumerate()
        .map(|(i, (id, _))| (*id, 40 * i as i64))
        .collect();
    let out = core.handle(Event::Arrivals(heard(p, 30.0, &all)));
    let fix = fix_of(&out).expect("a fix");
    assert!((fix.x_m - p[0]).abs() < 1e-4 && (fix.y_m - p[1]).abs() < 1e-4);
    assert_eq!(fix.used.len(), 5);
}

/// The central unit sends a calibration right after cycle 43's trigger,
/// and the cell reports its sync sigma in a status made 50 ms into cycle
/// 41. Each cycle's arrivals race the next trigger and the status to the
/// MSU (and to a recorder, which can see the race end the other way).
/// Either way the calibration applies from cycle 44, the first triggered
/// after it, the sigma from cycle 42, the first started after the status,
/// and every fix, range difference and pose is the same. Before, each
/// applied to whichever arrivals were solved next.
#[test]
fn news_applies_from_the_cycle_it_names_however_the_arrivals_raced() {
    let p = [1.7, 2.9, 0.5];
    let firing = |cycle: u64| -> Vec<(u32, i64)> {
        if cycle.is_multiple_of(2) {
            vec![(1, 0), (2, 12), (3, 24), (4, 36)]
        } else {
            vec![(5, 0), (3, 12), (2, 24), (4, 36)]
        }
    };
    let calibration = SurveyCalibration {
        epoch: 1,
        version: 7,
        fixes_taken: 100,
        offsets: TX
            .iter()
            .map(|&(tx_id, _)| ickon_proto::msg::control::TransmitterOffset {
                tx_id,
                offset_m: [0.0, 0.0, if tx_id == 5 { 0.04 } else { 0.0 }],
                sigma_m: [0.005; 3],
                late_m: 0.0,
                late_sigma_m: 0.003,
                left_out: false,
            })
            .collect(),
        speed_of_sound_m_s: 0.0,
        speed_of_sound_sigma_m_s: 0.0,
    };
    let status = CellStatus {
        cell_id: "a".into(),
        stamp: Time::from_nanos(4_150_000_000),
        offset_ns: 0,
        drift_ppb: 0,
        offset_sigma_ns: 300_000,
        sync_samples: 20,
        last_cycle_fired: 41,
        cycles_fired: 41,
        slots_skipped: 0,
        faults: Vec::new(),
        inputs_refused: 0,
        device: String::new(),
    };
    let run = |next_trigger_first: bool| {
        let mut core = listening("tdoa-ekf", 3.9);
        core.handle(Event::Trigger(trigger(40, &firing(40))));
        let mut outputs = Vec::new();
        // The range differences each cycle is solved into (with their
        // clocks' sync sigmas), by a copy of the solver.
        let mut differences = Vec::new();
        let mut solve = |core: &mut MsuCore, msg: &UltrasoundArrivals| {
            let mut clock = core.clock;
            let solved = core.solver.clone().solve(msg, None, &mut clock);
            differences.push(solved.map(|s| s.range_differences));
            core.handle(Event::Arrivals(msg.clone()))
        };
        for cycle in 40..46u64 {
            // An MSU clock 37 ms ahead of the central unit's.
            let msg = heard(p, cycle as f64 * 0.1 + 0.037, &firing(cycle));
            let mut news = vec![Event::Trigger(trigger(cycle + 1, &firing(cycle + 1)))];
            match cycle + 1 {
                42 => news.push(Event::CellStatus(status.clone())),
                43 => news.push(Event::Survey(calibration.clone())),
                _ => {}
            }
            if !next_trigger_first {
                outputs.extend(solve(&mut core, &msg));
            }
            for event in news {
                core.handle(event);
            }
            if next_trigger_first {
                outputs.extend(solve(&mut core, &msg));
            }
        }
        (outputs, differences)
    };
    let ((news_won, differences), arrivals_won) = (run(true), run(false));
    assert_eq!(
        (&news_won, &differences),
        (&arrivals_won.0, &arrivals_won.1)
    );
    let sync_sigma_m: Vec<f64> = differences
        .iter()
        .map(|d| d.as_ref().unwrap()[0].clocks.unwrap()[0].sync_sigma_m)
        .collect();
    assert_eq!(sync_sigma_m[..2], [0.0, 0.0]);
    assert!(
        sync_sigma_m[2..]
            .iter()
            .all(|&s| (s - 300e-6 * C).abs() < 1e-12)
    );
    let versions: Vec<u32> = news_won
        .iter()
        .filter_map(|o| match o {
            Output::Fix(f) => Some(f.survey_version),
            _ => None,
        })
        .collect();
    assert_eq!(versions, [0, 0, 0, 0, 7, 7]);
    assert!(news_won.iter().any(|o| matches!(o, Output::Pose(_))));
}

/// Before its robot's first input the MSU takes no trigger: a replay of a
/// recording starts there and cannot tell which of the earlier ones the
/// agent heard. After it, the same trigger is taken.
#[test]
fn a_trigger_before_the_robots_first_input_is_ignored() {
    let p = [1.7, 2.9, 0.5];
    let packed = [(4, 0), (2, 12), (1, 24), (3, 36)];
    let msg = heard(p, 20.0, &packed);
    let solved_at = |core: &mut MsuCore| {
        fix_of(&core.handle(Event::Arrivals(msg.clone())))
            .map(|f| (f.x_m - p[0]).hypot(f.y_m - p[1]))
    };
    let mut deaf = core_with("msu-raw");
    deaf.handle(Event::Trigger(trigger(40, &packed)));
    assert!(solved_at(&mut deaf).is_none_or(|e| e > 0.5));
    let mut core = listening("msu-raw", 19.9);
    core.handle(Event::Trigger(trigger(40, &packed)));
    assert!(solved_at(&mut core).is_some_and(|e| e < 1e-4));
}

/// News held for a cycle while triggers were followed never overrides
/// newer news taken at once after the central unit went back to firing
/// the whole schedule.
#[test]
fn news_held_for_a_cycle_does_not_override_newer_news_once_the_whole_schedule_fires() {
    let p = [1.7, 2.9, 0.5];
    let firing = [(1, 0), (2, 12), (3, 24), (4, 36)];
    let calibration = |version: u32, dz: f64| SurveyCalibration {
        epoch: 1,
        version,
        fixes_taken: 100,
        offsets: vec![ickon_proto::msg::control::TransmitterOffset {
            tx_id: 5,
            offset_m: [0.0, 0.0, dz],
            sigma_m: [0.005; 3],
            late_m: 0.0,
            late_sigma_m: 0.003,
            left_out: false,
        }],
        speed_of_sound_m_s: 0.0,
        speed_of_sound_sigma_m_s: 0.0,
    };
    let status = |stamp_s: f64, sigma_ns: i64| CellStatus {
        cell_id: "a".into(),
        stamp: Time::from_secs_f64(stamp_s),
        offset_ns: 0,
        drift_ppb: 0,
        offset_sigma_ns: sigma_ns,
        sync_samples: 20,
        last_cycle_fired: 0,
        cycles_fired: 0,
        slots_skipped: 0,
        faults: Vec::new(),
        inputs_refused: 0,
        device: String::new(),
    };
    let mut core = listening("msu-raw", 3.9);
    core.handle(Event::Trigger(trigger(40, &firing)));
    // Held: for cycle 41 on.
    core.handle(Event::Survey(calibration(3, 0.01)));
    core.handle(Event::CellStatus(status(4.05, 100_000)));
    // The whole schedule fires from now on; newer news is taken at once.
    core.handle(Event::Trigger(CycleTrigger {
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
        ..trigger(41, &[])
    }));
    core.handle(Event::Survey(calibration(4, 0.02)));
    core.handle(Event::CellStatus(status(4.15, 20_000)));
    let all: Vec<(u32, i64)> = TX
        .iter()
        .enumerate()
        .map(|(i, (id, _))| (*id, 40 * i as i64))
        .collect();
    let msg = heard(p, 4.2, &all);
    let mut clock = core.clock;
    let differences = core
        .solver
        .clone()
        .solve(&msg, None, &mut clock)
        .unwrap()
        .range_differences;
    assert!(
        differences
            .iter()
            .all(|d| (d.clocks.unwrap()[0].sync_sigma_m - 20e-6 * C).abs() < 1e-12)
    );
    let fix = fix_of(&core.handle(Event::Arrivals(msg)))
        .cloned()
        .expect("a fix");
    assert_eq!(fix.survey_version, 4);
}
