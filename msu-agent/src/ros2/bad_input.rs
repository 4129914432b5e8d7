//! Bad input on the ROS 2 topics: every kind counted, logged the first
//! time it happens and then at most once per [`LOG_INTERVAL_S`] per kind
//! (with how many were not logged), so that a robot flooding garbage can
//! neither crash the agent nor drown its log. Pure: the caller gives the time.

use std::collections::BTreeMap;

/// Least time between two log lines of one kind, seconds.
pub const LOG_INTERVAL_S: f64 = 10.0;

/// What was wrong with a ROS 2 sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum BadInputKind {
    /// The CDR did not decode (truncated, trailing bytes, bad header).
    Undecodable,
    /// The key names another type or type hash.
    WrongType,
    /// rmw_zenoh sample without the attachment (rmw_zenoh drops these too).
    NoAttachment,
    /// An attachment that is not the 33-byte layout.
    BadAttachment,
    /// NaN or infinity in a value or a covariance.
    NonFinite,
    /// A stamp with nanoseconds of one second or more.
    BadStamp,
    /// A stamp older than the previous sample of the same topic.
    Backwards,
    /// The odometry moved further between two samples than a robot can.
    Jump,
}

impl BadInputKind {
    /// What the log says.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Undecodable => "undecodable CDR",
            Self::WrongType => "wrong message type on the topic",
            Self::NoAttachment => "sample without the rmw_zenoh attachment",
            Self::BadAttachment => "malformed rmw_zenoh attachment",
            Self::NonFinite => "NaN or infinite value",
            Self::BadStamp => "malformed stamp",
            Self::Backwards => "stamp going backwards",
            Self::Jump => "odometry jump (re-anchored)",
        }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct PerKind {
    count: u64,
    last_logged_s: Option<f64>,
    unlogged: u64,
}

/// Counts of bad input, and when each kind may be logged again.
#[derive(Debug, Clone, Default)]
pub struct BadInputLog {
    kinds: BTreeMap<BadInputKind, PerKind>,
}

impl BadInputLog {
    /// Counts one `kind` at `now_s`; returns the line to log, if one is due.
    pub fn record(&mut self, kind: BadInputKind, topic: &str, now_s: f64) -> Option<String> {
        let k = self.kinds.entry(kind).or_default();
        k.count += 1;
        let due = match k.last_logged_s {
            None => true,
            // A non-finite clock logs every time rather than never.
            Some(t) => (now_s - t).partial_cmp(&LOG_INTERVAL_S) != Some(std::cmp::Ordering::Less),
        };
        if !due {
            k.unlogged += 1;
            return None;
        }
        let more = if k.unlogged > 0 {
            format!(" ({} more since the last report)", k.unlogged)
        } else {
            String::new()
        };
        k.last_logged_s = Some(now_s);
        k.unlogged = 0;
        Some(format!(
            "ros2 {topic}: dropped: {}{more}; {} so far",
            kind.describe(),
            k.count
        ))
    }

    /// How many of `kind` were seen.
    pub fn count(&self, kind: BadInputKind) -> u64 {
        self.kinds.get(&kind).map_or(0, |k| k.count)
    }

    /// All bad input seen.
    pub fn total(&self) -> u64 {
        self.kinds.values().map(|k| k.count).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logs_each_kind_once_then_at_most_every_interval() {
        let mut log = BadInputLog::default();
        assert!(
            log.record(BadInputKind::NonFinite, "/r1/odom", 0.0)
                .is_some()
        );
        assert!(
            log.record(BadInputKind::Backwards, "/r1/odom", 0.1)
                .is_some()
        );
        for i in 0..1000 {
            assert!(
                log.record(BadInputKind::NonFinite, "/r1/odom", 0.2 + i as f64 * 0.001)
                    .is_none()
            );
        }
        let line = log
            .record(BadInputKind::NonFinite, "/r1/odom", LOG_INTERVAL_S + 0.5)
            .unwrap();
        assert!(line.contains("1000 more"), "{line}");
        assert_eq!(log.count(BadInputKind::NonFinite), 1002);
        assert_eq!(log.total(), 1003);
    }

    #[test]
    fn a_nan_clock_still_counts_and_logs() {
        let mut log = BadInputLog::default();
        assert!(log.record(BadInputKind::Jump, "t", f64::NAN).is_some());
        assert!(log.record(BadInputKind::Jump, "t", f64::NAN).is_some());
        assert_eq!(log.count(BadInputKind::Jump), 2);
    }
}
