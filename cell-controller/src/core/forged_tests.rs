//! Forged and faulty control messages, each refused,
//! counted and reported, the cell's own bursts unaffected.

use super::tests::{MS, run_until, synced_cell};
use super::*;
use crate::fixtures::{EPOCH, schedule};

fn trigger(epoch: u64, cycle: u64, start: Time) -> CycleTrigger {
    CycleTrigger {
        cycle,
        start,
        schedule_version: 4,
        epoch,
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
    }
}

/// A synced cell with schedule v4 that has fired cycle 0 (starting 100 ms
/// after `now`); returns it, the local time after the cycle and cycle 0's start.
fn firing_cell() -> (CellCore, Time, Time) {
    let (mut core, now) = synced_cell(0);
    core.handle(now, Event::Schedule(schedule(4)));
    let start = now + Duration::from_millis(100);
    core.handle(now, Event::Trigger(trigger(EPOCH, 0, start)));
    let (fired, now) = run_until(&mut core, now, start + Duration::from_millis(60));
    assert_eq!(fired.len(), 2);
    (core, now, start)
}

/// Fires cycle `cycle` (of `epoch`, starting at `start`) and returns what fired.
fn fire(core: &mut CellCore, now: Time, epoch: u64, cycle: u64, start: Time) -> Vec<PlannedBurst> {
    core.handle(now, Event::Trigger(trigger(epoch, cycle, start)));
    run_until(core, now, start + Duration::from_millis(60)).0
}

#[test]
fn an_empty_schedule_under_the_current_version_is_refused_and_the_cell_fires_on() {
    let (mut core, now, start) = firing_cell();
    let mut empty = schedule(4);
    empty.emissions.clear();
    core.handle(now, Event::Schedule(empty));
    assert_eq!(core.counters().schedules_refused, 1);
    let period = Duration::from_millis(200);
    let fired = fire(&mut core, now, EPOCH, 1, start + period);
    assert_eq!(fired.len(), 2, "both transmitters fire as before");
    assert_eq!(core.status(now).inputs_refused, 1, "reported");
}

#[test]
fn a_schedule_of_a_newer_epoch_with_nothing_to_fire_is_refused_and_the_cell_fires_on() {
    let (mut core, now, start) = firing_cell();
    let mut empty = schedule(1);
    empty.epoch = EPOCH + 1;
    empty.emissions.clear();
    core.handle(now, Event::Schedule(empty));
    assert_eq!(core.counters().schedules_refused, 1);
    let period = Duration::from_millis(200);
    let fired = fire(&mut core, now, EPOCH, 1, start + period);
    assert_eq!(fired.len(), 2, "the epoch followed is unchanged");
}

#[test]
fn a_trigger_with_cycle_2_pow_62_is_refused_and_the_count_goes_on() {
    let (mut core, now, start) = firing_cell();
    let period = Duration::from_millis(200);
    // Well placed in time, absurd in number.
    let fired = fire(&mut core, now, EPOCH, 1 << 62, start + period);
    assert!(fired.is_empty(), "{fired:?}");
    assert_eq!(core.counters().triggers_refused, 1);
    let now = now + period;
    let fired = fire(&mut core, now, EPOCH, 2, start + period * 2);
    assert_eq!(fired.len(), 2);
    assert!(fired.iter().all(|b| b.cycle == 2 && b.epoch == EPOCH));
}

#[test]
fn a_rogue_clock_answer_is_refused_and_the_estimate_stays() {
    let (mut core, now, _) = firing_cell();
    let before = core.sync().estimate().unwrap();
    // An answer 300 ms off, from a node that is not the central unit
    // followed (another epoch)...
    let rogue = |epoch| ClockSample {
        t1: now,
        t2: now + Duration::from_millis(300),
        t3: now + Duration::from_millis(300),
        t4: now + Duration::from_micros(200),
        epoch,
        queued_ns: 0,
    };
    core.handle(now, Event::ClockExchange(Some(rogue(EPOCH + 1))));
    // ...and the same with the right epoch: one answer is not a clock step.
    core.handle(now, Event::ClockExchange(Some(rogue(EPOCH))));
    let c = core.counters();
    assert_eq!((c.clock_answers_refused, c.clock_steps), (2, 0));
    let after = core.sync().estimate().unwrap();
    assert!((after.offset_ns - before.offset_ns).abs() < 1_000.0);
    assert_eq!(core.status(now).inputs_refused, 2);
}

#[test]
fn three_agreeing_exchanges_are_a_clock_step() {
    let (mut core, mut now, _) = firing_cell();
    for _ in 0..3 {
        let stepped = ClockSample {
            t1: now,
            t2: now + Duration::from_millis(5),
            t3: now + Duration::from_millis(5),
            t4: now + Duration::from_micros(200),
            epoch: EPOCH,
            queued_ns: 0,
        };
        core.handle(now, Event::ClockExchange(Some(stepped)));
        now = now + Duration::from_millis(20);
    }
    assert_eq!(core.counters().clock_steps, 1);
}

#[test]
fn a_restarted_central_units_cycle_0_fires_at_once_and_the_old_one_is_fenced() {
    let (mut core, now, start) = firing_cell();
    // The old central unit's cycle 1 is planned...
    let period = Duration::from_millis(200);
    core.handle(now, Event::Trigger(trigger(EPOCH, 1, start + period)));
    // ...when a restarted one (a later epoch, versions from 1) takes over.
    let epoch = EPOCH + 10 * MS as u64;
    let mut fresh = schedule(1);
    fresh.epoch = epoch;
    core.handle(now, Event::Schedule(fresh));
    let new_start = start + period + Duration::from_millis(50);
    let t0 = CycleTrigger {
        cycle: 0,
        start: new_start,
        schedule_version: 1,
        epoch,
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
    };
    core.handle(now, Event::Trigger(t0));
    let (fired, now) = run_until(&mut core, now, new_start + Duration::from_millis(60));
    assert!(
        fired.iter().all(|b| b.epoch == epoch && b.cycle == 0),
        "the old epoch's planned bursts are dropped: {fired:?}"
    );
    assert_eq!(fired.len(), 2);
    // The old central unit, still sending, is refused.
    let old = fire(&mut core, now, EPOCH, 2, new_start + period);
    assert!(old.is_empty());
    assert_eq!(core.counters().triggers_refused, 1);
    assert_eq!(core.epoch(), Some(epoch));
}

/// A local clock set back 5 s left every deadline 5 s ahead: no exchange
/// noticed the step, so the cell fired nothing for 5 s.
#[test]
fn a_local_clock_stepped_back_asks_for_an_exchange_at_once() {
    let (mut core, now, _) = firing_cell();
    assert!(core.next_wake() > now);
    let back = now - Duration::from_millis(5_000);
    let out = core.handle(back, Event::Tick);
    assert!(out.contains(&Output::RequestClock), "{out:?}");
    assert!(core.next_wake() <= back + CellConfig::default().status_every);
    // A clock that only went back within the tolerance changes nothing.
    let (mut core, now, _) = firing_cell();
    let wake = core.next_wake();
    let out = core.handle(now - Duration::from_micros(500), Event::Tick);
    assert!(!out.contains(&Output::RequestClock), "{out:?}");
    assert_eq!(core.next_wake(), wake);
}
