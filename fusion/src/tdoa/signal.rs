//! One arrival of a cycle, the input checks, and the allocation-free subset
//! of signals the solver works on.

use nalgebra::Vector3;

use super::SolveError;
use super::sound::SoundError;

/// Most signals one cycle may carry: subsets are bit masks in a `u64`, which
/// keeps leave-one-out free of heap allocation.
pub const MAX_SIGNALS: usize = 64;

/// One transmitter heard in a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Signal {
    /// Transmitter id.
    pub tx_id: u32,
    /// Surveyed transmitter position, metres.
    pub tx_m: Vector3<f64>,
    /// `c (t_arrival - emission_offset)`, metres: the range plus the
    /// cycle's common unknown offset.
    pub pseudo_range_m: f64,
    /// Arrival time on the receiver's time axis, seconds (any origin shared
    /// by the cycle); the fix is stamped with the mean over the cycle.
    pub t_s: f64,
}

impl Signal {
    /// Builds a signal from its arrival time and scheduled emission offset,
    /// both on the receiver's time axis in seconds (any common origin).
    pub fn from_times(
        tx_id: u32,
        tx_m: Vector3<f64>,
        t_arrival_s: f64,
        emission_offset_s: f64,
        speed_of_sound_m_s: f64,
    ) -> Result<Self, SoundError> {
        if !(speed_of_sound_m_s > 0.0 && speed_of_sound_m_s.is_finite()) {
            return Err(SoundError::BadSpeed(speed_of_sound_m_s));
        }
        Ok(Self {
            tx_id,
            tx_m,
            pseudo_range_m: speed_of_sound_m_s * (t_arrival_s - emission_offset_s),
            t_s: t_arrival_s,
        })
    }
}

/// Checks what every entry point needs: finite numbers, unique ids, a count
/// within [`MAX_SIGNALS`] and at least `need`.
pub(crate) fn validate(signals: &[Signal], need: usize) -> Result<(), SolveError> {
    if signals.len() > MAX_SIGNALS {
        return Err(SolveError::TooManySignals {
            got: signals.len(),
            max: MAX_SIGNALS,
        });
    }
    for (index, s) in signals.iter().enumerate() {
        if !s.tx_m.iter().all(|v| v.is_finite()) {
            return Err(SolveError::NonFinite {
                field: "tx_m",
                index,
            });
        }
        if !s.pseudo_range_m.is_finite() {
            return Err(SolveError::NonFinite {
                field: "pseudo_range_m",
                index,
            });
        }
        if !s.t_s.is_finite() {
            return Err(SolveError::NonFinite {
                field: "t_s",
                index,
            });
        }
        if signals[..index].iter().any(|o| o.tx_id == s.tx_id) {
            return Err(SolveError::DuplicateTransmitter { tx_id: s.tx_id });
        }
    }
    if signals.len() < need {
        return Err(SolveError::TooFewSignals {
            got: signals.len(),
            need,
        });
    }
    Ok(())
}

/// A subset of the cycle's signals, as a bit mask over their indices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Subset(u64);

impl Subset {
    /// The first `n` signals (`n <= MAX_SIGNALS`).
    pub(crate) fn first(n: usize) -> Self {
        debug_assert!(n <= MAX_SIGNALS);
        Self(if n >= 64 { u64::MAX } else { (1u64 << n) - 1 })
    }

    /// No signal.
    pub(crate) fn empty() -> Self {
        Self(0)
    }

    /// This subset and signal `i` (`i < MAX_SIGNALS`).
    pub(crate) fn with(self, i: usize) -> Self {
        Self(self.0 | (1u64 << i))
    }

    /// Whether signal `i` is in the subset.
    pub(crate) fn contains(self, i: usize) -> bool {
        i < MAX_SIGNALS && self.0 & (1u64 << i) != 0
    }

    pub(crate) fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    pub(crate) fn without(self, i: usize) -> Self {
        Self(self.0 & !(1u64 << i))
    }

    /// Indices in increasing order.
    pub(crate) fn iter(self) -> impl Iterator<Item = usize> {
        let mut bits = self.0;
        std::iter::from_fn(move || {
            if bits == 0 {
                return None;
            }
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            Some(i)
        })
    }

    /// The selected signals, in order.
    pub(crate) fn of(self, signals: &[Signal]) -> impl Iterator<Item = &Signal> {
        self.iter().map(move |i| &signals[i])
    }
}
