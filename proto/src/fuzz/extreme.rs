//! Numbers and times that break arithmetic: NaN, ±inf, the i64 bounds,
//! next to plausible ones so that cores get past their first checks.

use proptest::prelude::*;

use crate::time::{Duration, Time};

/// A float: NaN, ±inf, ±`f64::MAX`, a subnormal, zero, or a plausible one.
pub fn float() -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(f64::MAX),
        1 => Just(-f64::MAX),
        1 => Just(f64::MIN_POSITIVE / 2.0),
        1 => Just(0.0),
        4 => -100.0..100.0f64,
        1 => any::<f64>(),
    ]
}

/// A nanosecond offset: the i64 bounds, zero, or within ±`span` (either sign).
pub fn offset_ns(span: i64) -> impl Strategy<Value = i64> {
    prop_oneof![
        1 => Just(i64::MIN),
        1 => Just(i64::MAX),
        1 => Just(0),
        6 => -span..=span,
        1 => any::<i64>(),
    ]
}

/// A time around `now`: mostly within ±`span`, sometimes at the i64 bounds.
pub fn time_near(now: Time, span: Duration) -> impl Strategy<Value = Time> {
    offset_ns(span.as_nanos()).prop_map(move |d| now + Duration::from_nanos(d))
}

/// A step of a node's own clock between two events: mostly forward by up
/// to half a second, sometimes backwards (a clock step), sometimes a jump
/// of up to a day either way, rarely to the ends of time.
pub fn clock_step() -> impl Strategy<Value = Duration> {
    prop_oneof![
        12 => 0i64..500_000_000,
        2 => -1_000_000_000i64..0,
        1 => -86_400_000_000_000i64..86_400_000_000_000,
        1 => prop_oneof![Just(i64::MIN), Just(i64::MAX)],
    ]
    .prop_map(Duration::from_nanos)
}
