//! What the central unit knows of each cell and robot: presence, what each
//! cell fired and when against its schedule, and what each robot publishes.
//! Pure bookkeeping for [`CentralCore`](crate::core::CentralCore).
//!
//! The residual sync error of a cell is `actual - scheduled` of each burst,
//! both on the master time base: `scheduled` is where the schedule put the
//! burst, `actual` where it really went out (a simulation knows it exactly
//! from the true time base; hardware reports its best estimate). Unlike the
//! cell's own uncertainty it sees every error of the sync slave, including
//! the round-trip asymmetry no exchange can observe.

use std::collections::{BTreeSet, VecDeque};

use ickon_proto::msg::admin::{CellHealth, CellState, RobotHealth};
use ickon_proto::msg::control::{Burst, CellStatus};
use ickon_proto::msg::robot::{MsuStatus, PoseStatus, RobotPose, RobotSummary};
use ickon_proto::time::{Duration, Time};

use crate::summary_gate::{Dropped, SummaryGate};
use crate::velocity::Velocity;

/// Fired cycles remembered per cell, to count missed ones.
const FIRED_MEMORY: usize = 64;
/// A live cell that fired nothing in this many cycles in a row that it was
/// due to fire in is reported down (hung: its process stopped but its
/// link, and so its liveliness token, lives on until the link lease expires).
pub const MISSED_IN_A_ROW_FOR_DOWN: u32 = 2;
/// A cell that has reported before and then reported nothing (no status,
/// no burst) for this long is reported down, due or not: three periods of
/// the cell's status report (one a second by default), so that one or two
/// lost reports do not page anyone, and a hung cell that is never due
/// (no robot near it) is still seen within seconds.
pub const REPORTS_SILENT_FOR_DOWN: Duration = Duration::from_millis(3_000);
/// Bursts behind the residual figures of a cell.
pub const RESIDUAL_WINDOW: usize = 64;
/// Fixes per second are counted over this window.
pub const FIX_RATE_WINDOW: Duration = Duration::from_millis(2_000);
/// A robot whose last pose came longer ago than this is stale: its agent
/// sends its summary every half second
/// ([`SUMMARY_PERIOD`](ickon_proto::msg::robot::SUMMARY_PERIOD)), so three
/// missing in a row are a stopped or hung MSU (or a broken link), not a
/// lost message.
pub const POSE_STALE_AFTER: Duration = Duration::from_millis(1_600);

/// One cell.
#[derive(Debug, Default, Clone)]
pub struct CellTracker {
    /// Whether its liveliness token is present.
    pub alive: bool,
    /// The state last reported.
    pub state: CellState,
    /// The last triggered cycle when `state` last changed.
    pub state_since_cycle: u64,
    /// Whether the last triggered cycle named one of its transmitters.
    pub due_in_last_cycle: bool,
    /// When it last reported (a status or a burst), central unit's clock.
    reported_at: Option<Time>,
    status: Option<CellStatus>,
    fired: BTreeSet<u64>,
    last_cycle_fired: u64,
    cycles_fired: u64,
    cycles_missed: u64,
    missed_in_a_row: u32,
    residuals_ns: VecDeque<i64>,
}

impl CellTracker {
    /// A burst of this cell received at `now`; `burst.actual` on the master time base.
    pub fn on_burst(&mut self, burst: &Burst, now: Time) {
        self.reported_at = Some(now);
        if self.residuals_ns.len() == RESIDUAL_WINDOW {
            self.residuals_ns.pop_front();
        }
        self.residuals_ns.push_back(
            burst
                .actual
                .as_nanos()
                .saturating_sub(burst.scheduled.as_nanos()),
        );
        if self.fired.insert(burst.cycle) {
            self.cycles_fired += 1;
            self.last_cycle_fired = self.last_cycle_fired.max(burst.cycle);
            while self.fired.len() > FIRED_MEMORY {
                self.fired.pop_first();
            }
        }
    }

    /// The cell's own status report, received at `now`.
    pub fn on_status(&mut self, status: CellStatus, now: Time) {
        self.status = Some(status);
        self.reported_at = Some(now);
    }

    /// `cycle` is over and the cell was due to fire in it (its trigger
    /// named one of the cell's transmitters): counts it as missed if the
    /// cell is alive and fired nothing in it. Cycles it was not due in are
    /// never checked: not firing in them is what it was asked to do.
    pub fn check_fired(&mut self, cycle: u64) {
        if self.fired.contains(&cycle) {
            self.missed_in_a_row = 0;
        } else if self.alive {
            self.cycles_missed += 1;
            self.missed_in_a_row = self.missed_in_a_row.saturating_add(1);
        }
    }

    /// Why the cell is down at `now`, if it is; `scheduled` tells whether
    /// it takes part in the schedule of the last triggered cycle. A hung
    /// cell keeps its token: it shows by missing the cycles it was due in,
    /// or, when it is due in none, by its reports stopping.
    pub fn down_reason(&self, now: Time, scheduled: bool) -> Option<&'static str> {
        if !self.alive {
            Some("its liveliness token is gone")
        } else if !scheduled {
            Some("not in the schedule in force")
        } else if self.missed_in_a_row >= MISSED_IN_A_ROW_FOR_DOWN {
            Some("it fired nothing in the cycles it was due in")
        } else if self
            .reported_at
            .is_some_and(|at| now.since(at) > REPORTS_SILENT_FOR_DOWN)
        {
            Some("its reports stopped")
        } else {
            None
        }
    }

    /// The state at `now` (see [`down_reason`](Self::down_reason)).
    pub fn state_at(&self, now: Time, scheduled: bool) -> CellState {
        if self.down_reason(now, scheduled).is_some() {
            CellState::Down
        } else if self.due_in_last_cycle {
            CellState::Up
        } else {
            CellState::Idle
        }
    }

    /// The admin view of this cell.
    pub fn health(&self, id: &str) -> CellHealth {
        let n = self.residuals_ns.len();
        let max = self
            .residuals_ns
            .iter()
            .map(|r| r.saturating_abs())
            .max()
            .unwrap_or(0);
        let rms = if n == 0 {
            0.0
        } else {
            (self
                .residuals_ns
                .iter()
                .map(|&r| (r as f64).powi(2))
                .sum::<f64>()
                / n as f64)
                .sqrt()
        };
        let status = self.status.as_ref();
        CellHealth {
            id: id.to_string(),
            state: self.state,
            state_since_cycle: self.state_since_cycle,
            sync_sigma_ns: status.map_or(0, |s| s.offset_sigma_ns),
            offset_ns: status.map_or(0, |s| s.offset_ns),
            drift_ppb: status.map_or(0, |s| s.drift_ppb),
            residual_samples: u32::try_from(n).unwrap_or(u32::MAX),
            residual_max_ns: max,
            residual_rms_ns: rms.round() as i64,
            last_cycle_fired: self.last_cycle_fired,
            cycles_fired: self.cycles_fired,
            cycles_missed: self.cycles_missed,
            slots_skipped: status.map_or(0, |s| s.slots_skipped),
            inputs_refused: status.map_or(0, |s| s.inputs_refused),
            device: status.map_or_else(String::new, |s| s.device.clone()),
        }
    }
}

/// The longest receivers' line kept of an agent's report.
const MAX_RECEIVERS_CHARS: usize = 400;

/// One robot.
#[derive(Debug, Default, Clone)]
pub struct RobotTracker {
    /// Whether its liveliness token is present.
    pub alive: bool,
    pose: Option<RobotPose>,
    /// When the last pose arrived (central unit's clock).
    pose_at: Option<Time>,
    /// The velocity its last summary reported.
    velocity: Option<Velocity>,
    /// When fixes were reported, and how many.
    fix_times: VecDeque<(Time, u32)>,
    /// Which of its summaries to believe.
    gate: SummaryGate,
    /// Its summaries dropped by the gate, since the central unit started.
    pub summaries_dropped: u64,
    /// Its receivers' state, as its agent last reported it.
    receivers: String,
}

impl RobotTracker {
    /// Its summary, received at `now`: its pose, velocity and the fixes
    /// its agent solved are taken when the gate lets it through
    /// ([`crate::summary_gate`]); a dropped one is counted.
    pub fn on_summary(&mut self, summary: &RobotSummary, now: Time) -> Result<(), Dropped> {
        if let Err(dropped) = self.gate.check(summary, now) {
            self.summaries_dropped += 1;
            return Err(dropped);
        }
        self.pose = Some(summary.pose());
        self.pose_at = Some(now);
        self.velocity = Velocity::of_summary(summary);
        self.note_fixes(summary.fixes_solved, now);
        Ok(())
    }

    /// Its liveliness token appeared or went: either way its next summary
    /// is a new start for the gate.
    pub fn set_alive(&mut self, up: bool) {
        self.alive = up;
        self.gate.reset();
        if !up {
            // A robot gone keeps its last pose and counts for the admin;
            // what grows with its messages is let go, so that a fleet
            // that came and went leaves the tables as small as before.
            self.fix_times = VecDeque::new();
            self.receivers = String::new();
        }
    }

    /// Fix reports it holds (the admin's fix rate window).
    pub fn fix_reports_held(&self) -> usize {
        self.fix_times.len()
    }

    /// Its agent's report of its state.
    pub fn on_status(&mut self, status: MsuStatus) {
        // A line, not a document: a forged report cannot grow the admin's answer.
        self.receivers = status.receivers.chars().take(MAX_RECEIVERS_CHARS).collect();
    }

    /// Why the robot is stale at `now`, if it is: a live robot (token
    /// present) whose poses stopped, or whose MSU says an input stalled.
    pub fn stale(&self, now: Time) -> Option<String> {
        if !self.alive && self.pose_at.is_none() {
            return None;
        }
        if let Some(at) = self.pose_at {
            let silent = now.since(at);
            if silent > POSE_STALE_AFTER {
                return Some(format!("no pose for {:.1} s", silent.as_secs_f64()));
            }
        } else {
            return Some("no pose yet".into());
        }
        match self.pose.as_ref().map(|p| p.status) {
            Some(PoseStatus::NoFixes) => Some("MSU: no fixes".into()),
            Some(PoseStatus::NoOdometry) => Some("MSU: no odometry".into()),
            Some(PoseStatus::Localising) => {
                Some("MSU: localising (no fix has confirmed its pose)".into())
            }
            _ => None,
        }
    }

    /// The last pose and when it was received.
    pub fn last_pose(&self) -> Option<(&RobotPose, Time)> {
        Some((self.pose.as_ref()?, self.pose_at?))
    }

    /// Its mean velocity over its last poses, as its last summary said.
    pub fn velocity(&self) -> Option<Velocity> {
        self.velocity
    }

    /// A fix of it, received at `now`.
    pub fn on_fix(&mut self, now: Time) {
        self.note_fixes(1, now);
    }

    /// `n` fixes of it reported at `now`.
    fn note_fixes(&mut self, n: u32, now: Time) {
        if n > 0 {
            self.fix_times.push_back((now, n));
        }
        while self
            .fix_times
            .front()
            .is_some_and(|(t, _)| now.since(*t) > FIX_RATE_WINDOW)
        {
            self.fix_times.pop_front();
        }
    }

    /// The admin view of this robot at `now`.
    pub fn health(&self, id: &str, now: Time) -> RobotHealth {
        let recent: u64 = self
            .fix_times
            .iter()
            .filter(|(t, _)| now.since(*t) <= FIX_RATE_WINDOW)
            .map(|(_, n)| u64::from(*n))
            .sum();
        let pose = self.pose.as_ref();
        RobotHealth {
            id: id.to_string(),
            up: self.alive,
            fixes_per_s: recent as f64 / FIX_RATE_WINDOW.as_secs_f64(),
            estimator: pose.map_or(String::new(), |p| p.estimator.clone()),
            pose_valid: pose.is_some(),
            x_m: pose.map_or(0.0, |p| p.x_m),
            y_m: pose.map_or(0.0, |p| p.y_m),
            theta_rad: pose.map_or(0.0, |p| p.theta_rad),
            stale: self.stale(now).unwrap_or_default(),
            // Counted by the survey calibration's share and check, not here.
            fixes_over_rate: 0,
            survey_check: String::new(),
            fixes_quarantined: 0,
            survey_misfit_m: -1.0,
            survey_bound_m: -1.0,
            receivers: self.receivers.clone(),
            summaries_dropped: self.summaries_dropped,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn burst(cycle: u64, error_ns: i64) -> Burst {
        Burst {
            cell_id: "c1".into(),
            tx_id: 11,
            cycle,
            scheduled: Time(1_000_000_000),
            actual: Time(1_000_000_000 + error_ns),
            epoch: 1,
        }
    }

    /// Found by `fuzz_central_core`: a burst report scheduled at
    /// `i64::MIN` overflowed the residual (a panic in a debug build).
    #[test]
    fn a_burst_scheduled_at_the_start_of_time_saturates_its_residual() {
        let mut c = CellTracker::default();
        c.on_burst(
            &Burst {
                scheduled: Time(i64::MIN),
                ..burst(1, 0)
            },
            Time(0),
        );
        c.on_burst(
            &Burst {
                actual: Time(i64::MIN),
                scheduled: Time(i64::MAX),
                ..burst(2, 0)
            },
            Time(0),
        );
        let h = c.health("c1");
        assert_eq!(h.residual_max_ns, i64::MAX);
        assert!(h.residual_rms_ns > 0);
    }

    #[test]
    fn residuals_are_actual_minus_scheduled_over_the_recent_bursts() {
        let mut c = CellTracker::default();
        c.on_burst(&burst(1, 300_000), Time(0)); // an early bad burst, later pushed out
        for k in 0..RESIDUAL_WINDOW as u64 {
            let error_ns = if k % 2 == 0 { 30_000 } else { -40_000 };
            c.on_burst(&burst(2 + k / 4, error_ns), Time(0));
        }
        let h = c.health("c1");
        assert_eq!(h.residual_samples, RESIDUAL_WINDOW as u32);
        assert_eq!(h.residual_max_ns, 40_000);
        assert_eq!(h.residual_rms_ns, 35_355);
        assert_eq!(h.cycles_fired, 1 + RESIDUAL_WINDOW as u64 / 4);
        assert_eq!(h.last_cycle_fired, 1 + RESIDUAL_WINDOW as u64 / 4);
    }

    #[test]
    fn a_cell_that_never_fired_has_no_residual() {
        let h = CellTracker::default().health("c9");
        assert_eq!((h.residual_samples, h.residual_max_ns), (0, 0));
        assert_eq!(h.state, CellState::Down);
    }

    #[test]
    fn missed_cycles_count_only_while_alive() {
        let mut c = CellTracker::default();
        c.check_fired(3);
        c.alive = true;
        c.on_burst(&burst(4, 0), Time(0));
        c.check_fired(4);
        c.check_fired(5);
        assert_eq!(c.health("c1").cycles_missed, 1);
    }

    #[test]
    fn a_live_cell_is_idle_when_not_due_and_down_when_its_reports_stop() {
        let mut c = CellTracker {
            alive: true,
            ..CellTracker::default()
        };
        assert_eq!(c.state_at(Time(0), true), CellState::Idle);
        c.due_in_last_cycle = true;
        assert_eq!(c.state_at(Time(0), true), CellState::Up);
        assert_eq!(c.state_at(Time(0), false), CellState::Down, "not scheduled");
        c.due_in_last_cycle = false;
        c.on_burst(&burst(4, 0), Time(1_000_000_000));
        let quiet_until = Time(1_000_000_000) + REPORTS_SILENT_FOR_DOWN;
        assert_eq!(c.state_at(quiet_until, true), CellState::Idle);
        let too_long = quiet_until + Duration::from_millis(1);
        assert_eq!(c.state_at(too_long, true), CellState::Down);
        let status = CellStatus {
            cell_id: "c1".into(),
            stamp: too_long,
            offset_ns: 0,
            drift_ppb: 0,
            offset_sigma_ns: 0,
            sync_samples: 0,
            last_cycle_fired: 4,
            cycles_fired: 1,
            slots_skipped: 0,
            faults: Vec::new(),
            inputs_refused: 0,
            device: String::new(),
        };
        c.on_status(status, too_long);
        assert_eq!(c.state_at(too_long, true), CellState::Idle);
    }

    #[test]
    fn fixes_per_second_count_a_sliding_window() {
        let mut r = RobotTracker::default();
        for k in 0..10 {
            r.on_fix(Time(k * 200_000_000));
        }
        let h = r.health("r1", Time(1_800_000_000));
        assert!((h.fixes_per_s - 5.0).abs() < 0.6, "{}", h.fixes_per_s);
        assert!(!h.pose_valid);
    }
}
