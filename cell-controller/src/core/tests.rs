use super::*;

pub(super) const MS: i64 = 1_000_000;

use crate::fixtures::{EPOCH, schedule};

/// A cell whose clock reads master + `offset_ms`, driven until it has
/// synchronised; returns the core and the local time reached.
pub(super) fn synced_cell(offset_ms: i64) -> (CellCore, Time) {
    let mut now = Time::from_nanos(offset_ms * MS);
    let mut core = CellCore::new("c1", CellConfig::default(), now);
    let mut outputs = core.handle(now, Event::Tick);
    assert!(outputs.contains(&Output::RequestSchedule));
    core.handle(now, Event::ScheduleUnanswered);
    for _ in 0..200 {
        if outputs.contains(&Output::RequestClock) {
            // A symmetric 100 us exchange: the estimate is exact.
            let t1 = now;
            let master = Time::from_nanos(t1.as_nanos() - offset_ms * MS + 100_000);
            let sample = ClockSample {
                t1,
                t2: master,
                t3: master,
                t4: t1 + Duration::from_micros(200),
                epoch: EPOCH,
                queued_ns: 0,
            };
            now = now + Duration::from_micros(200);
            outputs = core.handle(now, Event::ClockExchange(Some(sample)));
        } else if outputs.contains(&Output::RequestSchedule) {
            outputs = core.handle(now, Event::ScheduleUnanswered);
        } else {
            now = core.next_wake();
            outputs = core.handle(now, Event::Tick);
        }
        if core.sync().estimate().is_some_and(|e| e.samples > 2) {
            break;
        }
    }
    (core, now)
}

/// Ticks the core through `until` (local), collecting what it fires.
pub(super) fn run_until(
    core: &mut CellCore,
    mut now: Time,
    until: Time,
) -> (Vec<PlannedBurst>, Time) {
    let mut fired = Vec::new();
    while core.next_wake() <= until {
        now = core.next_wake().max(now);
        for o in core.handle(now, Event::Tick) {
            match o {
                Output::Fire(b) => fired.push(b),
                Output::RequestClock => {
                    core.handle(now, Event::ClockExchange(None));
                }
                _ => {}
            }
        }
    }
    (fired, now)
}

#[test]
fn a_new_cell_asks_for_the_schedule_and_a_clock_exchange_at_once() {
    let mut core = CellCore::new("c1", CellConfig::default(), Time(0));
    let out = core.handle(Time(0), Event::Tick);
    assert!(out.contains(&Output::RequestClock), "{out:?}");
    assert!(out.contains(&Output::RequestSchedule), "{out:?}");
    // No second request while the first is out.
    let again = core.handle(Time(1), Event::Tick);
    assert!(!again.contains(&Output::RequestClock));
    assert!(!again.contains(&Output::RequestSchedule));
    // An unanswered query is repeated after the retry period, not before.
    core.handle(Time(2), Event::ScheduleUnanswered);
    let retry = Time(2) + CellConfig::default().schedule_retry;
    let early = core.handle(Time(retry.as_nanos() - 1), Event::Tick);
    assert!(!early.contains(&Output::RequestSchedule), "{early:?}");
    assert!(
        core.handle(retry, Event::Tick)
            .contains(&Output::RequestSchedule)
    );
}

#[test]
fn bursts_are_programmed_ahead_on_the_local_clock_and_counted() {
    let (mut core, now) = synced_cell(40);
    core.handle(now, Event::Schedule(schedule(4)));
    let start = Time::from_nanos(now.as_nanos() - 40 * MS + 300 * MS);
    core.handle(
        now,
        Event::Trigger(CycleTrigger {
            cycle: 3,
            start,
            schedule_version: 4,
            epoch: EPOCH,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        }),
    );
    let (fired, _) = run_until(&mut core, now, now + Duration::from_millis(400));
    let ids: Vec<u32> = fired.iter().map(|b| b.tx_id).collect();
    assert_eq!(ids, vec![11, 12], "only this cell's transmitters");
    assert_eq!(fired[0].local, start + Duration::from_millis(40));
    assert_eq!(fired[1].master, start + Duration::from_millis(25));
    let c = core.counters();
    assert_eq!(
        (c.cycles_fired, c.last_cycle_fired, c.slots_skipped),
        (1, 3, 0)
    );
}

#[test]
fn a_trigger_for_an_unknown_schedule_waits_for_it_and_skips_only_past_slots() {
    let (mut core, now) = synced_cell(0);
    let start = now + Duration::from_millis(100);
    let out = core.handle(
        now,
        Event::Trigger(CycleTrigger {
            cycle: 9,
            start,
            schedule_version: 7,
            epoch: EPOCH,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        }),
    );
    assert!(out.contains(&Output::RequestSchedule), "{out:?}");
    // The schedule comes back after the first slot has passed.
    let late = start + Duration::from_millis(5);
    let mut fired: Vec<PlannedBurst> = core
        .handle(late, Event::Schedule(schedule(7)))
        .into_iter()
        .filter_map(|o| match o {
            Output::Fire(b) => Some(b),
            _ => None,
        })
        .collect();
    fired.extend(run_until(&mut core, late, late + Duration::from_millis(300)).0);
    assert_eq!(
        fired.iter().map(|b| b.tx_id).collect::<Vec<_>>(),
        vec![12],
        "{:?}",
        core.counters()
    );
    assert_eq!(core.counters().slots_skipped, 1);
}

#[test]
fn without_a_clock_estimate_a_trigger_is_a_fault_not_a_burst() {
    let mut core = CellCore::new("c1", CellConfig::default(), Time(0));
    core.handle(Time(0), Event::Schedule(schedule(1)));
    core.handle(
        Time(0),
        Event::Trigger(CycleTrigger {
            cycle: 0,
            start: Time::from_nanos(500 * MS),
            schedule_version: 1,
            epoch: EPOCH,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        }),
    );
    assert_eq!(core.counters().triggers_unplanned, 1);
    let status = core.status(Time(0));
    assert_eq!(
        status.faults,
        vec!["clock not synchronised yet".to_string()]
    );
}

#[test]
fn a_returning_central_unit_is_asked_for_its_schedule_and_the_clock_checked() {
    let (mut core, now) = synced_cell(0);
    core.handle(now, Event::Schedule(schedule(2)));
    core.handle(now, Event::CentralAlive(false));
    // Gone: nothing is forgotten.
    assert!(core.sync().estimate().is_some());
    let out = core.handle(now, Event::CentralAlive(true));
    // The estimate stays (a changed master clock shows as a step).
    assert!(core.sync().estimate().is_some());
    assert!(out.contains(&Output::RequestSchedule), "{out:?}");
    // A second `true` (liveliness history) changes nothing.
    let again = core.handle(now, Event::CentralAlive(true));
    assert!(!again.contains(&Output::RequestSchedule));
}

#[test]
fn status_goes_out_every_period_with_the_master_time() {
    let (mut core, now) = synced_cell(40);
    let mut statuses = Vec::new();
    let mut t = now;
    while t < now + Duration::from_millis(2_500) {
        t = core.next_wake();
        for o in core.handle(t, Event::Tick) {
            match o {
                Output::Status(s) => statuses.push(s),
                Output::RequestClock => {
                    core.handle(t, Event::ClockExchange(None));
                }
                _ => {}
            }
        }
    }
    assert!((2..=3).contains(&statuses.len()), "{}", statuses.len());
    let s = &statuses[0];
    assert_eq!(s.cell_id, "c1");
    assert!(
        // Master minus local.
        (s.offset_ns + 40 * MS).abs() < 1_000,
        "offset {} ns",
        s.offset_ns
    );
}

#[test]
fn a_trigger_far_from_now_is_refused_and_holds_nothing() {
    let (mut core, now) = synced_cell(0);
    core.handle(now, Event::Schedule(schedule(4)));
    for k in 0..1_000u64 {
        core.handle(
            now,
            Event::Trigger(CycleTrigger {
                cycle: (1 << 62) + k,
                start: now + Duration::from_millis(3_600_000),
                schedule_version: 4,
                epoch: EPOCH,
                firing: Vec::new(),
                cycle_period: ickon_proto::time::Duration::ZERO,
            }),
        );
    }
    assert_eq!(core.counters().triggers_refused, 1_000);
    // Nothing pending: the next wake-up is a clock exchange or a status.
    assert!(core.next_wake() <= now + CellConfig::default().status_every);
    // A real trigger still fires.
    let start = now + Duration::from_millis(100);
    core.handle(
        now,
        Event::Trigger(CycleTrigger {
            cycle: 5,
            start,
            schedule_version: 4,
            epoch: EPOCH,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        }),
    );
    let (fired, _) = run_until(&mut core, now, now + Duration::from_millis(300));
    assert_eq!(fired.len(), 2);
}

#[test]
fn a_stopping_cell_drops_its_planned_bursts_says_so_and_then_does_nothing() {
    let (mut core, now) = synced_cell(40);
    core.handle(now, Event::Schedule(schedule(4)));
    let start = Time::from_nanos(now.as_nanos() - 40 * MS + 300 * MS);
    let trigger = CycleTrigger {
        cycle: 3,
        start,
        schedule_version: 4,
        epoch: EPOCH,
        firing: Vec::new(),
        cycle_period: ickon_proto::time::Duration::ZERO,
    };
    core.handle(now, Event::Trigger(trigger.clone()));
    let out = core.handle(now, Event::Shutdown);
    match out.as_slice() {
        [Output::Status(s)] => assert_eq!(s.faults, ["stopping: 2 planned bursts dropped"]),
        other => panic!("{other:?}"),
    }
    // Nothing fires, nothing is asked for, whatever comes after.
    assert!(core.handle(now, Event::Trigger(trigger)).is_empty());
    let (fired, _) = run_until(&mut core, now, now + Duration::from_millis(400));
    assert!(fired.is_empty(), "{fired:?}");
    assert!(
        core.handle(now + Duration::from_millis(5_000), Event::Tick)
            .is_empty()
    );
    assert_eq!(
        core.next_wake(),
        Time::from_nanos(i64::MAX),
        "never woken again"
    );
    assert_eq!(core.counters().cycles_fired, 0);
}

#[test]
fn skipped_slots_are_logged_at_powers_of_two_only() {
    let logged: Vec<u64> = (0..40u64)
        .filter(|&n| crosses_power_of_two(n, n + 1))
        .map(|n| n + 1)
        .collect();
    assert_eq!(logged, vec![1, 2, 4, 8, 16, 32]);
    // A plan that skips several at once logs when it passes one.
    assert!(crosses_power_of_two(5, 9));
    assert!(!crosses_power_of_two(9, 12));
    assert!(!crosses_power_of_two(3, 3));
}
