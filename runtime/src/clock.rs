//! Time sources: the system clock as a [`Time`], and the simulated device
//! clock that gives a node an injected offset and drift.

use std::time::{SystemTime, UNIX_EPOCH};

use ickon_proto::time::Time;

/// The system clock as a [`Time`] since the Unix epoch. In a real-time
/// simulation this is the true time base; on a real site the master's.
pub fn system_now() -> Time {
    let ns = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    Time::from_nanos(i64::try_from(ns).unwrap_or(i64::MAX))
}

/// A device clock: true time plus an offset and a drift from a reference instant.
/// `local = true + offset + drift * (true - reference)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedClock {
    reference: Time,
    offset_ns: i64,
    drift: f64,
}

impl SimulatedClock {
    /// A clock that reads `true + offset_ns` at `reference` and gains `drift` seconds per second.
    pub fn new(reference: Time, offset_ns: i64, drift: f64) -> Self {
        Self {
            reference,
            offset_ns,
            drift: if drift.is_finite() { drift } else { 0.0 },
        }
    }

    /// The local reading at true time `t`.
    pub fn local(&self, t: Time) -> Time {
        let since = t.since(self.reference).as_nanos() as f64;
        Time::from_nanos(t.as_nanos() + self.offset_ns + (self.drift * since).round() as i64)
    }

    /// The true time at which the clock reads `local`.
    pub fn true_time(&self, local: Time) -> Time {
        let base = local.as_nanos() - self.offset_ns - self.reference.as_nanos();
        let since = (base as f64 / (1.0 + self.drift)).round() as i64;
        Time::from_nanos(self.reference.as_nanos() + since)
    }

    /// The local reading now (from the system clock).
    pub fn now(&self) -> Time {
        self.local(system_now())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulated_clock_inverts_exactly_enough() {
        let c = SimulatedClock::new(Time(1_000_000_000_000), -50_000_000, 100e-6);
        for t in [1_000_000_000_000i64, 1_030_000_000_000, 1_100_000_000_000] {
            let local = c.local(Time(t));
            assert!((c.true_time(local).as_nanos() - t).abs() <= 1, "{t}");
        }
        // 30 s after the reference the clock has gained 3 ms on top of its -50 ms.
        let l = c.local(Time(1_030_000_000_000));
        assert_eq!(l.as_nanos() - 1_030_000_000_000, -50_000_000 + 3_000_000);
    }
}
