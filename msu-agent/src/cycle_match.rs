//! Which cycle trigger a message of arrivals belongs to, when the central
//! unit names the transmitters of each cycle (occupancy firing, issue 20).
//!
//! The MSU hears bursts on its own clock and has no cycle number: a cycle's
//! arrivals come after its trigger and often after the next one's. So each
//! recent trigger is tried as an explanation: it must name the transmitters
//! heard (the most of them wins), and its offsets must explain the arrival
//! times, i.e. `t_i - offset_i` (the cycle start on the MSU clock plus each
//! flight time) must spread no wider than flight times can; the tightest
//! spread wins, the newest trigger breaks a tie.

use std::collections::VecDeque;

use ickon_proto::epoch::ScheduleBook;
use ickon_proto::msg::control::CycleTrigger;
use ickon_proto::msg::robot::UltrasoundArrivals;
use ickon_proto::time::Duration;

/// Triggers kept to be matched: a cycle's arrivals reach the MSU within a
/// cycle or two of its trigger.
pub const TRIGGERS_KEPT: usize = 8;

/// The recent triggers of the epoch followed, newest last.
#[derive(Debug, Clone, Default)]
pub struct RecentTriggers {
    triggers: VecDeque<CycleTrigger>,
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

    /// The trigger that best explains `msg` (see the module doc), among
    /// those whose schedule `book` holds; `None` if none does.
    pub fn best_for(&self, msg: &UltrasoundArrivals, book: &ScheduleBook) -> Option<&CycleTrigger> {
        let mut best: Option<(usize, i64, &CycleTrigger)> = None;
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
            let mut covered = 0usize;
            let mut lo = i64::MAX;
            let mut hi = i64::MIN;
            for a in &msg.arrivals {
                let Some(e) = emissions.iter().find(|e| e.tx_id == a.tx_id) else {
                    continue;
                };
                covered += 1;
                let start_ns = a.t_arrival.as_nanos().saturating_sub(e.offset.as_nanos());
                lo = lo.min(start_ns);
                hi = hi.max(start_ns);
            }
            if covered == 0 {
                continue;
            }
            let spread_ns = hi.saturating_sub(lo);
            // Newest first: a later candidate must be strictly better.
            let better = match best {
                None => true,
                Some((c, s, _)) => covered > c || (covered == c && spread_ns < s),
            };
            if better {
                best = Some((covered, spread_ns, trigger));
            }
        }
        best.map(|(_, _, t)| t)
    }
}

#[cfg(test)]
pub(crate) mod tests;
