//! Each robot's share of the survey calibration, bounded by rate: an MSU
//! solves at most one fix a cycle, so a robot that sends more is broken or
//! forged, and without a bound one robot's flood of fixes would outweigh
//! the rest of the fleet and move every transmitter (up to the 0.25 m a
//! calibration corrects) and every cell's lateness. A token bucket per
//! robot of the site, and one shared by every id the site does not list
//! (so that ids made up by the thousand share one robot's rate and the
//! table stays bounded by the site): it refills at [`FIXES_PER_CYCLE`]
//! per cycle the central unit triggers (a standby: per cycle it hears the
//! active one trigger) and holds [`BURST_FIXES`].
//! Checked before anything else of the fix, so that a flood costs a map
//! look-up, not the fix's line-of-sight checks.

use std::collections::BTreeMap;

/// Fixes a robot may give per cycle on average: one, with a quarter to
/// spare for fixes delivered around a cycle's boundary.
pub const FIXES_PER_CYCLE: f64 = 1.25;

/// Fixes a robot may give at once: a few cycles' fixes delivered together
/// after a delay of the network.
pub const BURST_FIXES: f64 = 3.0;

/// The buckets, by robot (the empty key: every robot the site does not
/// list).
#[derive(Debug, Clone, Default)]
pub struct FixRate {
    buckets: BTreeMap<String, Bucket>,
}

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    /// The central unit's cycle when it was last refilled.
    cycle: u64,
    /// Fixes refused so far.
    refused: u64,
}

impl FixRate {
    /// Whether a fix of the robot `key` during the central unit's cycle
    /// `cycle` is within its share (taking it from the share if so); if
    /// not, `Err` with the robot's fixes refused so far, this one included.
    /// The share is counted in the cycles the central unit triggers, not
    /// in time: the firing plan shortens a cycle below the schedule's
    /// period, and a clock stepped either way moves no cycle.
    pub fn admit(&mut self, key: &str, cycle: u64) -> Result<(), u64> {
        let Some(b) = self.buckets.get_mut(key) else {
            self.buckets.insert(
                key.to_string(),
                Bucket {
                    tokens: BURST_FIXES - 1.0,
                    cycle,
                    refused: 0,
                },
            );
            return Ok(());
        };
        // Cycles counted again from 0 (a new epoch) refill nothing once.
        let cycles = cycle.saturating_sub(b.cycle) as f64;
        b.tokens = (b.tokens + cycles * FIXES_PER_CYCLE).min(BURST_FIXES);
        b.cycle = cycle;
        if b.tokens >= 1.0 {
            b.tokens -= 1.0;
            Ok(())
        } else {
            b.refused += 1;
            Err(b.refused)
        }
    }

    /// Fixes of the robot `key` refused so far.
    pub fn refused(&self, key: &str) -> u64 {
        self.buckets.get(key).map_or(0, |b| b.refused)
    }

    /// Robot `key` left: its bucket is dropped unless it was refused fixes
    /// (a count the admin shows). Coming back, it starts with a full burst,
    /// as it did the first time.
    pub fn forget(&mut self, key: &str) {
        if self.buckets.get(key).is_some_and(|b| b.refused == 0) {
            self.buckets.remove(key);
        }
    }

    /// Robots with a bucket.
    pub fn len(&self) -> usize {
        self.buckets.len()
    }

    /// Whether no robot has a bucket yet.
    pub fn is_empty(&self) -> bool {
        self.buckets.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_fix_a_cycle_is_always_taken_however_it_is_delivered() {
        let mut rate = FixRate::default();
        // Every cycle's fix; every seventh delayed by two cycles and
        // delivered with the next ones.
        let mut taken = 0;
        for k in 0..4_000u64 {
            let during = if k % 7 == 3 { k + 2 } else { k };
            taken += usize::from(rate.admit("r1", during).is_ok());
        }
        assert_eq!(taken, 4_000);
    }

    #[test]
    fn a_flood_is_held_to_the_rate_and_unknown_ids_share_one_share() {
        let mut rate = FixRate::default();
        // 100 fixes a cycle for 40 cycles from one robot.
        let taken = (0..4_000u64)
            .filter(|&k| rate.admit("r1", k / 100).is_ok())
            .count();
        // 39 cycles at 1.25 a cycle, and the burst.
        assert!((50..=52).contains(&taken), "{taken}");
        // Another robot is not held back by it.
        assert!(rate.admit("r2", 20).is_ok());
        // Made-up ids, all keyed as unknown by the core, share one bucket.
        let unknown = (0..1_000u32).filter(|_| rate.admit("", 50).is_ok()).count();
        assert_eq!(unknown, 3);
        assert_eq!(rate.refused(""), 997);
        assert_eq!(rate.refused("r1"), 4_000 - taken as u64);
        assert_eq!(rate.len(), 3);
    }

    #[test]
    fn cycles_counted_again_from_zero_refill_nothing_once_then_as_before() {
        let mut rate = FixRate::default();
        for _ in 0..3 {
            assert!(rate.admit("r1", 10_000).is_ok());
        }
        assert_eq!(rate.admit("r1", 10_000), Err(1));
        // A new epoch counts from 0: no refill across the reset, and no
        // robot left waiting for the old count to come round.
        assert_eq!(rate.admit("r1", 0), Err(2));
        assert!(rate.admit("r1", 1).is_ok());
        assert_eq!(rate.admit("r1", 1), Err(3));
    }
}
