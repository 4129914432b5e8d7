//! Which cycle triggers a cell takes: those of the newest epoch it has seen
//! (a restarted central unit's first trigger is taken at once, its cycle 0
//! included), near now, and whose cycle number agrees with the time they
//! name. One trigger with an absurd cycle number (2^62) or from a replaced
//! central unit cannot move what the cell fires.
//!
//! Cycle numbers are bounded by time: within an epoch, a trigger `k` cycles
//! after the last one taken must start about `k` periods after it. If the
//! last one taken was itself the forgery, the real triggers are refused
//! until [`CONFIRMING_TRIGGERS`] of them agree among themselves; the count
//! then starts again from them.

use ickon_proto::epoch::plausible_epoch;
use ickon_proto::msg::control::CycleTrigger;
use ickon_proto::time::{Duration, Time};

/// A trigger is taken only if its cycle starts within this long of now:
/// the central unit sends it a few tens of milliseconds ahead, so anything
/// further is forged or broken, and planning it would hold bursts (and
/// memory) for a cycle that never comes. (An epoch is bounded the same way:
/// [`ickon_proto::epoch::plausible_epoch`].)
pub const TRIGGER_HORIZON: Duration = Duration::from_millis(10_000);

/// Consecutive triggers that agree with each other but not with the count
/// followed, after which the count follows them.
pub const CONFIRMING_TRIGGERS: u32 = 3;

/// Why a trigger was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum TriggerRefused {
    /// Its cycle starts too far from now.
    #[error("cycle {cycle} starts {ahead} from now")]
    Far {
        /// Its cycle.
        cycle: u64,
        /// How far ahead (negative: behind).
        ahead: Duration,
    },
    /// It comes from a central unit that has been replaced.
    #[error("epoch {got} is older than the epoch followed, {current}")]
    OldEpoch {
        /// Its epoch.
        got: u64,
        /// The epoch followed.
        current: u64,
    },
    /// Its epoch starts in the future.
    #[error("epoch {0} starts in the future")]
    FutureEpoch(u64),
    /// Its cycle was taken already, or is older than one taken.
    #[error("cycle {cycle} is not after cycle {last}, taken already")]
    Repeated {
        /// Its cycle.
        cycle: u64,
        /// The last cycle taken.
        last: u64,
    },
    /// Its cycle number does not agree with its start time.
    #[error("cycle {cycle} where its start time says cycle {expected}")]
    OffTheCount {
        /// Its cycle.
        cycle: u64,
        /// The cycle its start time gives.
        expected: u64,
    },
}

/// The gate's state: the epoch followed and the last trigger taken.
#[derive(Debug, Clone, Default)]
pub struct TriggerGate {
    epoch: Option<u64>,
    last: Option<CycleTrigger>,
    suspect: Option<(CycleTrigger, u32)>,
}

/// Whether `later` is where the count from `earlier` puts it, for a cycle
/// period of `period` (or the length `earlier` gave its own cycle, when it
/// named one: occupancy firing shortens cycles; `later`'s own claim is not
/// trusted): `Err(expected)` if not. The tolerance (one cycle, and an
/// eighth of the gap) covers a period change between the two.
fn on_the_count(earlier: &CycleTrigger, later: &CycleTrigger, period: Duration) -> Result<(), u64> {
    let period = if earlier.cycle_period > Duration::ZERO {
        earlier.cycle_period
    } else {
        period
    };
    let gap_ns = later.start.since(earlier.start).as_nanos() as f64;
    let cycles = (gap_ns / period.as_nanos().max(1) as f64).round();
    let expected_f = earlier.cycle as f64 + cycles;
    let expected = if expected_f <= 0.0 {
        0
    } else if expected_f >= u64::MAX as f64 {
        u64::MAX
    } else {
        expected_f as u64
    };
    let tolerance = 1 + expected.abs_diff(earlier.cycle) / 8;
    if later.cycle.abs_diff(expected) <= tolerance && later.cycle > earlier.cycle {
        Ok(())
    } else {
        Err(expected)
    }
}

impl TriggerGate {
    /// A gate that has seen nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The epoch followed.
    pub fn epoch(&self) -> Option<u64> {
        self.epoch
    }

    /// Follows `epoch` if it is newer (a schedule of a restarted central
    /// unit came first); `false` if it is older than the one followed.
    pub fn note_epoch(&mut self, epoch: u64) -> bool {
        match self.epoch {
            Some(e) if epoch < e => false,
            Some(e) if epoch == e => true,
            _ => {
                self.epoch = Some(epoch);
                self.last = None;
                self.suspect = None;
                true
            }
        }
    }

    /// Takes `trigger` or says why not. `master_now` is now on the master
    /// time base (`None` before the clock is synchronised: no time bound
    /// then), `period` the cycle period of the schedule it names (`None`
    /// if unknown: no count check then). `Ok(true)`: it opened a new epoch.
    pub fn admit(
        &mut self,
        trigger: &CycleTrigger,
        master_now: Option<Time>,
        period: Option<Duration>,
    ) -> Result<bool, TriggerRefused> {
        if let Some(now) = master_now {
            let ahead = trigger.start.since(now);
            if ahead.as_nanos().unsigned_abs() > TRIGGER_HORIZON.as_nanos().unsigned_abs() {
                return Err(TriggerRefused::Far {
                    cycle: trigger.cycle,
                    ahead,
                });
            }
            if !plausible_epoch(trigger.epoch, now) {
                return Err(TriggerRefused::FutureEpoch(trigger.epoch));
            }
        }
        if let Some(current) = self.epoch
            && trigger.epoch < current
        {
            return Err(TriggerRefused::OldEpoch {
                got: trigger.epoch,
                current,
            });
        }
        if self.epoch != Some(trigger.epoch) {
            self.note_epoch(trigger.epoch);
            self.last = Some(trigger.clone());
            return Ok(true);
        }
        let Some(last) = self.last.clone() else {
            self.last = Some(trigger.clone());
            return Ok(false);
        };
        if trigger.cycle <= last.cycle && trigger.start <= last.start {
            return Err(TriggerRefused::Repeated {
                cycle: trigger.cycle,
                last: last.cycle,
            });
        }
        let Some(period) = period else {
            self.last = Some(trigger.clone());
            return Ok(false);
        };
        match on_the_count(&last, trigger, period) {
            Ok(()) => {
                self.last = Some(trigger.clone());
                self.suspect = None;
                Ok(false)
            }
            Err(expected) => {
                let agreeing = match &self.suspect {
                    Some((s, n)) if on_the_count(s, trigger, period).is_ok() => n + 1,
                    _ => 1,
                };
                if agreeing >= CONFIRMING_TRIGGERS {
                    tracing::info!(
                        "{agreeing} triggers agree on cycle {}: the count follows them",
                        trigger.cycle
                    );
                    self.last = Some(trigger.clone());
                    self.suspect = None;
                    return Ok(false);
                }
                self.suspect = Some((trigger.clone(), agreeing));
                Err(TriggerRefused::OffTheCount {
                    cycle: trigger.cycle,
                    expected,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests;
