//! Logs of bad input, bounded: a node fed garbage (a broken driver, a
//! forger, a flood) must not fill its disk or spend its time writing logs.
//! Each kind of problem is logged the first time, then at most once per
//! window, with how many were left unsaid in between.

use std::collections::HashMap;
use std::hash::Hash;
use std::time::{Duration, Instant};

/// One line per kind per window.
pub const DEFAULT_WINDOW: Duration = Duration::from_secs(10);

/// Per-kind log budget.
#[derive(Debug)]
pub struct LogLimiter<K> {
    window: Duration,
    /// Per kind: when it was last logged, and how many were held back since.
    kinds: HashMap<K, (Instant, u64)>,
}

impl<K: Eq + Hash> Default for LogLimiter<K> {
    fn default() -> Self {
        Self::new(DEFAULT_WINDOW)
    }
}

impl<K: Eq + Hash> LogLimiter<K> {
    /// A limiter that lets one line per kind through every `window`.
    pub fn new(window: Duration) -> Self {
        Self {
            window,
            kinds: HashMap::new(),
        }
    }

    /// Whether a problem of `kind` seen at `now` may be logged: `Some(n)`
    /// with the number held back since the last line, or `None` (counted).
    pub fn admit(&mut self, kind: K, now: Instant) -> Option<u64> {
        match self.kinds.get_mut(&kind) {
            None => {
                self.kinds.insert(kind, (now, 0));
                Some(0)
            }
            Some((last, held)) if now.saturating_duration_since(*last) >= self.window => {
                let n = *held;
                *last = now;
                *held = 0;
                Some(n)
            }
            Some((_, held)) => {
                *held += 1;
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_is_logged_once_per_window_with_the_count_held_back() {
        let mut limit = LogLimiter::new(Duration::from_secs(10));
        let t0 = Instant::now();
        assert_eq!(limit.admit("truncated", t0), Some(0));
        assert_eq!(limit.admit("wrong type", t0), Some(0));
        for k in 1..=1000 {
            assert_eq!(
                limit.admit("truncated", t0 + Duration::from_millis(k)),
                None
            );
        }
        assert_eq!(
            limit.admit("truncated", t0 + Duration::from_secs(10)),
            Some(1000)
        );
        assert_eq!(limit.admit("truncated", t0 + Duration::from_secs(11)), None);
        assert_eq!(
            limit.admit("wrong type", t0 + Duration::from_secs(11)),
            Some(0)
        );
    }
}
