//! Which robot summaries the central unit believes: each robot's are
//! checked against the last one it took of that robot, so that a robot
//! that floods summaries, stamps them from the future, or an impostor
//! publishing under another robot's id does not move the robot on the
//! map and in the firing plan. A dropped summary is counted by reason.
//!
//! The stamps are on the robot's own clock, which the central unit does
//! not know: they are compared with each other and with the time between
//! their arrivals, never with the central unit's clock. A robot none of
//! whose summaries was taken for [`REANCHOR_AFTER`] is taken again from its
//! next one (its MSU restarted, its clock was stepped, or it came back
//! from elsewhere), so that no rule can silence a robot for good.
//!
//! Pure: fed a summary and the time it arrived, it says whether to take it.

use ickon_proto::msg::robot::{MAX_SUMMARY_FIXES, RobotSummary};
use ickon_proto::time::{Duration, Time};

/// Least time between two summaries of a robot that are both taken: a
/// robot's agent sends one every
/// [`SUMMARY_PERIOD`](ickon_proto::msg::robot::SUMMARY_PERIOD) (500 ms);
/// the network may bring two closer, not five times closer.
pub const MIN_GAP: Duration = Duration::from_millis(100);
/// How far a summary's stamp may run ahead of the time between the
/// arrivals (the network's delays differ from one message to the next).
pub const FUTURE_SLACK: Duration = Duration::from_millis(1_000);
/// How long a stamp anchor serves: the stamps are compared with the
/// arrivals since the anchor, which moves to the newest summary taken
/// after this long (a robot's clock that runs 100 ppm fast gains 6 ms
/// in a minute, well inside [`FUTURE_SLACK`]).
pub const ANCHOR_SPAN: Duration = Duration::from_millis(60_000);
/// A robot with no summary taken for this long is taken from its next one.
pub const REANCHOR_AFTER: Duration = Duration::from_millis(3_000);
/// Fastest a robot's position may move between two summaries, m/s: twice
/// the fastest robot the firing plan allows for, so that no true robot is
/// refused.
pub const MAX_SPEED_M_S: f64 = 3.0;
/// Added to the distance a robot may move between two summaries, metres,
/// beyond three standard deviations of both positions.
pub const JUMP_SLACK_M: f64 = 0.5;

/// Largest position sigma a summary's jump allowance counts, metres: a
/// sender cannot widen the allowance at will by claiming a vast
/// uncertainty (the firing plan sweeps around a robot over 1 m anyway).
pub const MAX_SIGMA_M: f64 = 2.0;

/// Why a summary was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Dropped {
    /// Arrived and stamped within [`MIN_GAP`] of the last one taken: a
    /// robot that floods.
    Flood,
    /// Stamped at or before the last one taken: a repeat, a reordered or
    /// replayed message.
    Old,
    /// Stamped further ahead than the time between the arrivals allows
    /// (since the robot's stamp anchor, so that a sender cannot run ahead
    /// a little at a time).
    Future,
    /// A position the robot cannot have reached since the last one taken:
    /// another sender under this robot's id.
    Jump,
    /// More fixes than a summary carries.
    Malformed,
}

impl Dropped {
    /// Every reason, in order.
    pub const ALL: [Dropped; 5] = [
        Dropped::Flood,
        Dropped::Old,
        Dropped::Future,
        Dropped::Jump,
        Dropped::Malformed,
    ];

    /// A short name for logs and counters.
    pub fn label(self) -> &'static str {
        match self {
            Dropped::Flood => "flood",
            Dropped::Old => "old",
            Dropped::Future => "future",
            Dropped::Jump => "impostor",
            Dropped::Malformed => "malformed",
        }
    }
}

/// The last summary taken of one robot.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Taken {
    stamp: Time,
    at: Time,
    /// A summary taken earlier (its stamp and arrival) that the stamps
    /// are held to.
    anchor: (Time, Time),
    xy: Option<[f64; 2]>,
    sigma_m: f64,
}

/// One robot's gate.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SummaryGate {
    last: Option<Taken>,
}

impl SummaryGate {
    /// Whether to take `summary`, arrived at `now` (central unit's clock);
    /// when taken it is the one the next is checked against.
    pub fn check(&mut self, summary: &RobotSummary, now: Time) -> Result<(), Dropped> {
        if summary.fixes.len() > MAX_SUMMARY_FIXES {
            return Err(Dropped::Malformed);
        }
        let xy = [summary.x_m, summary.y_m];
        let xy = xy.iter().all(|v| v.is_finite()).then_some(xy);
        let sigma_m = position_sigma_m(&summary.covariance);
        if let Some(last) = self.last.filter(|l| now.since(l.at) < REANCHOR_AFTER) {
            let arrived_after = now.since(last.at);
            if summary.stamp <= last.stamp {
                return Err(Dropped::Old);
            }
            let stamped_after = summary.stamp.since(last.stamp);
            // Both close: a robot's own summaries are stamped half a second
            // apart, however close a stalled loop or the network brings
            // their arrivals (stamps far apart that arrive close are judged
            // from the future below).
            if arrived_after < MIN_GAP && stamped_after < MIN_GAP {
                return Err(Dropped::Flood);
            }
            let (anchor_stamp, anchor_at) = last.anchor;
            if summary.stamp.since(anchor_stamp) > now.since(anchor_at) + FUTURE_SLACK {
                return Err(Dropped::Future);
            }
            if let (Some(a), Some(b)) = (last.xy, xy) {
                let moved_m = (a[0] - b[0]).hypot(a[1] - b[1]);
                let allowed_m = MAX_SPEED_M_S * stamped_after.as_secs_f64()
                    + 3.0 * (last.sigma_m + sigma_m)
                    + JUMP_SLACK_M;
                if moved_m > allowed_m {
                    return Err(Dropped::Jump);
                }
            }
        }
        let anchor = match self.last {
            Some(l) if now.since(l.at) < REANCHOR_AFTER && now.since(l.anchor.1) < ANCHOR_SPAN => {
                l.anchor
            }
            _ => (summary.stamp, now),
        };
        self.last = Some(Taken {
            stamp: summary.stamp,
            at: now,
            anchor,
            xy,
            sigma_m,
        });
        Ok(())
    }

    /// Forgets the last summary taken (the robot's token went: whatever
    /// comes next is a new start).
    pub fn reset(&mut self) {
        self.last = None;
    }
}

/// The larger standard deviation of the position, from the pose's
/// covariance (x, y, theta), at most [`MAX_SIGMA_M`] (0 when it is not a
/// number: such a summary is judged by its position alone).
fn position_sigma_m(cov: &[f64; 9]) -> f64 {
    let s = cov[0].max(cov[4]).sqrt();
    if s.is_finite() {
        s.min(MAX_SIGMA_M)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests;
