//! Occupancy firing on the live path: the MSU hears the cycle triggers and
//! solves each cycle's arrivals with the firings that explain them.

use super::tests::{C, TX, core_with};
use crate::events::{Event, Output};
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

    let mut core = core_with("msu-raw");
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
