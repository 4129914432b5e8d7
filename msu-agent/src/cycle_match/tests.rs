use super::*;
use ickon_proto::msg::control::{Emission, Firing, Schedule};
use ickon_proto::msg::robot::Arrival;
use ickon_proto::time::{Duration, Time};

const EPOCH: u64 = 7;

fn book() -> ScheduleBook {
    let emissions = (1..=4)
        .map(|tx_id| Emission {
            tx_id,
            cell_id: "a".into(),
            offset: Duration::from_millis(100 * i64::from(tx_id - 1)),
            slot: tx_id - 1,
        })
        .collect();
    let mut book = ScheduleBook::new();
    book.offer(Schedule {
        version: 1,
        effective_cycle: 0,
        cycle_period: Duration::from_millis(400),
        slot_length: Duration::from_millis(100),
        emissions,
        active_cells: vec!["a".into()],
        epoch: EPOCH,
    })
    .unwrap();
    book
}

fn trigger(cycle: u64, firing: &[(u32, i64)]) -> CycleTrigger {
    trigger_in(EPOCH, cycle, firing)
}

/// A trigger of cycle `cycle` of `epoch` (cycles 100 ms apart) firing
/// `(tx, offset ms)` in that order.
pub(crate) fn trigger_in(epoch: u64, cycle: u64, firing: &[(u32, i64)]) -> CycleTrigger {
    CycleTrigger {
        cycle,
        start: Time::from_nanos(cycle as i64 * 100_000_000),
        schedule_version: 1,
        epoch,
        firing: firing
            .iter()
            .map(|&(tx_id, ms)| Firing {
                tx_id,
                offset: Duration::from_millis(ms),
            })
            .collect(),
        cycle_period: Duration::from_millis(100),
    }
}

/// Arrivals of bursts at the given offsets from a cycle start of `start_ms`
/// (MSU clock), each with its own flight time.
fn heard(start_ms: i64, bursts: &[(u32, i64, i64)]) -> UltrasoundArrivals {
    UltrasoundArrivals {
        seq: 1,
        arrivals: bursts
            .iter()
            .map(|&(tx_id, offset_ms, flight_us)| Arrival {
                tx_id,
                receiver_id: 0,
                t_arrival: Time::from_nanos((start_ms + offset_ms) * 1_000_000 + flight_us * 1_000),
            })
            .collect(),
    }
}

#[test]
fn the_trigger_naming_the_heard_transmitters_wins_over_a_newer_one() {
    let mut recent = RecentTriggers::default();
    recent.note(trigger(10, &[(1, 0), (2, 30), (3, 60)]));
    recent.note(trigger(11, &[(2, 0), (4, 30)]));
    let msg = heard(5_000, &[(1, 0, 4_000), (2, 30, 9_000), (3, 60, 6_000)]);
    assert_eq!(
        recent
            .best_for(&msg, &book(), &|_| None)
            .map(|m| m.trigger.cycle),
        Some(10)
    );
}

#[test]
fn among_triggers_naming_the_same_set_the_offsets_that_explain_the_times_win() {
    let mut recent = RecentTriggers::default();
    recent.note(trigger(20, &[(1, 0), (2, 30)]));
    recent.note(trigger(21, &[(2, 0), (1, 30)]));
    // Heard as cycle 20 fired: 1 first, 2 thirty milliseconds later.
    let msg = heard(9_000, &[(1, 0, 5_000), (2, 30, 7_000)]);
    assert_eq!(
        recent
            .best_for(&msg, &book(), &|_| None)
            .map(|m| m.trigger.cycle),
        Some(20)
    );
    let msg = heard(9_000, &[(2, 0, 5_000), (1, 30, 7_000)]);
    assert_eq!(
        recent
            .best_for(&msg, &book(), &|_| None)
            .map(|m| m.trigger.cycle),
        Some(21)
    );
}

#[test]
fn triggers_without_their_schedule_older_epochs_and_oversized_ones_are_not_used() {
    let mut recent = RecentTriggers::default();
    let mut unknown = trigger(30, &[(1, 0)]);
    unknown.schedule_version = 9;
    recent.note(unknown);
    let msg = heard(0, &[(1, 0, 1_000)]);
    assert!(recent.best_for(&msg, &book(), &|_| None).is_none());
    let mut huge = trigger(31, &[(1, 0)]);
    huge.firing = vec![
        Firing {
            tx_id: 1,
            offset: Duration::ZERO
        };
        5
    ];
    recent.note(huge);
    assert!(recent.best_for(&msg, &book(), &|_| None).is_none());
    let mut old = trigger(40, &[(1, 0)]);
    old.epoch = EPOCH - 1;
    recent.note(old);
    assert!(
        recent.best_for(&msg, &book(), &|_| None).is_none(),
        "an older epoch is ignored"
    );
    recent.note(trigger(31, &[(1, 0)]));
    assert!(
        recent.best_for(&msg, &book(), &|_| None).is_none(),
        "a repeated cycle is ignored"
    );
}

#[test]
fn at_most_the_kept_number_of_triggers_is_held() {
    let mut recent = RecentTriggers::default();
    for cycle in 0..100 {
        recent.note(trigger(cycle, &[(1, 0)]));
    }
    assert_eq!(recent.triggers.len(), TRIGGERS_KEPT);
    assert_eq!(
        recent.triggers.front().map(|t| t.cycle),
        Some(100 - TRIGGERS_KEPT as u64)
    );
}

#[test]
fn a_trigger_of_the_whole_schedule_forgets_the_others() {
    let mut recent = RecentTriggers::default();
    recent.note(trigger(50, &[(1, 0)]));
    let mut plain = trigger(51, &[]);
    plain.cycle_period = Duration::ZERO;
    recent.note(plain);
    assert!(recent.is_empty());
}

/// Flight times of transmitters 1-3 from where the receiver is, microseconds.
const FLIGHTS_US: [(u32, i64); 3] = [(1, 4_000), (2, 9_000), (3, 6_000)];

fn flights(tx_id: u32) -> Option<i64> {
    FLIGHTS_US
        .iter()
        .find(|(id, _)| *id == tx_id)
        .map(|&(_, us)| us * 1_000)
}

/// The arrivals of cycle `cycle` (start `cycle * 100` ms on the central
/// clock) on an MSU clock `clock_ms` ahead, bursts at 0, 30 and 60 ms.
fn heard_in_cycle(cycle: i64, clock_ms: i64) -> UltrasoundArrivals {
    heard(
        cycle * 100 + clock_ms,
        &[(1, 0, 4_000), (2, 30, 9_000), (3, 60, 6_000)],
    )
}

const SAME: [(u32, i64); 3] = [(1, 0), (2, 30), (3, 60)];

/// The start of cycle `cycle` read on an MSU clock `clock_ms` ahead of the
/// central unit's (cycles 100 ms apart), nanoseconds.
fn msu_start_ns(cycle: i64, clock_ms: i64) -> i64 {
    (cycle * 100 + clock_ms) * 1_000_000
}

#[test]
fn a_learnt_clock_offset_picks_the_cycle_heard_among_triggers_of_identical_offsets() {
    let mut recent = RecentTriggers::default();
    for cycle in 40..44 {
        recent.note(trigger(cycle, &SAME));
    }
    let msg = heard_in_cycle(41, 37);
    // Nothing tells them apart but their starts: the newest wins, and the
    // choice is not clear enough to learn from.
    let m = recent.best_for(&msg, &book(), &flights).unwrap();
    assert_eq!((m.trigger.cycle, m.clear), (43, false));
    // A clock offset learnt (37 ms) from a cycle solved before.
    recent.learn_clock(&trigger(39, &SAME), msu_start_ns(39, 37));
    assert_eq!(recent.clock_offset_ns(), Some(37_000_000));
    for cycle in 40..44 {
        let m = recent
            .best_for(&heard_in_cycle(cycle, 37), &book(), &flights)
            .unwrap();
        assert_eq!((m.trigger.cycle, m.clear), (cycle as u64, true));
    }
    // Without a position the starts include the flight times: the offset is not used.
    let m = recent.best_for(&msg, &book(), &|_| None).unwrap();
    assert_eq!(m.trigger.cycle, 43);
}

#[test]
fn a_clear_choice_is_one_the_others_explain_more_than_twice_as_badly() {
    let mut recent = RecentTriggers::default();
    recent.note(trigger(60, &SAME));
    recent.note(trigger(61, &[(1, 0), (2, 33), (3, 60)]));
    let m = recent
        .best_for(&heard_in_cycle(60, 5), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clear), (60, true));
    // Without positions, the flight times hide a 3 ms difference no better.
    let m = recent
        .best_for(&heard_in_cycle(60, 5), &book(), &|_| None)
        .unwrap();
    assert!(!m.clear);
}

#[test]
fn after_a_clock_step_the_offset_is_learnt_again() {
    let mut recent = RecentTriggers::default();
    for cycle in 70..74 {
        recent.note(trigger(cycle, &SAME));
    }
    recent.learn_clock(&trigger(69, &SAME), msu_start_ns(69, 20));
    // The MSU clock steps 250 ms: no trigger fits the offset learnt.
    for _ in 0..MISFITS_BEFORE_RELEARN {
        let m = recent
            .best_for(&heard_in_cycle(71, 270), &book(), &flights)
            .unwrap();
        assert!(!m.clear, "a misfit is not learnt from");
    }
    // A cycle solved after the step (a clear choice, below) replaces what was learnt.
    recent.learn_clock(&trigger(72, &SAME), msu_start_ns(72, 270));
    assert_eq!(recent.clock_offset_ns(), Some(270_000_000));
    let m = recent
        .best_for(&heard_in_cycle(71, 270), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clear), (71, true));
}

#[test]
fn forged_start_times_and_extreme_stamps_neither_panic_nor_displace_the_cycle_heard() {
    let mut recent = RecentTriggers::default();
    for cycle in 80..83 {
        recent.note(trigger(cycle, &SAME));
    }
    recent.learn_clock(&trigger(79, &SAME), msu_start_ns(79, 37));
    // Newer triggers naming the same transmitters, stamped at the ends of time.
    for (cycle, start) in [(83, i64::MAX), (84, i64::MIN)] {
        let mut forged = trigger(cycle, &SAME);
        forged.start = Time::from_nanos(start);
        recent.note(forged);
    }
    let m = recent
        .best_for(&heard_in_cycle(81, 37), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clear), (81, true));
    // Arrival stamps at the ends of time match something or nothing, without overflow.
    for t in [i64::MIN, i64::MAX] {
        let msg = UltrasoundArrivals {
            seq: 2,
            arrivals: (1..=3)
                .map(|tx_id| Arrival {
                    tx_id,
                    receiver_id: 0,
                    t_arrival: Time::from_nanos(t),
                })
                .collect(),
        };
        let _ = recent.best_for(&msg, &book(), &flights);
        let _ = recent.best_for(&msg, &book(), &|_| Some(i64::MAX));
        assert!(
            cycle_start_ns(
                &msg,
                &trigger(81, &SAME).emissions(&book().latest().unwrap().clone()),
                &flights
            )
            .is_some()
        );
    }
    // The learnt offset is still the real one.
    assert_eq!(recent.clock_offset_ns(), Some(37_000_000));
}
