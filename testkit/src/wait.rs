//! Bounded waits: poll a condition until it holds or a deadline passes.

use std::time::{Duration, Instant};

/// How often [`poll_until`] looks again.
pub const POLL_INTERVAL: Duration = Duration::from_millis(20);

/// A wait that ran out of time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimedOut {
    /// What was waited for.
    pub what: String,
    /// How long.
    pub after: Duration,
}

impl std::fmt::Display for TimedOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "timed out after {:.1} s waiting for {}",
            self.after.as_secs_f64(),
            self.what
        )
    }
}

impl std::error::Error for TimedOut {}

/// Calls `check` every [`POLL_INTERVAL`] until it returns `Some`, for at
/// most `timeout`; `check` is always called at least once.
pub fn poll_until<T>(
    timeout: Duration,
    what: &str,
    mut check: impl FnMut() -> Option<T>,
) -> Result<T, TimedOut> {
    let start = Instant::now();
    loop {
        if let Some(v) = check() {
            return Ok(v);
        }
        if start.elapsed() >= timeout {
            return Err(TimedOut {
                what: what.to_string(),
                after: start.elapsed(),
            });
        }
        std::thread::sleep(POLL_INTERVAL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polling_returns_the_first_value_and_gives_up_on_time() {
        let mut n = 0;
        assert_eq!(
            poll_until(Duration::from_secs(5), "n = 3", || {
                n += 1;
                (n == 3).then_some(n)
            }),
            Ok(3)
        );
        let start = Instant::now();
        let err = poll_until(Duration::from_millis(100), "never", || None::<()>).unwrap_err();
        assert!(start.elapsed() < Duration::from_secs(2));
        assert!(err.to_string().contains("waiting for never"), "{err}");
    }
}
