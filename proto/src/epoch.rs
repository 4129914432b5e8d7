//! Epochs and the schedule book: the rules every receiver of the control
//! plane applies, so that a restarted central unit is recognised at its
//! first message and no single control message can stop the site.
//!
//! - An epoch is the start of a central unit (or of its term as the active
//!   one) on the master time base, in nanoseconds ([`epoch_of`]). Epochs only
//!   grow: a message of an older epoch comes from a central unit that has
//!   been replaced and is refused; a newer one replaces everything known of
//!   the old (schedules, cycle numbers).
//! - Within an epoch, schedule versions only move forward and a published
//!   version never changes: the same `(epoch, version)` with other content is
//!   refused ([`ScheduleRefused::Altered`]), and so is a version older than
//!   the newest known that was never seen ([`ScheduleRefused::Backwards`]).
//!   The same schedule again (the central unit re-announces it
//!   periodically) is a [`ScheduleOffer::Repeat`].
//! - A schedule that cannot be fired (no or a huge cycle period, no
//!   emission, emissions outside the cycle or of cells it does not include,
//!   more emissions than a site can have) is refused before anything else
//!   ([`ScheduleRefused::Invalid`]), by every receiver: cells, MSUs and a
//!   standby central unit alike.

use std::collections::BTreeMap;

use crate::msg::control::Schedule;
use crate::time::{Duration, Time};

/// The epoch of a central unit that starts (or becomes active) at master
/// time `now`, never at or below `after` (the epoch it follows, if any):
/// epochs stay ordered even if the clock reads less than the last one.
pub fn epoch_of(now: Time, after: Option<u64>) -> u64 {
    let from_clock = u64::try_from(now.as_nanos()).unwrap_or(0);
    match after {
        Some(a) => from_clock.max(a.saturating_add(1)),
        None => from_clock,
    }
}

/// The master time an epoch stands for (its start), for comparing it with
/// a clock: an epoch in the future of the master clock cannot be real.
pub fn epoch_start(epoch: u64) -> Time {
    Time::from_nanos(i64::try_from(epoch).unwrap_or(i64::MAX))
}

/// How far ahead of the master clock an epoch may lie and be real: an
/// epoch is a central unit's start, so one further ahead was forged (or is
/// broken). The cells refuse it, and a central unit neither stands by for it
/// nor takes it over.
pub const EPOCH_HORIZON: Duration = Duration::from_millis(10_000);

/// Whether `epoch` can be a central unit's start, seen at master time `now`
/// (not beyond [`EPOCH_HORIZON`] ahead).
pub fn plausible_epoch(epoch: u64, now: Time) -> bool {
    epoch_start(epoch).since(now) <= EPOCH_HORIZON
}

/// The longest cycle period a schedule may have (a site fires at least once a minute).
pub const MAX_CYCLE_PERIOD: Duration = Duration::from_millis(60_000);

/// The shortest cycle period a schedule may have: a cycle carries at least
/// one ultrasonic burst (2 ms by default, `burst_length_ms` of the site
/// file) and its flight. Below it a schedule is garbage or forged; taken,
/// a period of nanoseconds would make a standby's lease of a few cycles
/// run out at once.
pub const MIN_CYCLE_PERIOD: Duration = Duration::from_millis(1);

/// More emissions per cycle than any site has (a cell has a handful of
/// transmitters; 4096 would be a site of a thousand cells).
pub const MAX_EMISSIONS: usize = 4096;

/// Why a schedule was not taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ScheduleRefused {
    /// Its numbers cannot be real.
    #[error("schedule v{version} of epoch {epoch} is invalid: {why}")]
    Invalid {
        /// The epoch it names.
        epoch: u64,
        /// Its version.
        version: u32,
        /// What is wrong.
        why: &'static str,
    },
    /// It comes from a central unit older than the one followed.
    #[error("schedule of epoch {got} is from a replaced central unit (following epoch {current})")]
    OldEpoch {
        /// Its epoch.
        got: u64,
        /// The epoch followed.
        current: u64,
    },
    /// The same version was published with other content.
    #[error(
        "schedule v{version} of epoch {epoch} differs from the one published under that version"
    )]
    Altered {
        /// The epoch.
        epoch: u64,
        /// The version.
        version: u32,
    },
    /// A version older than the newest known, never seen before.
    #[error("schedule v{got} is older than v{newest} (versions only move forward)")]
    Backwards {
        /// Its version.
        got: u32,
        /// The newest version known.
        newest: u32,
    },
}

/// What taking a schedule did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScheduleOffer {
    /// A new version of the epoch followed.
    New,
    /// A schedule known already (a re-announcement, or a query's answer).
    Repeat,
    /// The first schedule of a newer epoch: everything of the old one was forgotten.
    NewEpoch,
}

/// Checks the numbers of a schedule that do not depend on the site.
pub fn check_schedule(s: &Schedule) -> Result<(), ScheduleRefused> {
    let invalid = |why| ScheduleRefused::Invalid {
        epoch: s.epoch,
        version: s.version,
        why,
    };
    if s.cycle_period < MIN_CYCLE_PERIOD || s.cycle_period > MAX_CYCLE_PERIOD {
        return Err(invalid("cycle period out of range (1 ms to 60 s)"));
    }
    if s.slot_length <= Duration::ZERO || s.slot_length > s.cycle_period {
        return Err(invalid("slot length out of range"));
    }
    if s.emissions.is_empty() {
        return Err(invalid("no emission: a cycle of it fires nothing"));
    }
    if s.emissions.len() > MAX_EMISSIONS {
        return Err(invalid("too many emissions"));
    }
    if s.emissions
        .iter()
        .any(|e| !s.active_cells.contains(&e.cell_id))
    {
        return Err(invalid(
            "an emission belongs to a cell the schedule does not include",
        ));
    }
    if s.emissions
        .iter()
        .any(|e| e.offset < Duration::ZERO || e.offset >= s.cycle_period)
    {
        return Err(invalid("an emission lies outside the cycle"));
    }
    Ok(())
}

/// The schedules of the epoch followed, by version, under the rules of the
/// module doc. Bounded: only the newest [`ScheduleBook::KEPT`] versions are kept.
#[derive(Debug, Clone, Default)]
pub struct ScheduleBook {
    epoch: Option<u64>,
    schedules: BTreeMap<u32, Schedule>,
    refused: u64,
}

impl ScheduleBook {
    /// Versions kept besides the newest (a trigger may name one a little
    /// older than the newest while a change takes effect).
    pub const KEPT: usize = 8;

    /// An empty book, following no epoch yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes `schedule` if the rules allow it.
    pub fn offer(&mut self, schedule: Schedule) -> Result<ScheduleOffer, ScheduleRefused> {
        let verdict = self.judge(&schedule);
        match verdict {
            Err(_) => self.refused += 1,
            Ok(ScheduleOffer::Repeat) => {}
            Ok(ScheduleOffer::NewEpoch) => {
                self.schedules.clear();
                self.epoch = Some(schedule.epoch);
                self.schedules.insert(schedule.version, schedule);
            }
            Ok(ScheduleOffer::New) => {
                self.schedules.insert(schedule.version, schedule);
                while self.schedules.len() > Self::KEPT {
                    self.schedules.pop_first();
                }
            }
        }
        verdict
    }

    /// What [`offer`](Self::offer) would do with `schedule`, without taking it.
    pub fn judge(&self, schedule: &Schedule) -> Result<ScheduleOffer, ScheduleRefused> {
        check_schedule(schedule)?;
        match self.epoch {
            Some(current) if schedule.epoch < current => Err(ScheduleRefused::OldEpoch {
                got: schedule.epoch,
                current,
            }),
            Some(current) if schedule.epoch == current => {
                if let Some(known) = self.schedules.get(&schedule.version) {
                    return if known == schedule {
                        Ok(ScheduleOffer::Repeat)
                    } else {
                        Err(ScheduleRefused::Altered {
                            epoch: current,
                            version: schedule.version,
                        })
                    };
                }
                match self.newest_version() {
                    Some(newest) if schedule.version < newest => Err(ScheduleRefused::Backwards {
                        got: schedule.version,
                        newest,
                    }),
                    _ => Ok(ScheduleOffer::New),
                }
            }
            _ => Ok(ScheduleOffer::NewEpoch),
        }
    }

    /// Forgets every schedule but keeps the epoch, so that older epochs stay refused.
    pub fn clear(&mut self) {
        self.schedules.clear();
    }

    /// The epoch followed (that of the schedules held).
    pub fn epoch(&self) -> Option<u64> {
        self.epoch
    }

    /// Version `version` of the epoch followed.
    pub fn get(&self, version: u32) -> Option<&Schedule> {
        self.schedules.get(&version)
    }

    /// Schedule `(epoch, version)`, if it is held.
    pub fn get_in(&self, epoch: u64, version: u32) -> Option<&Schedule> {
        (self.epoch == Some(epoch))
            .then(|| self.schedules.get(&version))
            .flatten()
    }

    /// The newest schedule held.
    pub fn latest(&self) -> Option<&Schedule> {
        self.schedules.values().next_back()
    }

    /// The schedule in force for `cycle` of the epoch followed: the newest
    /// whose effective cycle has come, else the oldest held.
    pub fn for_cycle(&self, cycle: u64) -> Option<&Schedule> {
        self.schedules
            .values()
            .rev()
            .find(|s| s.effective_cycle <= cycle)
            .or_else(|| self.schedules.values().next())
    }

    /// Schedules refused so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    fn newest_version(&self) -> Option<u32> {
        self.schedules.keys().next_back().copied()
    }
}

#[cfg(test)]
mod tests;
