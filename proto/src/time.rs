//! Integer-nanosecond time types shared by the wire format and the cores.
//!
//! A [`Time`] is an instant on some time base (the master time base of the
//! central unit, a device clock, or the simulation's true time); which one is
//! part of the field's documentation, never implied. Integer nanoseconds keep
//! arithmetic exact and deterministic across machines; conversion to `f64`
//! seconds happens at the edge of the numeric code.

use serde::{Deserialize, Serialize};

/// Nanoseconds in one second.
pub const NANOS_PER_SECOND: i64 = 1_000_000_000;

/// An instant, in nanoseconds since the epoch of its time base.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Time(pub i64);

/// A signed span of time, in nanoseconds.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Duration(pub i64);

impl Time {
    /// The epoch of the time base.
    pub const ZERO: Time = Time(0);

    /// Builds a time from nanoseconds.
    pub const fn from_nanos(ns: i64) -> Self {
        Time(ns)
    }

    /// Nanoseconds since the epoch.
    pub const fn as_nanos(self) -> i64 {
        self.0
    }

    /// Builds a time from seconds, rounded to the nearest nanosecond
    /// (saturating; a non-finite input gives the epoch).
    pub fn from_secs_f64(s: f64) -> Self {
        Time(secs_to_nanos(s))
    }

    /// Seconds since the epoch as `f64` (exact to the nanosecond for about 104 days).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / NANOS_PER_SECOND as f64
    }

    /// The span from `earlier` to `self` (saturating).
    pub fn since(self, earlier: Time) -> Duration {
        Duration(self.0.saturating_sub(earlier.0))
    }
}

impl Duration {
    /// No time at all.
    pub const ZERO: Duration = Duration(0);

    /// Builds a duration from nanoseconds.
    pub const fn from_nanos(ns: i64) -> Self {
        Duration(ns)
    }

    /// Builds a duration from microseconds (saturating).
    pub const fn from_micros(us: i64) -> Self {
        Duration(us.saturating_mul(1_000))
    }

    /// Builds a duration from milliseconds (saturating).
    pub const fn from_millis(ms: i64) -> Self {
        Duration(ms.saturating_mul(1_000_000))
    }

    /// Builds a duration from seconds, rounded to the nearest nanosecond
    /// (saturating; a non-finite input gives zero).
    pub fn from_secs_f64(s: f64) -> Self {
        Duration(secs_to_nanos(s))
    }

    /// Nanoseconds.
    pub const fn as_nanos(self) -> i64 {
        self.0
    }

    /// Seconds as `f64`.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / NANOS_PER_SECOND as f64
    }

    /// Converts to a `std::time::Duration`; negative spans become zero.
    pub fn to_std(self) -> std::time::Duration {
        std::time::Duration::from_nanos(self.0.max(0) as u64)
    }
}

fn secs_to_nanos(s: f64) -> i64 {
    if !s.is_finite() {
        return 0;
    }
    // `as` saturates at the i64 bounds, which is what we want for absurd inputs.
    (s * NANOS_PER_SECOND as f64).round() as i64
}

impl std::ops::Add<Duration> for Time {
    type Output = Time;
    fn add(self, rhs: Duration) -> Time {
        Time(self.0.saturating_add(rhs.0))
    }
}

impl std::ops::Sub<Duration> for Time {
    type Output = Time;
    fn sub(self, rhs: Duration) -> Time {
        Time(self.0.saturating_sub(rhs.0))
    }
}

impl std::ops::Sub for Time {
    type Output = Duration;
    fn sub(self, rhs: Time) -> Duration {
        self.since(rhs)
    }
}

impl std::ops::Add for Duration {
    type Output = Duration;
    fn add(self, rhs: Duration) -> Duration {
        Duration(self.0.saturating_add(rhs.0))
    }
}

impl std::ops::Sub for Duration {
    type Output = Duration;
    fn sub(self, rhs: Duration) -> Duration {
        Duration(self.0.saturating_sub(rhs.0))
    }
}

impl std::ops::Mul<i64> for Duration {
    type Output = Duration;
    fn mul(self, rhs: i64) -> Duration {
        Duration(self.0.saturating_mul(rhs))
    }
}

impl std::fmt::Display for Time {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.6} s", self.as_secs_f64())
    }
}

impl std::fmt::Display for Duration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ns = self.0;
        if ns.abs() < 10_000 {
            write!(f, "{ns} ns")
        } else if ns.abs() < 10_000_000 {
            write!(f, "{:.1} us", ns as f64 / 1e3)
        } else {
            write!(f, "{:.3} ms", ns as f64 / 1e6)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_round_trip_to_the_nanosecond() {
        let t = Time::from_secs_f64(1_234.567_890_123);
        assert_eq!(t.as_nanos(), 1_234_567_890_123);
        assert!((t.as_secs_f64() - 1_234.567_890_123).abs() < 1e-9);
    }

    #[test]
    fn non_finite_seconds_do_not_poison_time() {
        assert_eq!(Time::from_secs_f64(f64::NAN), Time::ZERO);
        assert_eq!(Duration::from_secs_f64(f64::INFINITY), Duration::ZERO);
    }

    #[test]
    fn arithmetic_saturates_instead_of_overflowing() {
        assert_eq!(Time(i64::MAX) + Duration(5), Time(i64::MAX));
        assert_eq!(Time(i64::MIN) - Duration(5), Time(i64::MIN));
        assert_eq!(Time(10) - Time(4), Duration(6));
    }

    #[test]
    fn durations_print_in_readable_units() {
        assert_eq!(Duration::from_nanos(500).to_string(), "500 ns");
        assert_eq!(Duration::from_micros(150).to_string(), "150.0 us");
        assert_eq!(Duration::from_millis(25).to_string(), "25.000 ms");
    }
}
