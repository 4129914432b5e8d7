//! Cycles: when the next trigger is due, triggering it (skipping cycles
//! too late to fire), planning its firings and counting missed ones.

use std::collections::BTreeSet;

use ickon_proto::msg::control::{CycleTrigger, Firing, Schedule};
use ickon_proto::msg::robot::PoseStatus;
use ickon_proto::time::{Duration, Time};

use crate::occupancy::{RobotView, plan};
use crate::spacing::SpacingTable;

use super::{CentralCore, Output};

/// Own triggers remembered to recognise them on the way back: 25 s at
/// 10 cycles/s, longer at slower rates. An overloaded router delivers a
/// unit's own triggers back many cycles late; fewer would count them as
/// forged.
pub(super) const SENT_TRIGGERS_KEPT: usize = 256;

/// Cycles that may still be triggered late in one tick; older ones are skipped.
const MAX_LATE_CYCLES: i64 = 2;

impl CentralCore {
    /// When the node should call [`tick`](Self::tick) next: the next
    /// trigger time (the schedule is re-announced with the first trigger
    /// after its period, so it needs no wake-up of its own); for a standby,
    /// when the active one's lease runs out.
    pub fn next_wake(&self) -> Time {
        match &self.standby {
            Some(f) => f.lease_end(),
            None => self.next_trigger_at(),
        }
    }

    /// Whether a tick is due at once, before [`Self::next_wake`]: the
    /// survey calibration put off by the last tick's triggers, to be
    /// computed as soon as they are published.
    pub fn tick_pending(&self) -> bool {
        self.standby.is_none() && self.survey_deferred
    }

    /// When the next trigger goes out.
    pub(super) fn next_trigger_at(&self) -> Time {
        self.next_start - self.config.trigger_lead
    }

    /// Emits every trigger due at `now` (one per cycle, never two for one
    /// cycle); a standby emits nothing.
    pub(super) fn tick(&mut self, now: Time) -> Vec<Output> {
        let mut out = self.notice_clock_step_back(now);
        if self.standby.is_some() {
            return out;
        }
        self.skip_stale_cycles(now);
        let first_cycle = self.next_cycle;
        while now >= self.next_trigger_at() {
            let before = self.next_start;
            let cycle = self.next_cycle;
            let schedule = self.schedule_for(cycle).clone();
            let (firing, period) = self.plan_cycle(&schedule, now);
            let trigger = CycleTrigger {
                cycle,
                start: self.next_start,
                schedule_version: schedule.version,
                epoch: self.epoch,
                firing,
                cycle_period: period,
            };
            if !self.paused {
                if self.sent_triggers.len() == SENT_TRIGGERS_KEPT {
                    self.sent_triggers.pop_front();
                }
                self.sent_triggers.push_back(trigger.clone());
                out.push(Output::Trigger(trigger.clone()));
                self.count_missed(cycle);
            }
            // A paused cycle asks no cell to fire: all are idle.
            self.note_due(if self.paused { None } else { Some(&trigger) });
            self.last_trigger = Some(trigger);
            self.next_cycle = self.next_cycle.saturating_add(1);
            self.cycles_heard = self.cycles_heard.saturating_add(1);
            self.next_start = self.next_start + period;
            if self.next_start <= before {
                // At the end of time (saturated): nothing more to trigger.
                break;
            }
        }
        if now >= self.next_reannounce && !out.is_empty() {
            self.next_reannounce = now + self.config.schedule_reannounce;
            out.push(Output::Schedule(self.latest_schedule().clone()));
        }
        // A calibration takes milliseconds to compute (a dense solve over
        // every transmitter), and the node publishes a tick's outputs when
        // the tick is done: computed with a cycle's trigger it would hold
        // the trigger back by that long. So it is computed in the tick
        // right after (the node wakes at once), in the cycle's idle time;
        // a subscriber still hears it between the same two triggers.
        let cycled = self.next_cycle != first_cycle;
        if self.survey.is_some() && cycled && !self.survey_deferred {
            self.survey_deferred = true;
        } else {
            self.survey_deferred = false;
            let air = self.air.evidence(now, self.site.speed_of_sound_m_s);
            if let Some(p) = self.survey.as_mut() {
                p.observe_air_temperature(air);
            }
            if let Some(survey) = self.survey.as_mut().and_then(|p| p.due(now, self.epoch)) {
                out.push(Output::Survey(survey));
            }
        }
        out.extend(self.reconcile_membership(now));
        self.update_states(now);
        out
    }

    /// After a forward clock jump (or a process that was stopped), skips
    /// the cycles whose time is long past instead of triggering each of
    /// them late (a day's jump was 432 000 triggers in one tick, the end
    /// of time a loop without end); the cycle count moves on with the
    /// time, so that the cells' trigger gate still finds it in step.
    fn skip_stale_cycles(&mut self, now: Time) {
        let period = i128::from(
            self.schedule_for(self.next_cycle)
                .cycle_period
                .as_nanos()
                .max(1),
        );
        // In i128: the gap between two times may exceed i64 (a start taken
        // over from a forged trigger near i64::MIN, a clock near i64::MAX).
        let behind = i128::from(now.as_nanos()) - i128::from(self.next_trigger_at().as_nanos());
        let skip = behind / period - i128::from(MAX_LATE_CYCLES);
        if skip > 0 {
            self.next_cycle = self
                .next_cycle
                .saturating_add(u64::try_from(skip).unwrap_or(u64::MAX));
            let start = i128::from(self.next_start.as_nanos()) + skip * period;
            self.next_start = Time::from_nanos(i64::try_from(start).unwrap_or(i64::MAX));
        }
    }

    /// The transmitters that fire in the next cycle under `schedule` and
    /// the cycle's length: every emission of the schedule, or with
    /// occupancy-aware firing those robots can hear, packed anew.
    fn plan_cycle(&mut self, schedule: &Schedule, now: Time) -> (Vec<Firing>, Duration) {
        let all = || {
            schedule
                .emissions
                .iter()
                .map(|e| Firing {
                    tx_id: e.tx_id,
                    offset: e.offset,
                })
                .collect()
        };
        if !self.config.firing.occupancy {
            return (all(), schedule.cycle_period);
        }
        if self
            .table
            .as_ref()
            .is_none_or(|t| !same_cells(t, &schedule.active_cells))
        {
            self.table = Some(SpacingTable::new(&self.site, &schedule.active_cells));
            self.history.clear();
        }
        let Some(table) = self.table.as_ref() else {
            return (all(), schedule.cycle_period);
        };
        let views: Vec<RobotView> = self
            .robots
            .values()
            .filter_map(|r| match r.last_pose() {
                // A pose no fix has confirmed may be far from the robot
                // (a restarted MSU): as good as none, so everything fires.
                Some((pose, at)) if pose.status != PoseStatus::Localising => {
                    Some(RobotView::Seen(pose, at, r.velocity()))
                }
                _ => r.alive.then_some(RobotView::New),
            })
            .collect();
        let guess = self
            .last_trigger
            .as_ref()
            .map_or(schedule.cycle_period, |t| t.period(schedule));
        let planned = plan(
            table,
            &views,
            &self.config.firing,
            now,
            guess,
            &self.history,
        );
        if let Some(p) = &planned {
            self.plan_stats.note(&p.hdops);
        }
        let (offsets, period, need) = match planned {
            Some(p) => (p.packing.offsets, p.packing.period, Some(p.need)),
            None => (
                schedule
                    .emissions
                    .iter()
                    .filter_map(|e| Some((table.index_of(e.tx_id)?, e.offset)))
                    .collect(),
                schedule.cycle_period,
                None,
            ),
        };
        let spacing = |j: usize, i: usize| match &need {
            Some(n) => n.get(j).and_then(|r| r.get(i)).copied().flatten(),
            None => table.need(j, i),
        };
        // The previous cycle fired other transmitters at other offsets:
        // delay this one until every burst keeps its spacing from those.
        let mut delay = Duration::ZERO;
        if let Some(prev) = &self.last_trigger {
            let prev_period = prev.period(schedule);
            for f in &prev.firing {
                let Some(j) = table.index_of(f.tx_id) else {
                    continue;
                };
                for &(i, offset) in &offsets {
                    if let Some(n) = spacing(j, i) {
                        let earliest = f.offset + n;
                        let at = prev_period + offset + delay;
                        if earliest > at {
                            delay = delay + (earliest - at);
                        }
                    }
                }
            }
        }
        self.history
            .note(offsets.iter().map(|&(i, _)| i), self.next_start);
        let firing = offsets
            .iter()
            .map(|&(i, offset)| Firing {
                tx_id: table.tx_ids[i],
                offset: offset + delay,
            })
            .collect();
        (firing, period + delay)
    }

    /// What the admin sees as the schedule: the newest schedule, or, once
    /// a cycle of it has been triggered, that cycle's firing set at its
    /// offsets and its length (the rate the site runs at now).
    pub fn current_firing(&self) -> Schedule {
        let latest = self.latest_schedule();
        match &self.last_trigger {
            Some(t) if t.schedule_version == latest.version => t.schedule_of_cycle(latest),
            _ => latest.clone(),
        }
    }

    /// The trigger of the last cycle (sent or, while paused, not).
    pub fn last_trigger(&self) -> Option<&CycleTrigger> {
        self.last_trigger.as_ref()
    }

    /// Counts, for the cycle two before `cycle` (its bursts have had time to
    /// arrive), the cells due in it that did not fire. A cycle not sent
    /// (paused) had no cell due.
    fn count_missed(&mut self, cycle: u64) {
        let Some(checked) = cycle.checked_sub(2) else {
            return;
        };
        let Some(trigger) = self.sent_triggers.iter().find(|t| t.cycle == checked) else {
            return;
        };
        let due = self.cells_due(trigger);
        for id in due {
            if let Some(c) = self.cells.get_mut(&id) {
                c.check_fired(checked);
            }
        }
    }

    /// Notes which cells the trigger sent asks to fire (the others are idle).
    fn note_due(&mut self, sent: Option<&CycleTrigger>) {
        let due = sent.map(|t| self.cells_due(t)).unwrap_or_default();
        for (id, c) in &mut self.cells {
            c.due_in_last_cycle = due.contains(id);
        }
    }

    /// The cells owning a transmitter `trigger` fires (a trigger naming
    /// none fires its whole schedule).
    pub(super) fn cells_due(&self, trigger: &CycleTrigger) -> BTreeSet<String> {
        let schedule = self
            .schedules
            .iter()
            .find(|s| s.version == trigger.schedule_version)
            .unwrap_or_else(|| self.schedule_for(trigger.cycle));
        trigger
            .emissions(schedule)
            .into_iter()
            .map(|e| e.cell_id)
            .collect()
    }
}

/// Whether `table` holds the transmitters of exactly `cells`.
fn same_cells(table: &SpacingTable, cells: &[String]) -> bool {
    let have: std::collections::BTreeSet<&String> = table.cells.iter().collect();
    have.len() == cells.len() && have.iter().all(|c| cells.contains(c))
}
