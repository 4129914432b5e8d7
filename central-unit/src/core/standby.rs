//! The hot standby: a second central unit that follows the active one
//! (its schedule, cycle and epoch, from what it publishes) and takes over
//! when the active one's liveliness token goes ([`Event::ActiveGone`]) or,
//! for a hung one whose token outlives it, when no trigger came for
//! [`LEASE_CYCLES`] cycle periods.
//!
//! Taking over opens a new epoch above the followed one: the cells take its
//! cycle 0 at once and refuse the old epoch from then on, so two actives
//! cannot both be followed (fencing by epoch). The cycles keep their
//! rhythm: the new cycle 0 starts where the followed count would have put
//! its next cycle, with the followed schedule re-issued as version 1. An
//! active central unit that hears a newer epoch steps down and follows it.
//!
//! A central unit started while another is active (its `alive/central`
//! token seen at start: [`CentralCore::starting`]) starts as a standby
//! even without `--standby`: a restarted first central unit must not take
//! the site back from the standby that took over from it (a second switch
//! for nothing).
//!
//! [`Event::ActiveGone`]: super::Event::ActiveGone

use ickon_proto::epoch::{ScheduleBook, epoch_of, plausible_epoch};
use ickon_proto::msg::control::{CycleTrigger, Schedule};
use ickon_proto::time::{Duration, Time};

use super::{CentralConfig, CentralCore, Output};
use crate::schedule::ScheduleError;

/// Cycle periods without a trigger after which a standby takes over from
/// a hung active central unit (its liveliness token lives until the link
/// lease ends, seconds later).
pub const LEASE_CYCLES: i64 = 2;

/// How long a standby started alone waits for an active one before it
/// becomes active itself.
pub const FIRST_LEASE: Duration = Duration::from_millis(2_000);

/// What a standby knows of the active central unit.
#[derive(Debug, Clone)]
pub struct Follower {
    schedules: ScheduleBook,
    last_trigger: Option<CycleTrigger>,
    lease_end: Time,
}

impl Follower {
    /// When the active one counts as hung if no trigger comes before.
    pub fn lease_end(&self) -> Time {
        self.lease_end
    }
}

impl CentralCore {
    /// A hot standby serving `site`, started at `now`: it publishes nothing
    /// until it takes over.
    pub fn standby(
        site: ickon_proto::site::Site,
        site_toml: String,
        config: CentralConfig,
        now: Time,
    ) -> Result<Self, ScheduleError> {
        let mut core = Self::new(site, site_toml, config, now)?;
        core.standby = Some(Follower {
            schedules: ScheduleBook::new(),
            last_trigger: None,
            lease_end: now + FIRST_LEASE,
        });
        Ok(core)
    }

    /// A central unit started at `now`: a standby when `standby` (the
    /// `--standby` flag) says so or when `active_seen` (another central
    /// unit's token was there at start), active otherwise.
    pub fn starting(
        site: ickon_proto::site::Site,
        site_toml: String,
        config: CentralConfig,
        now: Time,
        standby: bool,
        active_seen: bool,
    ) -> Result<Self, ScheduleError> {
        if standby || active_seen {
            Self::standby(site, site_toml, config, now)
        } else {
            Self::new(site, site_toml, config, now)
        }
    }

    /// The epoch followed by a standby (the active one's), if it saw one.
    pub fn followed_epoch(&self) -> Option<u64> {
        self.standby.as_ref()?.schedules.epoch()
    }

    pub(super) fn follow_schedule(&mut self, schedule: Schedule) {
        if let Some(f) = &mut self.standby {
            let _ = f.schedules.offer(schedule);
        }
    }

    pub(super) fn follow_trigger(&mut self, trigger: CycleTrigger, now: Time) {
        let own_period = self.latest_schedule().cycle_period;
        let Some(f) = &mut self.standby else {
            return;
        };
        if f.last_trigger
            .as_ref()
            .is_some_and(|t| trigger.epoch < t.epoch)
        {
            return;
        }
        let period = f
            .schedules
            .get_in(trigger.epoch, trigger.schedule_version)
            .map_or(own_period, |s| s.cycle_period);
        // The lease counts whole periods of the schedule, never the shorter
        // cycles of occupancy firing: a late takeover, never a false one.
        // A real trigger starts a trigger lead after it is heard; one
        // stamped further ahead (forged) must not hold the standby back
        // until then: its start counts as one period from now at most.
        f.lease_end = trigger.start.min(now + period) + period * LEASE_CYCLES;
        let again = f
            .last_trigger
            .as_ref()
            .is_some_and(|t| (t.epoch, t.cycle) == (trigger.epoch, trigger.cycle));
        f.last_trigger = Some(trigger);
        if !again {
            self.cycles_heard = self.cycles_heard.saturating_add(1);
        }
    }

    pub(super) fn lease_expired(&self, now: Time) -> bool {
        self.standby.as_ref().is_some_and(|f| now >= f.lease_end)
    }

    /// Becomes the active central unit at `now`, in a new epoch above every
    /// one seen; returns the schedule to publish.
    pub(super) fn take_over(&mut self, now: Time) -> Vec<Output> {
        let Some(f) = self.standby.take() else {
            return Vec::new();
        };
        // An epoch is a central unit's start: one further ahead of the
        // clock than the cells accept was forged, and following it would
        // fence nothing (at `u64::MAX` no epoch is above it) and put this
        // one's epoch where the cells refuse it.
        let real = |e: &u64| plausible_epoch(*e, now);
        let followed = f
            .last_trigger
            .as_ref()
            .map(|t| t.epoch)
            .filter(real)
            .max(f.schedules.epoch().filter(real));
        let after = followed.map_or(self.epoch, |e| e.max(self.epoch));
        self.epoch = epoch_of(now, Some(after));
        let base = f
            .last_trigger
            .as_ref()
            .and_then(|t| f.schedules.get_in(t.epoch, t.schedule_version))
            .or(f.schedules.latest())
            .filter(|s| real(&s.epoch) && self.can_fire(s))
            .cloned()
            .unwrap_or_else(|| self.latest_schedule().clone());
        let schedule = Schedule {
            version: 1,
            effective_cycle: 0,
            epoch: self.epoch,
            ..base
        };
        // The first cycle whose trigger can still go out in time, on the
        // followed rhythm (or a start delay from now if nothing was followed).
        let mut start = match &f.last_trigger {
            Some(t) => t.start + t.period(&schedule),
            None => now + self.config.start_delay,
        };
        // Whole periods up to the first start still ahead of the trigger
        // lead (in i128: a followed start may lie anywhere in i64).
        let period = i128::from(schedule.cycle_period.as_nanos().max(1));
        let due = i128::from((now + self.config.trigger_lead).as_nanos());
        let behind = due - i128::from(start.as_nanos());
        if behind > 0 {
            let periods = (behind + period - 1) / period;
            let at = i128::from(start.as_nanos()) + periods * period;
            start = Time::from_nanos(i64::try_from(at).unwrap_or(i64::MAX));
        }
        self.schedules = vec![schedule.clone()];
        self.next_cycle = 0;
        self.next_start = start;
        self.sent_triggers.clear();
        self.next_reannounce = now + self.config.schedule_reannounce;
        tracing::warn!(
            "taking over as the active central unit: epoch {} (followed {:?}), cycle 0 at {}",
            self.epoch,
            followed,
            start
        );
        // The first cycle's trigger may be due at once (its start exactly
        // a trigger lead away): send it now, not at the next event.
        let mut out = vec![Output::Schedule(schedule)];
        out.extend(self.tick(now));
        out
    }

    /// Whether this site can fire `schedule`: some emission, every one by
    /// a transmitter of the site, every cell of the site. A schedule that
    /// names none (a forged one followed) is not taken over: the site's
    /// own is, or the site would stay silent under the new epoch.
    fn can_fire(&self, schedule: &Schedule) -> bool {
        !schedule.emissions.is_empty()
            && schedule
                .emissions
                .iter()
                .all(|e| self.site.transmitter(e.tx_id).is_some())
            && schedule
                .active_cells
                .iter()
                .all(|c| self.site.cell(c).is_some())
    }

    /// Hears a newer epoch's schedule while active: another central unit
    /// took over; this one steps down and follows it.
    pub(super) fn step_down(&mut self, schedule: &Schedule) {
        tracing::warn!(
            "a central unit of a newer epoch ({} > {}) is active: standing by",
            schedule.epoch,
            self.epoch
        );
        let mut schedules = ScheduleBook::new();
        let _ = schedules.offer(schedule.clone());
        self.standby = Some(Follower {
            schedules,
            last_trigger: None,
            lease_end: self.next_start + schedule.cycle_period * LEASE_CYCLES,
        });
    }

    /// The same for a newer epoch's trigger.
    pub(super) fn step_down_for(&mut self, trigger: CycleTrigger, now: Time) {
        tracing::warn!(
            "a central unit of a newer epoch ({} > {}) is active: standing by",
            trigger.epoch,
            self.epoch
        );
        self.standby = Some(Follower {
            schedules: ScheduleBook::new(),
            last_trigger: None,
            lease_end: trigger.start,
        });
        self.follow_trigger(trigger, now);
    }
}

#[cfg(test)]
mod tests;
