//! Time sources: the system clock as a [`Time`], and the simulated device
//! clock that gives a node an injected offset and drift.

use std::sync::atomic::{AtomicI64, Ordering};
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

/// The steps this process's device clock took at run time, nanoseconds
/// (simulation only: `ickon sim --faults clockstep:`, see
/// [`crate::clock_steps`]). One per process, as a device has one clock.
static STEPPED_NS: AtomicI64 = AtomicI64::new(0);

/// A device clock: true time plus an offset and a drift from a reference
/// instant, plus the steps it took at run time.
/// `local = true + offset + drift * (true - reference) + steps`.
#[derive(Debug, Clone, Copy)]
pub struct SimulatedClock {
    reference: Time,
    offset_ns: i64,
    drift: f64,
    stepped_ns: &'static AtomicI64,
}

impl PartialEq for SimulatedClock {
    fn eq(&self, other: &Self) -> bool {
        self.reference == other.reference
            && self.offset_ns == other.offset_ns
            && self.drift == other.drift
            && std::ptr::eq(self.stepped_ns, other.stepped_ns)
    }
}

impl SimulatedClock {
    /// A clock that reads `true + offset_ns` at `reference` and gains `drift` seconds per second.
    /// Its steps are the process's (see [`SimulatedClock::step`]).
    pub fn new(reference: Time, offset_ns: i64, drift: f64) -> Self {
        Self {
            reference,
            offset_ns,
            drift: if drift.is_finite() { drift } else { 0.0 },
            stepped_ns: &STEPPED_NS,
        }
    }

    /// The same clock with steps of its own instead of the process's
    /// (tests, and several simulated devices in one process).
    pub fn with_own_steps(self) -> Self {
        Self {
            stepped_ns: Box::leak(Box::new(AtomicI64::new(0))),
            ..self
        }
    }

    /// Steps the clock by `ns` from now on (every copy of it reads the
    /// step: they share it); saturates instead of overflowing.
    pub fn step(&self, ns: i64) {
        let _ = self
            .stepped_ns
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |s| {
                Some(s.saturating_add(ns))
            });
    }

    /// The sum of the steps taken, nanoseconds.
    pub fn stepped_ns(&self) -> i64 {
        self.stepped_ns.load(Ordering::Relaxed)
    }

    /// The local reading at true time `t`.
    pub fn local(&self, t: Time) -> Time {
        let since = t.since(self.reference).as_nanos() as f64;
        Time::from_nanos(
            t.as_nanos() + self.offset_ns + (self.drift * since).round() as i64 + self.stepped_ns(),
        )
    }

    /// The true time at which the clock reads `local`.
    pub fn true_time(&self, local: Time) -> Time {
        let base =
            local.as_nanos() - self.offset_ns - self.stepped_ns() - self.reference.as_nanos();
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

    #[test]
    fn a_step_moves_every_copy_of_the_clock_and_still_inverts() {
        let c = SimulatedClock::new(Time(1_000_000_000_000), 20_000, 10e-6).with_own_steps();
        let copy = c;
        let t = Time(1_010_000_000_000);
        let before = c.local(t);
        c.step(5_000_000);
        assert_eq!(copy.local(t).as_nanos() - before.as_nanos(), 5_000_000);
        assert!((copy.true_time(copy.local(t)).as_nanos() - t.as_nanos()).abs() <= 1);
        c.step(i64::MAX);
        c.step(1);
        assert_eq!(c.stepped_ns(), i64::MAX, "saturates");
        // Another clock of the process is not stepped.
        let other = SimulatedClock::new(Time(1_000_000_000_000), 20_000, 10e-6);
        assert_eq!(other.stepped_ns(), 0);
    }
}
