//! The one place where wire time (integer nanoseconds, [`Time`]) becomes
//! fusion time (`f64` seconds) and back.
//!
//! Fusion time counts seconds from an epoch one hour before the agent's
//! first input. Within 2^51 ns (about 26 days) of it, a nanosecond count
//! converts to `f64` seconds and back exactly (a division and a product by
//! 1e9 each round once; below 2^51 their sum stays under half a
//! nanosecond; failures begin a little past 2^51.5), so
//! a pose is stamped with the very nanosecond of the input it answers,
//! however large the wire times are (Unix time as `f64` seconds keeps only
//! a quarter of a microsecond). Beyond that, a nanosecond or two is lost.
//! The hour keeps late inputs (a history of seconds) at positive times.

use ickon_proto::time::{Duration, Time};

/// How far before the first input the epoch lies.
const EPOCH_LEAD: Duration = Duration::from_millis(3_600_000);

/// Converts between wire and fusion time; the epoch is fixed by the first
/// conversion.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusionClock {
    epoch: Option<Time>,
}

impl FusionClock {
    /// Fusion seconds of wire time `t` (fixing the epoch on the first call).
    pub fn to_fusion(&mut self, t: Time) -> f64 {
        let epoch = *self.epoch.get_or_insert(Time::from_nanos(
            t.as_nanos().saturating_sub(EPOCH_LEAD.as_nanos()),
        ));
        Duration::from_nanos(t.as_nanos().saturating_sub(epoch.as_nanos())).as_secs_f64()
    }

    /// Wire time of fusion seconds `t_s` (rounded to the nanosecond).
    pub fn to_wire(&self, t_s: f64) -> Time {
        match self.epoch {
            Some(epoch) => Time::from_nanos(
                epoch
                    .as_nanos()
                    .saturating_add(Duration::from_secs_f64(t_s).as_nanos()),
            ),
            None => Time::from_secs_f64(t_s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unix_nanoseconds_go_to_fusion_seconds_and_back_exactly() {
        let mut clock = FusionClock::default();
        let first = Time::from_nanos(1_764_000_000_123_456_789);
        assert_eq!(clock.to_fusion(first), 3_600.0);
        // Odd nanoseconds across the 25 days after the first input, and
        // the seconds before it that a late input can have.
        let mut t = first.as_nanos() - 2_000_000_001;
        while t < first.as_nanos() + 25 * 86_400 * 1_000_000_000 {
            let wire = Time::from_nanos(t);
            let t_s = clock.to_fusion(wire);
            assert_eq!(clock.to_wire(t_s), wire, "{t}");
            t += 377_777_777_777;
        }
        // What the conversion replaced: Unix seconds as f64 lose the nanoseconds.
        let lossy = Time::from_secs_f64(Time::from_nanos(1_764_000_000_123_456_789).as_secs_f64());
        assert_ne!(lossy, first);
    }

    #[test]
    fn nonsense_stamps_saturate_instead_of_overflowing() {
        let mut clock = FusionClock::default();
        clock.to_fusion(Time::from_nanos(i64::MIN + 5));
        let far = clock.to_fusion(Time::from_nanos(i64::MAX));
        assert!(far.is_finite() && far > 0.0);
        let _ = clock.to_wire(f64::NAN);
        let _ = clock.to_wire(f64::INFINITY);
    }
}
