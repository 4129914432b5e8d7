//! Which cell's clock bias each clock slot of the ground filter's state
//! holds.
//!
//! A cell fires its transmitters on its own estimate of the central unit's
//! time; what that estimate is off by (the sync error, tens to hundreds of
//! microseconds, more on a loaded network) delays or advances every burst
//! of the cell alike. Within a cell it cancels in each range difference;
//! between two cells it does not, and a robot on a cell border then reads a
//! range difference off by the two errors' difference times the speed of
//! sound (100 us: 3.4 cm). Treated as white noise it is counted as if it
//! averaged away over cycles, which it does not; as a state per cell it is
//! learnt from the differences between cells, while the differences inside
//! each cell keep giving the position.
//!
//! The prior of a cell's bias is the sync sigma the cell itself reports
//! (`cell/<id>/status`, handed over with each arrival by the MSU), at least
//! the configured floor: on a quiet network tens of microseconds, and the
//! states cost little; on a congested one hundreds, and they learn what
//! the cells' clocks are off by. Without a report and a floor there is no
//! state (a replayed recording, a radio anchor).
//!
//! The state holds [`CLOCK_SLOTS`] biases; a cell heard for the first time
//! (or again after the slot was given to another) takes the slot used
//! least recently, at its prior. What the old cell's bias was is forgotten:
//! when it is heard again it is learnt again.

use super::ground_state::{CLOCK, CLOCK_SLOTS, Cov, N, State};
use crate::estimator::TransmitterClock;

/// Largest sync sigma taken from a report, metres of path (10 ms of sound):
/// a report is network input, and beyond this the state is free anyway.
const MAX_REPORTED_SIGMA_M: f64 = 3.43;

/// One slot: its clock, when last used, and the sigma its prior came from.
#[derive(Debug, Clone, Copy)]
struct Slot {
    clock: u32,
    last_s: f64,
    sigma_m: f64,
}

/// The cell of each slot and when an arrival of it was last fused.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ClockSlots {
    slots: [Option<Slot>; CLOCK_SLOTS],
}

/// The prior sigma of `clock`: what its owner reports, at least `floor_m`.
fn sigma_of(clock: &TransmitterClock, floor_m: f64) -> f64 {
    let reported = if clock.sync_sigma_m.is_finite() {
        clock.sync_sigma_m.clamp(0.0, MAX_REPORTED_SIGMA_M)
    } else {
        0.0
    };
    reported.max(floor_m)
}

impl ClockSlots {
    /// The state index of `clock`'s bias at time `t_s`, giving it a slot
    /// (uncorrelated, at its prior) if it has none. The prior sigma is the
    /// one its owner reports, at least `floor_m`; when a later report is
    /// larger (the sync got worse), the bias's variance grows by the
    /// difference. `None` when the clock is unknown or its sigma is zero.
    pub fn column(
        &mut self,
        clock: Option<TransmitterClock>,
        t_s: f64,
        floor_m: f64,
        x: &mut State,
        p: &mut Cov,
    ) -> Option<usize> {
        let clock = clock?;
        let sigma_m = sigma_of(&clock, floor_m);
        if sigma_m.is_nan() || sigma_m <= 0.0 {
            return None;
        }
        let known = self
            .slots
            .iter()
            .position(|s| s.is_some_and(|s| s.clock == clock.id));
        if let Some(k) = known {
            let c = CLOCK + k;
            if let Some(slot) = &mut self.slots[k] {
                slot.last_s = slot.last_s.max(t_s);
                if sigma_m > slot.sigma_m {
                    p[(c, c)] += sigma_m * sigma_m - slot.sigma_m * slot.sigma_m;
                    slot.sigma_m = sigma_m;
                }
            }
            return Some(c);
        }
        let k = self
            .slots
            .iter()
            .position(Option::is_none)
            .or_else(|| {
                (0..CLOCK_SLOTS).min_by(|&a, &b| {
                    let at = |k: usize| self.slots[k].map_or(f64::NEG_INFINITY, |s| s.last_s);
                    at(a).total_cmp(&at(b))
                })
            })
            .unwrap_or(0);
        self.slots[k] = Some(Slot {
            clock: clock.id,
            last_s: t_s,
            sigma_m,
        });
        let c = CLOCK + k;
        x[c] = 0.0;
        for j in 0..N {
            p[(c, j)] = 0.0;
            p[(j, c)] = 0.0;
        }
        p[(c, c)] = sigma_m * sigma_m;
        Some(c)
    }

    /// State indices of the slots in use, with the sigma of each.
    pub fn used(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter_map(|(k, s)| s.map(|s| (CLOCK + k, s.sigma_m)))
    }

    /// Forgets every cell (the state was started again at its prior).
    pub fn clear(&mut self) {
        self.slots = [None; CLOCK_SLOTS];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clock(id: u32, sync_sigma_m: f64) -> TransmitterClock {
        TransmitterClock { id, sync_sigma_m }
    }

    #[test]
    fn a_fifth_cell_takes_the_slot_used_least_recently_at_its_prior() {
        let mut slots = ClockSlots::default();
        let mut x = State::zeros();
        let mut p = Cov::identity();
        let cols: Vec<usize> = (0..4)
            .map(|c| {
                slots
                    .column(Some(clock(c, 0.0)), f64::from(c), 0.03, &mut x, &mut p)
                    .unwrap()
            })
            .collect();
        assert_eq!(cols, vec![CLOCK, CLOCK + 1, CLOCK + 2, CLOCK + 3]);
        // Cell 0 is heard again: cell 1 is now the oldest.
        assert_eq!(
            slots.column(Some(clock(0, 0.0)), 5.0, 0.03, &mut x, &mut p),
            Some(CLOCK)
        );
        x[CLOCK + 1] = 0.2;
        p[(CLOCK + 1, 0)] = 0.5;
        p[(0, CLOCK + 1)] = 0.5;
        assert_eq!(
            slots.column(Some(clock(9, 0.0)), 6.0, 0.03, &mut x, &mut p),
            Some(CLOCK + 1)
        );
        assert_eq!(x[CLOCK + 1], 0.0);
        assert_eq!(p[(CLOCK + 1, 0)], 0.0);
        assert!((p[(CLOCK + 1, CLOCK + 1)] - 0.03 * 0.03).abs() < 1e-15);
        assert_eq!(slots.used().count(), 4);
    }

    #[test]
    fn no_slot_without_a_clock_or_with_the_states_off() {
        let mut slots = ClockSlots::default();
        let (mut x, mut p) = (State::zeros(), Cov::identity());
        assert_eq!(slots.column(None, 0.0, 0.03, &mut x, &mut p), None);
        assert_eq!(
            slots.column(Some(clock(1, 0.0)), 0.0, 0.0, &mut x, &mut p),
            None
        );
        assert_eq!(slots.used().count(), 0);
    }

    #[test]
    fn the_reported_sigma_sets_the_prior_and_a_worse_report_widens_it() {
        let mut slots = ClockSlots::default();
        let (mut x, mut p) = (State::zeros(), Cov::identity());
        let c = slots
            .column(Some(clock(3, 0.05)), 0.0, 0.01, &mut x, &mut p)
            .unwrap();
        assert!((p[(c, c)] - 0.05 * 0.05).abs() < 1e-15);
        // Learnt down to 1 cm; the same report again changes nothing.
        p[(c, c)] = 1e-4;
        slots.column(Some(clock(3, 0.05)), 1.0, 0.01, &mut x, &mut p);
        assert!((p[(c, c)] - 1e-4).abs() < 1e-15);
        // The sync got worse: the variance grows by the difference.
        slots.column(Some(clock(3, 0.1)), 2.0, 0.01, &mut x, &mut p);
        assert!((p[(c, c)] - (1e-4 + 0.01 - 0.0025)).abs() < 1e-12);
        // A report of nonsense falls back on the floor or the bound.
        let d = slots
            .column(Some(clock(4, f64::NAN)), 3.0, 0.01, &mut x, &mut p)
            .unwrap();
        assert!((p[(d, d)] - 1e-4).abs() < 1e-15);
        let e = slots
            .column(Some(clock(5, 1e300)), 3.0, 0.0, &mut x, &mut p)
            .unwrap();
        assert!((p[(e, e)] - MAX_REPORTED_SIGMA_M.powi(2)).abs() < 1e-9);
    }
}
