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
//! The state holds [`CLOCK_SLOTS`] biases; a cell heard for the first time
//! (or again after the slot was given to another) takes the slot used
//! least recently, at its prior. What the old cell's bias was is forgotten:
//! when it is heard again it is learnt again.

use super::ground_state::{CLOCK, CLOCK_SLOTS, Cov, N, State};

/// The cell of each slot and when an arrival of it was last fused.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ClockSlots {
    slots: [Option<(u32, f64)>; CLOCK_SLOTS],
}

impl ClockSlots {
    /// The state index of `clock`'s bias at time `t_s`, giving it a slot
    /// (at the prior `sigma_m`, uncorrelated) if it has none. `None` when
    /// the clock is unknown or the states are switched off (`sigma_m` 0).
    pub fn column(
        &mut self,
        clock: Option<u32>,
        t_s: f64,
        sigma_m: f64,
        x: &mut State,
        p: &mut Cov,
    ) -> Option<usize> {
        let clock = clock?;
        if sigma_m.is_nan() || sigma_m <= 0.0 {
            return None;
        }
        if let Some(k) = self
            .slots
            .iter()
            .position(|s| s.is_some_and(|(c, _)| c == clock))
        {
            if let Some((_, last)) = &mut self.slots[k] {
                *last = last.max(t_s);
            }
            return Some(CLOCK + k);
        }
        let k = self
            .slots
            .iter()
            .position(Option::is_none)
            .or_else(|| {
                (0..CLOCK_SLOTS).min_by(|&a, &b| {
                    let at = |k: usize| self.slots[k].map_or(f64::NEG_INFINITY, |(_, t)| t);
                    at(a).total_cmp(&at(b))
                })
            })
            .unwrap_or(0);
        self.slots[k] = Some((clock, t_s));
        let c = CLOCK + k;
        x[c] = 0.0;
        for j in 0..N {
            p[(c, j)] = 0.0;
            p[(j, c)] = 0.0;
        }
        p[(c, c)] = sigma_m * sigma_m;
        Some(c)
    }

    /// State indices of the slots in use.
    pub fn used(&self) -> impl Iterator<Item = usize> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_some())
            .map(|(k, _)| CLOCK + k)
    }

    /// Forgets every cell (the state was started again at its prior).
    pub fn clear(&mut self) {
        self.slots = [None; CLOCK_SLOTS];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fifth_cell_takes_the_slot_used_least_recently_at_its_prior() {
        let mut slots = ClockSlots::default();
        let mut x = State::zeros();
        let mut p = Cov::identity();
        let cols: Vec<usize> = (0..4)
            .map(|c| {
                slots
                    .column(Some(c), f64::from(c), 0.03, &mut x, &mut p)
                    .unwrap()
            })
            .collect();
        assert_eq!(cols, vec![CLOCK, CLOCK + 1, CLOCK + 2, CLOCK + 3]);
        // Cell 0 is heard again: cell 1 is now the oldest.
        assert_eq!(
            slots.column(Some(0), 5.0, 0.03, &mut x, &mut p),
            Some(CLOCK)
        );
        x[CLOCK + 1] = 0.2;
        p[(CLOCK + 1, 0)] = 0.5;
        p[(0, CLOCK + 1)] = 0.5;
        assert_eq!(
            slots.column(Some(9), 6.0, 0.03, &mut x, &mut p),
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
        assert_eq!(slots.column(Some(1), 0.0, 0.0, &mut x, &mut p), None);
        assert_eq!(slots.used().count(), 0);
    }
}
