//! Which cycle trigger a message of arrivals belongs to, when the central
//! unit names the transmitters of each cycle (occupancy firing).
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
//!
//! Whether a choice was clear is judged against the triggers of a fixed
//! window of cycles around it, the next one included, never against
//! whichever happened to be heard when the arrivals were: the next cycle's
//! trigger often races a cycle's arrivals to the MSU, and a recorder of
//! the site can see that race end the other way. So when the next trigger
//! has not come yet, the judgement waits for it ([`Clarity::AwaitingNext`],
//! [`RecentTriggers::defer_learning`]), and the agent and a replay of its
//! recording learn the same offset from the same cycles.

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

/// Cycles before the chosen one whose triggers a choice is judged against
/// (with the chosen one's and the next one's): every trigger of that
/// window is still kept when the judgement is made, however many newer
/// ones have come ([`TRIGGERS_KEPT`] leaves room for three).
pub const CLARITY_CYCLES_BEFORE: u64 = 3;

/// The recent triggers of the epoch followed, newest last, and the MSU
/// clock's offset from the central unit's.
#[derive(Debug, Clone, Default)]
pub struct RecentTriggers {
    triggers: VecDeque<CycleTrigger>,
    /// MSU clock minus central clock at the last cycles solved, nanoseconds.
    clock_offsets_ns: VecDeque<i64>,
    misfits: u32,
    /// A cycle solved with a good fix whose clarity waits for the next trigger.
    deferred: Option<Deferred>,
}

/// Whether a choice may teach the clock offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clarity {
    /// It fitted the learnt offset, or every trigger of its window was
    /// heard and every other one spread the starts more than twice as wide.
    Clear,
    /// Another trigger explains the arrivals nearly as well (a tie is never
    /// clear), one of the window was not heard, or the flight times are
    /// not known.
    Unclear,
    /// The next cycle's trigger, which belongs to the window, has not been
    /// heard yet: judged when it is.
    AwaitingNext,
}

/// The trigger chosen for a message of arrivals.
#[derive(Debug, Clone, PartialEq)]
pub struct Matched {
    /// The trigger whose firings the arrivals are solved with.
    pub trigger: CycleTrigger,
    /// Whether the choice may teach the clock offset.
    pub clarity: Clarity,
}

/// A solved cycle waiting for the next trigger to say whether its choice was clear.
#[derive(Debug, Clone)]
struct Deferred {
    trigger: CycleTrigger,
    /// Its start on the MSU clock, from the fix, nanoseconds.
    start_ns: i64,
    msg: UltrasoundArrivals,
    /// The flight times the choice was made with, by transmitter, nanoseconds.
    flights_ns: Vec<(u32, i64)>,
}

/// One trigger tried on a message.
struct Candidate<'a> {
    trigger: &'a CycleTrigger,
    covered: usize,
    deviation_ns: i64,
    /// Where the trigger puts the MSU clock's offset, nanoseconds.
    clock_offset_ns: i64,
    /// Whether every arrival it names had a flight time.
    flights_known: bool,
}

/// How `trigger` explains `msg` (`None`: its schedule is not in `book`, it
/// is oversized, or it names none of the transmitters heard).
fn explain<'a>(
    trigger: &'a CycleTrigger,
    msg: &UltrasoundArrivals,
    book: &ScheduleBook,
    flight_ns: &dyn Fn(u32) -> Option<i64>,
) -> Option<Candidate<'a>> {
    let schedule = book.get_in(trigger.epoch, trigger.schedule_version)?;
    // More firings than emissions cannot be the central unit's (and would
    // make the look-up below cost what a forger chooses).
    if trigger.firing.len() > schedule.emissions.len() {
        return None;
    }
    let emissions = trigger.emissions(schedule);
    let mut flights_known = true;
    let mut starts_ns: Vec<i64> = Vec::with_capacity(msg.arrivals.len());
    for (a, e) in named(msg, &emissions) {
        let flight = flight_ns(a.tx_id);
        flights_known &= flight.is_some();
        starts_ns.push(start_ns(a, e, flight.unwrap_or(0)));
    }
    if starts_ns.is_empty() {
        return None;
    }
    let (median, deviation_ns) = median_and_deviation_ns(&mut starts_ns);
    Some(Candidate {
        trigger,
        covered: starts_ns.len(),
        deviation_ns,
        clock_offset_ns: median.saturating_sub(trigger.start.as_nanos()),
        flights_known,
    })
}

impl RecentTriggers {
    /// Keeps `trigger` (the oldest kept goes beyond [`TRIGGERS_KEPT`]); one
    /// of an older epoch than the newest kept, or a repeat, is ignored. A
    /// trigger that names no firings and no period (the whole schedule
    /// fires) forgets them all: arrivals are then
    /// matched to the newest schedule, exactly as without triggers.
    ///
    /// A cycle whose clarity waited for a newer trigger is judged now
    /// (`book` holds the schedules the triggers name), and teaches the
    /// clock offset if it was clear.
    pub fn note(&mut self, trigger: CycleTrigger, book: &ScheduleBook) {
        if trigger.firing.is_empty() && trigger.cycle_period <= Duration::ZERO {
            self.triggers.clear();
            self.deferred = None;
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
                self.deferred = None;
            }
        }
        if self.triggers.len() == TRIGGERS_KEPT {
            self.triggers.pop_front();
        }
        self.triggers.push_back(trigger);
        if let Some(d) = self.deferred.take() {
            let flight_ns = |tx: u32| d.flights_ns.iter().find(|(id, _)| *id == tx).map(|f| f.1);
            let explained: Vec<Candidate> = self
                .triggers
                .iter()
                .filter_map(|t| explain(t, &d.msg, book, &flight_ns))
                .collect();
            match self.judge(&explained, &d.trigger) {
                Clarity::Clear => self.learn_clock(&d.trigger, d.start_ns),
                Clarity::Unclear => {}
                Clarity::AwaitingNext => self.deferred = Some(d),
            }
        }
    }

    /// Keeps a cycle solved with a good fix whose choice was
    /// [`Clarity::AwaitingNext`]: `trigger` started at `start_ns` on the
    /// MSU clock; `msg` was matched with the flight times `flights_ns`
    /// (each of its transmitters', nanoseconds). The next trigger judges it
    /// ([`Self::note`]); a newer deferred cycle replaces it.
    pub fn defer_learning(
        &mut self,
        trigger: &CycleTrigger,
        start_ns: i64,
        msg: &UltrasoundArrivals,
        flights_ns: Vec<(u32, i64)>,
    ) {
        self.deferred = Some(Deferred {
            trigger: trigger.clone(),
            start_ns,
            msg: msg.clone(),
            flights_ns,
        });
    }

    /// `(epoch, cycle)` of the newest trigger kept.
    pub fn newest(&self) -> Option<(u64, u64)> {
        self.triggers.back().map(|t| (t.epoch, t.cycle))
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
        // Newest first.
        let explained: Vec<Candidate> = self
            .triggers
            .iter()
            .rev()
            .filter_map(|t| explain(t, msg, book, flight_ns))
            .collect();
        let flights_known = explained.iter().all(|c| c.flights_known);
        let most = explained.iter().map(|c| c.covered).max()?;
        let candidates: Vec<&Candidate> = explained.iter().filter(|c| c.covered == most).collect();
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
                    clarity: Clarity::Clear,
                });
            }
            self.misfits += 1;
        }
        // The tightest spread; newest first, so a later one must be strictly tighter.
        let best = candidates
            .iter()
            .fold(None::<&Candidate>, |best, c| match best {
                Some(b) if b.deviation_ns <= c.deviation_ns => best,
                _ => Some(c),
            })?;
        let clarity = if flights_known {
            self.judge(&explained, best.trigger)
        } else {
            Clarity::Unclear
        };
        Some(Matched {
            trigger: best.trigger.clone(),
            clarity,
        })
    }

    /// Whether `chosen` explains the arrivals clearly, given how each kept
    /// trigger explains them (`explained`): every trigger of its window
    /// (from [`CLARITY_CYCLES_BEFORE`] cycles before it to the next one) was
    /// heard, and every other one that names as many of the transmitters
    /// heard spreads the starts more than twice as wide.
    /// [`Clarity::AwaitingNext`] until a trigger newer than `chosen` is kept.
    fn judge(&self, explained: &[Candidate], chosen: &CycleTrigger) -> Clarity {
        let newer_kept = self
            .triggers
            .back()
            .is_some_and(|t| t.epoch == chosen.epoch && t.cycle > chosen.cycle);
        if !newer_kept {
            return Clarity::AwaitingNext;
        }
        let window =
            chosen.cycle.saturating_sub(CLARITY_CYCLES_BEFORE)..=chosen.cycle.saturating_add(1);
        let in_window = |t: &CycleTrigger| t.epoch == chosen.epoch && window.contains(&t.cycle);
        // A trigger of the window not heard (lost, or sent before the MSU
        // listened) could be the one that explains the arrivals as well:
        // the right cycle may be missing, and the one chosen a neighbour.
        let window_len = window.end() - window.start() + 1;
        if self.triggers.iter().filter(|t| in_window(t)).count() as u64 != window_len {
            return Clarity::Unclear;
        }
        let mut rivals = explained.iter().filter(|c| in_window(c.trigger));
        let Some(mine) = rivals.clone().find(|c| c.trigger.cycle == chosen.cycle) else {
            return Clarity::Unclear;
        };
        let clear = mine.flights_known
            && rivals.all(|c| {
                c.trigger.cycle == chosen.cycle
                    || c.covered < mine.covered
                    || c.deviation_ns > mine.deviation_ns.saturating_mul(2)
            });
        if clear {
            Clarity::Clear
        } else {
            Clarity::Unclear
        }
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
