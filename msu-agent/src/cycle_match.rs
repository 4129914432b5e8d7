//! Which cycle trigger a message of arrivals belongs to, when the central
//! unit names the transmitters of each cycle (occupancy firing, issue 20).
//!
//! The MSU hears bursts on its own clock and has no cycle number: a cycle's
//! arrivals come after its trigger and often after the next one's. So each
//! recent trigger is tried as an explanation: it must name the transmitters
//! heard (the most of them wins), and its offsets must explain the arrival
//! times: `t_i - offset_i - flight_i` is the cycle's start on the MSU clock
//! for every arrival, `flight_i` the flight time from where the receiver
//! last had a fix (0 when it has none).
//!
//! Consecutive triggers often name the same transmitters at offsets a few
//! tens of microseconds apart (the spacings follow where the robots are),
//! and taking a neighbour's costs centimetres; the spread of the starts
//! cannot tell them apart. Their start times can: they are a cycle apart.
//! So the MSU learns its clock's offset from the central unit's (the
//! median of [`CLOCK_OFFSETS_KEPT`] cycles solved with a good fix) and
//! takes the trigger whose start that offset explains, within
//! [`CLOCK_GATE`]. Until it knows the offset, and when no trigger fits it,
//! the tightest spread of the starts wins (the least summed distance from
//! their median), the newest trigger breaking a tie; the offset is learnt
//! only from such a choice when it was clear (every other trigger spread
//! more than twice as wide), so that a neighbour of identical offsets is
//! never learnt as the right one. After [`MISFITS_BEFORE_RELEARN`] cycles
//! in a row that no trigger fits (a stepped clock, another central unit),
//! the offset is learnt again.

use std::collections::VecDeque;

use ickon_proto::epoch::ScheduleBook;
use ickon_proto::msg::control::{CycleTrigger, Emission};
use ickon_proto::msg::robot::{Arrival, UltrasoundArrivals};
use ickon_proto::time::Duration;

/// Triggers kept to be matched: a cycle's arrivals reach the MSU within a
/// cycle or two of its trigger.
pub const TRIGGERS_KEPT: usize = 8;

/// Clock offsets kept, one per cycle solved with a good fix.
pub const CLOCK_OFFSETS_KEPT: usize = 8;

/// How far a trigger's start may lie from where the learnt clock offset
/// puts the cycle heard. Far under the shortest cycle (87 ms: one robot on
/// `warehouse`), far over a fix's error in time (0.1 m is 0.3 ms), the
/// drift of two crystals over the offsets kept (20 ppm of a few seconds:
/// 0.1 ms) and the detection jitter.
pub const CLOCK_GATE: Duration = Duration::from_millis(10);

/// Cycles in a row that no trigger fits before the clock offset is learnt again.
pub const MISFITS_BEFORE_RELEARN: u32 = 3;

/// The recent triggers of the epoch followed, newest last, and the MSU
/// clock's offset from the central unit's.
#[derive(Debug, Clone, Default)]
pub struct RecentTriggers {
    triggers: VecDeque<CycleTrigger>,
    /// MSU clock minus central clock at the last cycles solved, nanoseconds.
    clock_offsets_ns: VecDeque<i64>,
    misfits: u32,
}

/// The trigger chosen for a message of arrivals.
#[derive(Debug, Clone, PartialEq)]
pub struct Matched {
    /// The trigger whose firings the arrivals are solved with.
    pub trigger: CycleTrigger,
    /// Whether the choice may teach the clock offset: it fitted the learnt
    /// offset, or every other trigger spread the starts more than twice as
    /// wide (a tie is never clear).
    pub clear: bool,
}

/// One trigger tried on a message.
struct Candidate<'a> {
    trigger: &'a CycleTrigger,
    covered: usize,
    deviation_ns: i64,
    /// Where the trigger puts the MSU clock's offset, nanoseconds.
    clock_offset_ns: i64,
}

impl RecentTriggers {
    /// Keeps `trigger` (the oldest kept goes beyond [`TRIGGERS_KEPT`]); one
    /// of an older epoch than the newest kept, or a repeat, is ignored. A
    /// trigger that names no firings and no period (the whole schedule
    /// fires, as before issue 20) forgets them all: arrivals are then
    /// matched to the newest schedule, exactly as without triggers.
    pub fn note(&mut self, trigger: CycleTrigger) {
        if trigger.firing.is_empty() && trigger.cycle_period <= Duration::ZERO {
            self.triggers.clear();
            return;
        }
        if let Some(last) = self.triggers.back() {
            if trigger.epoch < last.epoch
                || (trigger.epoch == last.epoch && trigger.cycle <= last.cycle)
            {
                return;
            }
            if trigger.epoch > last.epoch {
                self.triggers.clear();
            }
        }
        if self.triggers.len() == TRIGGERS_KEPT {
            self.triggers.pop_front();
        }
        self.triggers.push_back(trigger);
    }

    /// Whether none is kept.
    pub fn is_empty(&self) -> bool {
        self.triggers.is_empty()
    }

    /// The learnt offset of the MSU clock from the central unit's,
    /// nanoseconds (`None` until a clear choice was solved with a good fix).
    pub fn clock_offset_ns(&self) -> Option<i64> {
        if self.clock_offsets_ns.is_empty() {
            return None;
        }
        let mut kept: Vec<i64> = self.clock_offsets_ns.iter().copied().collect();
        kept.sort_unstable();
        Some(kept[kept.len() / 2])
    }

    /// The trigger that best explains `msg` (see the module doc), among
    /// those whose schedule `book` holds; `None` if none does.
    /// `flight_ns(tx_id)` is the flight time expected from where the
    /// receiver is thought to be, nanoseconds (`None` when that is not
    /// known: the starts then include the flight times, and the clock
    /// offset is not used).
    pub fn best_for(
        &mut self,
        msg: &UltrasoundArrivals,
        book: &ScheduleBook,
        flight_ns: &dyn Fn(u32) -> Option<i64>,
    ) -> Option<Matched> {
        let mut candidates: Vec<Candidate> = Vec::new();
        let mut flights_known = true;
        // Newest first.
        for trigger in self.triggers.iter().rev() {
            let Some(schedule) = book.get_in(trigger.epoch, trigger.schedule_version) else {
                continue;
            };
            // More firings than emissions cannot be the central unit's (and
            // would make the look-up below cost what a forger chooses).
            if trigger.firing.len() > schedule.emissions.len() {
                continue;
            }
            let emissions = trigger.emissions(schedule);
            let mut starts_ns: Vec<i64> = Vec::with_capacity(msg.arrivals.len());
            for (a, e) in named(msg, &emissions) {
                let flight = flight_ns(a.tx_id);
                flights_known &= flight.is_some();
                starts_ns.push(start_ns(a, e, flight.unwrap_or(0)));
            }
            if starts_ns.is_empty() {
                continue;
            }
            let (median, deviation_ns) = median_and_deviation_ns(&mut starts_ns);
            candidates.push(Candidate {
                trigger,
                covered: starts_ns.len(),
                deviation_ns,
                clock_offset_ns: median.saturating_sub(trigger.start.as_nanos()),
            });
        }
        let most = candidates.iter().map(|c| c.covered).max()?;
        candidates.retain(|c| c.covered == most);
        let learnt = self.clock_offset_ns().filter(|_| flights_known);
        if let Some(offset) = learnt {
            let nearest = candidates
                .iter()
                .min_by_key(|c| c.clock_offset_ns.abs_diff(offset))
                .filter(|c| {
                    c.clock_offset_ns.abs_diff(offset) <= CLOCK_GATE.as_nanos().unsigned_abs()
                });
            if let Some(c) = nearest {
                self.misfits = 0;
                return Some(Matched {
                    trigger: c.trigger.clone(),
                    clear: true,
                });
            }
            self.misfits += 1;
        }
        // The tightest spread; newest first, so a later one must be strictly tighter.
        let best =
            candidates
                .iter()
                .enumerate()
                .fold(None::<(usize, &Candidate)>, |best, (k, c)| match best {
                    Some((_, b)) if b.deviation_ns <= c.deviation_ns => best,
                    _ => Some((k, c)),
                })?;
        let clear = flights_known
            && candidates.iter().enumerate().all(|(k, c)| {
                k == best.0 || c.deviation_ns > best.1.deviation_ns.saturating_mul(2)
            });
        Some(Matched {
            trigger: best.1.trigger.clone(),
            clear,
        })
    }

    /// Learns the clock offset from a cycle solved with a good fix: the
    /// cycle of `trigger` (under `book`) started at `start_ns` on the MSU
    /// clock. After [`MISFITS_BEFORE_RELEARN`] misfits, what was learnt
    /// goes first.
    pub fn learn_clock(&mut self, trigger: &CycleTrigger, start_ns: i64) {
        if self.misfits >= MISFITS_BEFORE_RELEARN {
            self.clock_offsets_ns.clear();
            self.misfits = 0;
        }
        if self.clock_offsets_ns.len() == CLOCK_OFFSETS_KEPT {
            self.clock_offsets_ns.pop_front();
        }
        self.clock_offsets_ns
            .push_back(start_ns.saturating_sub(trigger.start.as_nanos()));
    }
}

/// The cycle's start on the MSU clock that `msg`'s arrivals give under
/// `emissions` and the flight times `flight_ns` (the median over the
/// arrivals of the emissions named), nanoseconds.
pub fn cycle_start_ns(
    msg: &UltrasoundArrivals,
    emissions: &[Emission],
    flight_ns: &dyn Fn(u32) -> Option<i64>,
) -> Option<i64> {
    let mut starts_ns: Vec<i64> = named(msg, emissions)
        .filter_map(|(a, e)| Some(start_ns(a, e, flight_ns(a.tx_id)?)))
        .collect();
    if starts_ns.is_empty() {
        return None;
    }
    Some(median_and_deviation_ns(&mut starts_ns).0)
}

/// The arrivals of `msg` from transmitters `emissions` names, each with its emission.
fn named<'a>(
    msg: &'a UltrasoundArrivals,
    emissions: &'a [Emission],
) -> impl Iterator<Item = (&'a Arrival, &'a Emission)> {
    msg.arrivals
        .iter()
        .filter_map(|a| Some((a, emissions.iter().find(|e| e.tx_id == a.tx_id)?)))
}

/// Where `arrival` puts the cycle's start on the MSU clock, nanoseconds:
/// its time less its emission's offset and its flight time.
fn start_ns(arrival: &Arrival, emission: &Emission, flight_ns: i64) -> i64 {
    arrival
        .t_arrival
        .as_nanos()
        .saturating_sub(emission.offset.as_nanos())
        .saturating_sub(flight_ns)
}

/// The median of `starts_ns` and how far they lie from it, summed,
/// nanoseconds: a late reflection adds its own delay once, whereas a
/// trigger whose offsets are wrong for several transmitters adds each
/// one's error. `starts_ns` must not be empty.
fn median_and_deviation_ns(starts_ns: &mut [i64]) -> (i64, i64) {
    starts_ns.sort_unstable();
    let median = starts_ns[starts_ns.len() / 2];
    let deviation = starts_ns.iter().fold(0i64, |sum, &s| {
        sum.saturating_add(i64::try_from(s.abs_diff(median)).unwrap_or(i64::MAX))
    });
    (median, deviation)
}

#[cfg(test)]
pub(crate) mod tests;
