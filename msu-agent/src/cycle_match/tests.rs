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
    recent.note(trigger(10, &[(1, 0), (2, 30), (3, 60)]), &book());
    recent.note(trigger(11, &[(2, 0), (4, 30)]), &book());
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
    recent.note(trigger(20, &[(1, 0), (2, 30)]), &book());
    recent.note(trigger(21, &[(2, 0), (1, 30)]), &book());
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
    recent.note(unknown, &book());
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
    recent.note(huge, &book());
    assert!(recent.best_for(&msg, &book(), &|_| None).is_none());
    let mut old = trigger(40, &[(1, 0)]);
    old.epoch = EPOCH - 1;
    recent.note(old, &book());
    assert!(
        recent.best_for(&msg, &book(), &|_| None).is_none(),
        "an older epoch is ignored"
    );
    recent.note(trigger(31, &[(1, 0)]), &book());
    assert!(
        recent.best_for(&msg, &book(), &|_| None).is_none(),
        "a repeated cycle is ignored"
    );
}

#[test]
fn at_most_the_kept_number_of_triggers_is_held() {
    let mut recent = RecentTriggers::default();
    for cycle in 0..100 {
        recent.note(trigger(cycle, &[(1, 0)]), &book());
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
    recent.note(trigger(50, &[(1, 0)]), &book());
    let mut plain = trigger(51, &[]);
    plain.cycle_period = Duration::ZERO;
    recent.note(plain, &book());
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

/// The flight times of `msg`'s transmitters, as the solver keeps them for
/// a deferred judgement.
fn flights_of(msg: &UltrasoundArrivals) -> Vec<(u32, i64)> {
    msg.arrivals
        .iter()
        .filter_map(|a| Some((a.tx_id, flights(a.tx_id)?)))
        .collect()
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
        recent.note(trigger(cycle, &SAME), &book());
    }
    let msg = heard_in_cycle(41, 37);
    // Nothing tells them apart but their starts: the newest wins, and
    // whether the choice is clear waits for the next trigger, which ties
    // with it too: nothing is learnt.
    let m = recent.best_for(&msg, &book(), &flights).unwrap();
    assert_eq!((m.trigger.cycle, m.clarity), (43, Clarity::AwaitingNext));
    recent.defer_learning(&m.trigger, msu_start_ns(43, 37), &msg, flights_of(&msg));
    recent.note(trigger(44, &SAME), &book());
    assert_eq!(recent.clock_offset_ns(), None);
    // A clock offset learnt (37 ms) from a cycle solved before.
    recent.learn_clock(&trigger(39, &SAME), msu_start_ns(39, 37));
    assert_eq!(recent.clock_offset_ns(), Some(37_000_000));
    for cycle in 40..44 {
        let m = recent
            .best_for(&heard_in_cycle(cycle, 37), &book(), &flights)
            .unwrap();
        assert_eq!((m.trigger.cycle, m.clarity), (cycle as u64, Clarity::Clear));
    }
    // Without a position the starts include the flight times: the offset
    // is not used, the newest wins, and it is never clear.
    let m = recent.best_for(&msg, &book(), &|_| None).unwrap();
    assert_eq!((m.trigger.cycle, m.clarity), (44, Clarity::Unclear));
}

#[test]
fn a_clear_choice_is_one_the_others_explain_more_than_twice_as_badly() {
    let mut recent = RecentTriggers::default();
    recent.note(trigger(58, &[(1, 0), (2, 30), (3, 66)]), &book());
    recent.note(trigger(59, &[(1, 0), (2, 36), (3, 60)]), &book());
    recent.note(trigger(60, &SAME), &book());
    recent.note(trigger(61, &[(1, 0), (2, 33), (3, 60)]), &book());
    // Cycle 57 of the window was not heard: nothing tells that it would
    // not have explained the arrivals as well.
    let m = recent
        .best_for(&heard_in_cycle(60, 5), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clarity), (60, Clarity::Unclear));
    let mut recent = RecentTriggers::default();
    for (cycle, firing) in [
        (57, [(1, 0), (2, 30), (3, 54)]),
        (58, [(1, 0), (2, 30), (3, 66)]),
        (59, [(1, 0), (2, 36), (3, 60)]),
        (60, SAME),
        (61, [(1, 0), (2, 33), (3, 60)]),
    ] {
        recent.note(trigger(cycle, &firing), &book());
    }
    let m = recent
        .best_for(&heard_in_cycle(60, 5), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clarity), (60, Clarity::Clear));
    // Without positions, the flight times hide a 3 ms difference no better.
    let m = recent
        .best_for(&heard_in_cycle(60, 5), &book(), &|_| None)
        .unwrap();
    assert_eq!(m.clarity, Clarity::Unclear);
}

#[test]
fn after_a_clock_step_the_offset_is_learnt_again() {
    let mut recent = RecentTriggers::default();
    for cycle in 70..74 {
        recent.note(trigger(cycle, &SAME), &book());
    }
    recent.learn_clock(&trigger(69, &SAME), msu_start_ns(69, 20));
    // The MSU clock steps 250 ms: no trigger fits the offset learnt.
    for _ in 0..MISFITS_BEFORE_RELEARN {
        let m = recent
            .best_for(&heard_in_cycle(71, 270), &book(), &flights)
            .unwrap();
        assert_ne!(m.clarity, Clarity::Clear, "a misfit is not learnt from");
    }
    // A cycle solved after the step (a clear choice, below) replaces what was learnt.
    recent.learn_clock(&trigger(72, &SAME), msu_start_ns(72, 270));
    assert_eq!(recent.clock_offset_ns(), Some(270_000_000));
    let m = recent
        .best_for(&heard_in_cycle(71, 270), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clarity), (71, Clarity::Clear));
}

#[test]
fn forged_start_times_and_extreme_stamps_neither_panic_nor_displace_the_cycle_heard() {
    let mut recent = RecentTriggers::default();
    for cycle in 80..83 {
        recent.note(trigger(cycle, &SAME), &book());
    }
    recent.learn_clock(&trigger(79, &SAME), msu_start_ns(79, 37));
    // Newer triggers naming the same transmitters, stamped at the ends of time.
    for (cycle, start) in [(83, i64::MAX), (84, i64::MIN)] {
        let mut forged = trigger(cycle, &SAME);
        forged.start = Time::from_nanos(start);
        recent.note(forged, &book());
    }
    let m = recent
        .best_for(&heard_in_cycle(81, 37), &book(), &flights)
        .unwrap();
    assert_eq!((m.trigger.cycle, m.clarity), (81, Clarity::Clear));
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

/// What a solver does with a choice for cycle `cycle`'s arrivals `msg`
/// (solved with a good fix, on an MSU clock 37 ms ahead).
fn solved(recent: &mut RecentTriggers, msg: &UltrasoundArrivals, cycle: i64) -> CycleTrigger {
    let m = recent.best_for(msg, &book(), &flights).unwrap();
    match m.clarity {
        Clarity::Clear => recent.learn_clock(&m.trigger, msu_start_ns(cycle, 37)),
        Clarity::AwaitingNext => {
            recent.defer_learning(&m.trigger, msu_start_ns(cycle, 37), msg, flights_of(msg))
        }
        Clarity::Unclear => {}
    }
    m.trigger
}

/// The next cycle's trigger races a cycle's arrivals to the MSU; a recorder
/// of the site can see the race end the other way. Either way the same
/// clock offset is learnt from the same cycles, and each cycle is solved
/// with the same firings: a replay reproduces the agent. (Before the
/// judgement waited for the next trigger, an MSU that heard cycle 50's
/// arrivals first learnt from it, and one that heard trigger 51 first, of
/// identical offsets, did not.)
#[test]
fn whether_the_next_trigger_comes_before_or_after_the_arrivals_the_same_is_learnt() {
    let wide = [(1, 0), (2, 33), (3, 60)];
    let late = [(1, 0), (2, 30), (3, 64)];
    let firings: [&[(u32, i64)]; 8] = [&SAME, &SAME, &wide, &wide, &SAME, &late, &SAME, &SAME];
    let first = 50;
    let run = |next_trigger_first: bool| {
        let mut recent = RecentTriggers::default();
        recent.note(trigger(first, firings[0]), &book());
        let mut seen = Vec::new();
        for (k, firing) in firings.iter().enumerate().take(firings.len() - 1) {
            let cycle = first + k as u64;
            let bursts: Vec<(u32, i64, i64)> = firing
                .iter()
                .map(|&(tx, ms)| (tx, ms, flights(tx).unwrap() / 1_000))
                .collect();
            let msg = heard(cycle as i64 * 100 + 37, &bursts);
            let next = trigger(cycle + 1, firings[k + 1]);
            let chosen = if next_trigger_first {
                recent.note(next, &book());
                solved(&mut recent, &msg, cycle as i64)
            } else {
                let chosen = solved(&mut recent, &msg, cycle as i64);
                recent.note(next, &book());
                chosen
            };
            seen.push((
                chosen.emissions(book().latest().unwrap()),
                recent.clock_offset_ns(),
            ));
        }
        seen
    };
    let (next_first, arrivals_first) = (run(true), run(false));
    assert_eq!(next_first, arrivals_first);
    // Nothing was learnt from the ties; the distinct cycle 55 taught the offset.
    assert_eq!(next_first[4].1, None);
    assert_eq!(next_first[5].1, Some(37_000_000));
}
