//! Epochs and other central units' control messages: the master clock
//! stepping back, schedules and triggers this unit did not send, and a
//! new epoch.

use ickon_proto::epoch::epoch_of;
use ickon_proto::msg::control::{CycleTrigger, Schedule};
use ickon_proto::time::Time;

use super::{CentralCore, Output};

impl CentralCore {
    /// When the master clock stepped back by more than a cycle (an operator
    /// or NTP set it), the next trigger time lies that far ahead and the
    /// site would stay silent until the clock caught up. Instead the cycles
    /// start again at once in a new epoch, as after a restart: receivers
    /// drop the old epoch's cycle count, whose starts are now in the future.
    /// A standby only follows; smaller steps just delay one cycle.
    pub(super) fn notice_clock_step_back(&mut self, now: Time) -> Vec<Output> {
        let period = self.schedule_for(self.next_cycle).cycle_period;
        let back = self.latest_now.since(now);
        if self.standby.is_some() {
            // A standby only follows: its time is whatever its clock says,
            // and a takeover starts from there.
            self.latest_now = now;
            return Vec::new();
        }
        if back <= period {
            self.latest_now = self.latest_now.max(now);
            return Vec::new();
        }
        self.latest_now = now;
        tracing::warn!(
            "the master clock stepped back by {:.3} s: cycles start again in a new epoch",
            back.as_secs_f64()
        );
        let out = self.new_epoch(now);
        // The first trigger of the new epoch after its schedule is out.
        self.next_start = now + self.config.schedule_announce + self.config.trigger_lead;
        self.next_reannounce = now + self.config.schedule_reannounce;
        out
    }

    /// A schedule heard on `central/schedule`: nothing if it is one of its
    /// own; otherwise counted, and the own schedule re-announced at once,
    /// under a version above the foreign one's when that claimed a newer
    /// version (receivers take only a newer version over it).
    pub(super) fn on_schedule_seen(&mut self, seen: Schedule, now: Time) -> Vec<Output> {
        if seen.epoch == self.epoch && self.schedules.contains(&seen) {
            return Vec::new();
        }
        let latest = self.latest_schedule().clone();
        if seen.epoch == self.epoch && seen.version < latest.version {
            // One of its own, dropped since (or a forged old version, which
            // every receiver refuses as going backwards).
            if !self.schedules.iter().any(|s| s.version == seen.version) {
                return Vec::new();
            }
        }
        self.foreign_control += 1;
        if self.foreign_control.is_power_of_two() {
            tracing::warn!(
                "a schedule v{} of epoch {} that this central unit (epoch {}) did not send; {} so far",
                seen.version,
                seen.epoch,
                self.epoch,
                self.foreign_control
            );
        }
        self.next_reannounce = now + self.config.schedule_reannounce;
        if seen.epoch != self.epoch || seen.version <= latest.version {
            return vec![Output::Schedule(latest)];
        }
        let Some(version) = seen.version.checked_add(1) else {
            // No version above it: only a new epoch displaces it.
            return self.new_epoch(now);
        };
        let effective = self.first_announceable_cycle(now);
        let healed = Schedule {
            version,
            effective_cycle: effective,
            ..latest
        };
        tracing::info!("schedule re-issued as v{version} from cycle {effective}");
        self.push_schedule(healed.clone());
        vec![Output::Schedule(healed)]
    }

    /// Starts a new epoch at `now`: cycles count from 0 again and the
    /// schedule in force is re-issued as version 1, from the next cycle.
    pub(crate) fn new_epoch(&mut self, now: Time) -> Vec<Output> {
        self.epoch = epoch_of(now, Some(self.epoch));
        let current = self.schedule_for(self.next_cycle).clone();
        let schedule = Schedule {
            version: 1,
            effective_cycle: 0,
            epoch: self.epoch,
            ..current
        };
        self.schedules = vec![schedule.clone()];
        self.next_cycle = 0;
        self.sent_triggers.clear();
        tracing::info!("new epoch {}", self.epoch);
        vec![Output::Schedule(schedule)]
    }

    /// A trigger heard on `central/cycle`: counted if it is not one of its own.
    pub(super) fn on_trigger_seen(&mut self, seen: &CycleTrigger) {
        if self.sent_triggers.contains(seen) {
            return;
        }
        self.foreign_control += 1;
        // Logged at 1, 2, 4, 8, ... so that a flood costs a few lines.
        if self.foreign_control.is_power_of_two() {
            tracing::warn!(
                "a trigger for cycle {} of epoch {} that this central unit (epoch {}) did not send; {} so far",
                seen.cycle,
                seen.epoch,
                self.epoch,
                self.foreign_control
            );
        }
    }
}
