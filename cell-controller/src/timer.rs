//! The burst timer: which of this cell's transmitters fire when in a cycle,
//! on the local clock, and which slots must be skipped because the trigger
//! came too late. A slot is never fired late: a late burst would be heard as
//! a wrong time difference by every robot.
//!
//! A trigger is planned when it arrives, up to a cycle ahead; each burst is
//! then programmed into the transmitter [`PROGRAM_AHEAD`] before it fires,
//! with the newest clock estimate ([`BurstTimer::program`]): an unknown
//! drift of 100 ppm costs 40 us over the 0.4 s a plan can be ahead, 2 us
//! over 20 ms.

use ickon_proto::epoch::{ScheduleBook, ScheduleOffer, ScheduleRefused};
use ickon_proto::msg::control::{CycleTrigger, Schedule};
use ickon_proto::time::{Duration, Time};

use crate::sync::SyncEstimate;

/// One burst to fire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlannedBurst {
    /// Transmitter.
    pub tx_id: u32,
    /// Cycle number.
    pub cycle: u64,
    /// The epoch of the trigger (with `cycle`, names the cycle).
    pub epoch: u64,
    /// When to fire, on the master time base.
    pub master: Time,
    /// When to fire, on the local clock.
    pub local: Time,
}

/// The plan of one trigger.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Plan {
    /// Bursts to fire, in time order.
    pub bursts: Vec<PlannedBurst>,
    /// Slots skipped because their time had passed (or nearly).
    pub skipped: u64,
}

/// Why a trigger cannot be planned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TimerError {
    /// The trigger names a schedule version (of its epoch) this cell does not have.
    #[error("schedule version {0} is unknown to this cell")]
    UnknownSchedule(u32),
    /// The clock is not synchronised yet.
    #[error("clock not synchronised yet")]
    NotSynchronised,
}

/// Keeps the schedules a trigger may name and plans bursts.
#[derive(Debug, Clone)]
pub struct BurstTimer {
    cell_id: String,
    schedules: ScheduleBook,
    /// A burst must be planned at least this long before it fires.
    pub margin: Duration,
}

/// How long before its time a burst is programmed into the transmitter.
pub const PROGRAM_AHEAD: Duration = Duration::from_millis(20);

impl BurstTimer {
    /// A timer for `cell_id`.
    pub fn new(cell_id: &str, margin: Duration) -> Self {
        Self {
            cell_id: cell_id.to_string(),
            schedules: ScheduleBook::new(),
            margin,
        }
    }

    /// Remembers a schedule if the rules of [`ickon_proto::epoch`] allow it
    /// (a newer epoch replaces every schedule of the old one).
    pub fn add_schedule(&mut self, schedule: Schedule) -> Result<ScheduleOffer, ScheduleRefused> {
        self.schedules.offer(schedule)
    }

    /// Forgets every schedule, keeping the epoch followed.
    pub fn forget_schedules(&mut self) {
        self.schedules.clear();
    }

    /// Whether schedule `version` of `epoch` is known.
    pub fn has_schedule(&self, epoch: u64, version: u32) -> bool {
        self.schedules.get_in(epoch, version).is_some()
    }

    /// The epoch of the schedules held.
    pub fn epoch(&self) -> Option<u64> {
        self.schedules.epoch()
    }

    /// The cycle period of schedule `version` of `epoch`, if held.
    pub fn cycle_period(&self, epoch: u64, version: u32) -> Option<Duration> {
        self.schedules
            .get_in(epoch, version)
            .map(|s| s.cycle_period)
    }

    /// The bursts this cell fires for `trigger`, given the local time now.
    pub fn plan(
        &self,
        trigger: &CycleTrigger,
        sync: Option<&SyncEstimate>,
        local_now: Time,
    ) -> Result<Plan, TimerError> {
        let schedule = self
            .schedules
            .get_in(trigger.epoch, trigger.schedule_version)
            .ok_or(TimerError::UnknownSchedule(trigger.schedule_version))?;
        let sync = sync.ok_or(TimerError::NotSynchronised)?;
        let mut plan = Plan::default();
        // The trigger may name only some transmitters, at offsets of its own.
        for e in trigger
            .emissions(schedule)
            .iter()
            .filter(|e| e.cell_id == self.cell_id)
        {
            let master = trigger.start + e.offset;
            let local = sync.to_local(master);
            if local < local_now + self.margin {
                plan.skipped += 1;
            } else {
                plan.bursts.push(PlannedBurst {
                    tx_id: e.tx_id,
                    cycle: trigger.cycle,
                    epoch: trigger.epoch,
                    master,
                    local,
                });
            }
        }
        plan.bursts.sort_by_key(|b| b.local);
        Ok(plan)
    }
}

impl BurstTimer {
    /// The final local firing time of a planned burst, from the newest clock
    /// estimate; `None` (skip it) when that time is less than the margin
    /// away at `local_now`.
    pub fn program(
        &self,
        burst: &PlannedBurst,
        sync: &SyncEstimate,
        local_now: Time,
    ) -> Option<PlannedBurst> {
        let local = sync.to_local(burst.master);
        (local >= local_now + self.margin).then_some(PlannedBurst { local, ..*burst })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schedule() -> Schedule {
        crate::fixtures::schedule(4)
    }

    fn sync(offset_ms: i64) -> SyncEstimate {
        SyncEstimate {
            reference: Time(0),
            offset_ns: (offset_ms * 1_000_000) as f64,
            drift: 0.0,
            sigma_ns: 1_000.0,
            samples: 8,
        }
    }

    /// Cycle 3 of schedule version 4, starting at 1 s on the master clock.
    fn trigger() -> CycleTrigger {
        CycleTrigger {
            cycle: 3,
            start: Time::from_nanos(1_000_000_000),
            schedule_version: 4,
            epoch: crate::fixtures::EPOCH,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        }
    }

    #[test]
    fn bursts_are_planned_on_the_local_clock() {
        let mut t = BurstTimer::new("c1", Duration::from_millis(1));
        t.add_schedule(schedule()).unwrap();
        let trigger = trigger();
        // master = local + 40 ms.
        let plan = t.plan(&trigger, Some(&sync(40)), Time(0)).unwrap();
        assert_eq!(plan.skipped, 0);
        let ids: Vec<u32> = plan.bursts.iter().map(|b| b.tx_id).collect();
        assert_eq!(ids, vec![11, 12]);
        assert_eq!(plan.bursts[0].local, Time::from_nanos(960_000_000));
        assert_eq!(plan.bursts[1].master, Time::from_nanos(1_025_000_000));
    }

    #[test]
    fn a_trigger_naming_its_firings_fires_only_those_at_its_offsets() {
        use ickon_proto::msg::control::Firing;
        let mut t = BurstTimer::new("c1", Duration::from_millis(1));
        t.add_schedule(schedule()).unwrap();
        let mut trigger = trigger();
        trigger.firing = vec![
            Firing {
                tx_id: 12,
                offset: Duration::from_millis(7),
            },
            // Another cell's, and one no schedule knows: not this cell's to fire.
            Firing {
                tx_id: 21,
                offset: Duration::ZERO,
            },
            Firing {
                tx_id: 99,
                offset: Duration::ZERO,
            },
        ];
        let plan = t.plan(&trigger, Some(&sync(0)), Time(0)).unwrap();
        assert_eq!(plan.bursts.len(), 1);
        assert_eq!(plan.bursts[0].tx_id, 12);
        assert_eq!(plan.bursts[0].master, Time::from_nanos(1_007_000_000));
    }

    #[test]
    fn slots_whose_time_has_passed_are_skipped_not_fired_late() {
        let mut t = BurstTimer::new("c1", Duration::from_millis(1));
        t.add_schedule(schedule()).unwrap();
        let trigger = trigger();
        let plan = t
            .plan(&trigger, Some(&sync(0)), Time::from_nanos(1_010_000_000))
            .unwrap();
        assert_eq!(plan.skipped, 1);
        assert_eq!(plan.bursts.len(), 1);
        assert_eq!(plan.bursts[0].tx_id, 12);
    }

    #[test]
    fn programming_uses_the_newest_estimate_and_never_fires_late() {
        let mut t = BurstTimer::new("c1", Duration::from_millis(1));
        t.add_schedule(schedule()).unwrap();
        let trigger = trigger();
        let plan = t.plan(&trigger, Some(&sync(40)), Time(0)).unwrap();
        // The estimate moved by 100 us since the plan: the burst follows it.
        let mut newer = sync(40);
        newer.offset_ns += 100_000.0;
        let b = t.program(&plan.bursts[0], &newer, Time::from_nanos(940_000_000));
        assert_eq!(b.unwrap().local, Time::from_nanos(959_900_000));
        // Woken too late to program it: skipped.
        assert_eq!(
            t.program(&plan.bursts[0], &newer, Time::from_nanos(959_000_000)),
            None
        );
    }

    #[test]
    fn unknown_schedule_and_no_sync_are_errors() {
        let mut t = BurstTimer::new("c1", Duration::from_millis(1));
        let trigger = CycleTrigger {
            cycle: 0,
            start: Time(0),
            schedule_version: 4,
            epoch: crate::fixtures::EPOCH,
            firing: Vec::new(),
            cycle_period: ickon_proto::time::Duration::ZERO,
        };
        assert_eq!(
            t.plan(&trigger, Some(&sync(0)), Time(0)),
            Err(TimerError::UnknownSchedule(4))
        );
        t.add_schedule(schedule()).unwrap();
        assert_eq!(
            t.plan(&trigger, None, Time(0)),
            Err(TimerError::NotSynchronised)
        );
        t.forget_schedules();
        assert!(!t.has_schedule(crate::fixtures::EPOCH, 4));
    }
}
