//! The cell controller's core fed random sequences of events (fuzz
//! target, see `ickon_proto::fuzz`): triggers and schedules with extreme
//! fields (near the ones it follows and not), clock answers of any epoch
//! and offset, unanswered queries, the central unit coming and going, and
//! a local clock that steps and jumps. It never panics, never fires a
//! burst twice, plans at most what a schedule holds, and its next wake-up
//! is never in the past.

use crate::sync::ClockSample;
use crate::{CellConfig, CellCore, Event, Output};
use ickon_proto::fuzz::extreme::{clock_step, offset_ns};
use ickon_proto::fuzz::values::draw;
use ickon_proto::fuzz::{config_for, entropy};
use ickon_proto::msg::control::{CycleTrigger, Emission, Schedule};
use ickon_proto::time::{Duration, Time};
use proptest::prelude::*;
use std::collections::BTreeSet;

const EPOCH: u64 = 1_700_000_000_000_000_000;

fn schedule(version: u32) -> Schedule {
    let e = |tx_id, cell: &str, ms| Emission {
        tx_id,
        cell_id: cell.into(),
        offset: Duration::from_millis(ms),
        slot: 0,
    };
    Schedule {
        version,
        effective_cycle: 0,
        cycle_period: Duration::from_millis(200),
        slot_length: Duration::from_millis(25),
        emissions: vec![e(11, "c1", 0), e(12, "c1", 25), e(21, "c2", 0)],
        active_cells: vec!["c1".into(), "c2".into()],
        epoch: EPOCH,
    }
}

#[derive(Debug, Clone)]
struct Act {
    kind: u8,
    step: Duration,
    e: Vec<u8>,
    off: i64,
}

fn act() -> impl Strategy<Value = Act> {
    (
        any::<u8>(),
        clock_step(),
        entropy(),
        offset_ns(1_000_000_000),
    )
        .prop_map(|(kind, step, e, off)| Act { kind, step, e, off })
}

/// The master time the fuzzed cell's clock maps to (it runs 3 ms ahead).
fn master(local: Time) -> Time {
    local - Duration::from_millis(3)
}

fn event(now: Time, cycle: &mut u64, a: &Act) -> Option<Event> {
    let e = &a.e;
    let plausible = e.first().is_some_and(|b| *b < 200);
    Some(match a.kind % 9 {
        0 | 1 => Event::Tick,
        2 => {
            let mut t = draw::<CycleTrigger>(e)?;
            if plausible {
                // The next cycle of the fixture's central unit, or a forgery near it.
                *cycle += 1;
                t.epoch = EPOCH;
                t.cycle = *cycle;
                t.start =
                    master(now) + Duration::from_millis(60) + Duration::from_nanos(a.off / 100);
                t.schedule_version = 1;
            }
            Event::Trigger(t)
        }
        3 => Event::Schedule(if plausible {
            let mut s = schedule(1 + u32::from(a.kind & 1));
            if a.kind & 2 == 0 {
                s.emissions.truncate(usize::from(a.kind >> 6));
            }
            s
        } else {
            draw::<Schedule>(e)?
        }),
        4 => Event::ScheduleUnanswered,
        5 => {
            let t1 = now;
            let m = master(now) + Duration::from_nanos(a.off);
            let sample = ClockSample {
                t1,
                t2: m,
                t3: m + Duration::from_micros(50),
                t4: t1 + Duration::from_micros(200),
                epoch: if plausible { EPOCH } else { draw::<u64>(e)? },
                queued_ns: 0,
            };
            Event::ClockExchange((a.kind & 0x80 == 0).then_some(sample))
        }
        6 => Event::ClockExchange(
            draw::<(i64, i64, i64, i64, u64)>(e).map(|(a, b, c, d, ep)| ClockSample {
                t1: Time(a),
                t2: Time(b),
                t3: Time(c),
                t4: Time(d),
                epoch: ep,
                queued_ns: 0,
            }),
        ),
        7 => Event::CentralAlive(a.kind & 0x80 == 0),
        _ => Event::Shutdown,
    })
}

fn run(acts: &[Act]) -> Result<(), TestCaseError> {
    let mut now = Time::from_nanos(EPOCH as i64 + 5_000_000_000);
    let mut core = CellCore::new("c1", CellConfig::default(), now);
    let mut cycle = 0;
    let mut fired = BTreeSet::new();
    for a in acts {
        now = now + a.step;
        // Shutdown is final: keep it rare so the rest is reached.
        if a.kind % 9 == 8 && a.kind < 250 {
            continue;
        }
        let Some(ev) = event(now, &mut cycle, a) else {
            continue;
        };
        let out = core.handle(now, ev);
        prop_assert!(out.len() <= 64, "{} outputs", out.len());
        for o in &out {
            if let Output::Fire(b) = o {
                prop_assert!(
                    fired.insert((b.epoch, b.cycle, b.tx_id)),
                    "fired twice: {b:?}"
                );
            }
        }
        if now < Time::from_nanos(i64::MAX / 2) {
            prop_assert!(core.next_wake() > now, "wake {} at {now}", core.next_wake());
        }
        core.status(now);
    }
    Ok(())
}

proptest! {
    #![proptest_config(config_for(64))]

    #[test]
    fn fuzz_cell_core(acts in proptest::collection::vec(act(), 1..40)) {
        run(&acts)?;
    }
}
