//! The synthetic fleet's loop state: whose turn it is, the cycles heard,
//! and the count of what was sent and what went late.

use std::time::Instant;

use ickon_proto::msg::control::{CycleTrigger, Schedule};
use ickon_proto::msg::robot::{MsuStatus, SUMMARY_PERIOD};
use serde::Serialize;
use zenoh::Session;
use zenoh::key_expr::KeyExpr;

use ickon_runtime::SimulatedClock;

use super::model::SyntheticFleet;
use super::{FleetKeptUp, RobotKeys, STATUS_PERIOD, ticks_in};

/// What the fleet's loop holds between two inputs.
pub(super) struct FleetLoop {
    /// The session the robots' messages are put on.
    pub session: Session,
    pub fleet: SyntheticFleet,
    pub robots: Vec<RobotKeys>,
    pub schedule: Schedule,
    pub clock: SimulatedClock,
    pub started: Instant,
    /// Ticks in a summary period and in a status period.
    pub per_summary: usize,
    pub per_status: usize,
    /// The latest survey calibration's version.
    pub survey_version: u32,
    /// The transmitters of the last cycle that fired and has ended (its
    /// fixes exist once the next cycle is triggered, as an agent's do once
    /// the cycle's arrivals are in), and of the one triggered last.
    pub last_fired: Option<Vec<u32>>,
    pub firing: Option<Vec<u32>>,
    pub cycles: u64,
    /// The last tick served, so that a late tick serves every turn it
    /// skipped.
    pub served_ms: usize,
    /// What was sent, what went late, what failed.
    pub kept_up: FleetKeptUp,
}

impl FleetLoop {
    /// A loop of `fleet` starting now, under `schedule`.
    pub fn new(
        session: Session,
        fleet: SyntheticFleet,
        robots: Vec<RobotKeys>,
        schedule: Schedule,
        clock: SimulatedClock,
        declare_s: f64,
    ) -> Self {
        Self {
            session,
            fleet,
            robots,
            schedule,
            clock,
            started: Instant::now(),
            per_summary: ticks_in(SUMMARY_PERIOD.to_std()),
            per_status: ticks_in(STATUS_PERIOD),
            survey_version: 0,
            last_fired: None,
            firing: None,
            cycles: 0,
            served_ms: 0,
            kept_up: FleetKeptUp {
                summaries: 0,
                late_turns: 0,
                failed_puts: 0,
                elapsed_s: 0.0,
                declare_s,
            },
        }
    }

    /// A tick: every turn since the last tick served is served now, by the
    /// time gone (a late tick's turns counted late).
    pub async fn tick(&mut self) {
        let now_ms = self.started.elapsed().as_millis() as usize;
        let t_s = self.started.elapsed().as_secs_f64();
        // Over a second behind, the turns beyond it are skipped (every
        // robot's are in the last second) and counted late.
        let window = self.per_summary.max(self.per_status);
        let behind = now_ms.saturating_sub(self.served_ms);
        self.kept_up.late_turns += behind.saturating_sub(window) as u64;
        let served_ms = self.served_ms;
        let turns = (now_ms + 1 - behind.min(window)..=now_ms).filter(|&k| k > served_ms);
        for k in turns {
            let late = now_ms - k >= self.per_summary;
            self.summaries_of_turn(k, t_s, late).await;
            self.statuses_of_turn(k).await;
        }
        self.served_ms = now_ms;
    }

    /// The summaries of the robots whose turn `k` is.
    async fn summaries_of_turn(&mut self, k: usize, t_s: f64, late: bool) {
        let per_summary = self.per_summary;
        for i in (k % per_summary..self.fleet.len()).step_by(per_summary) {
            let p = &mut self.robots[i];
            let stamp = self.clock.now();
            let solved = self
                .cycles
                .saturating_sub(p.cycles_at_last)
                .min(u64::from(u32::MAX)) as u32;
            let fix = self
                .last_fired
                .as_deref()
                .filter(|_| solved > 0)
                .and_then(|fired| self.fleet.fix(i, t_s, stamp, fired, self.survey_version));
            p.seq += 1;
            p.cycles_at_last = self.cycles;
            let summary =
                self.fleet
                    .summary(i, t_s, stamp, p.seq, solved, fix.into_iter().collect());
            self.kept_up.failed_puts +=
                u64::from(!put_counted(&self.session, &p.summary, &summary).await);
            self.kept_up.summaries += 1;
            self.kept_up.late_turns += u64::from(late);
        }
    }

    /// The statuses of the robots whose turn `k` is.
    async fn statuses_of_turn(&mut self, k: usize) {
        let per_status = self.per_status;
        for i in (k % per_status..self.fleet.len()).step_by(per_status) {
            let status = MsuStatus {
                stamp: self.clock.now(),
                receivers: String::new(),
            };
            let key = &self.robots[i].status;
            self.kept_up.failed_puts += u64::from(!put_counted(&self.session, key, &status).await);
        }
    }

    /// A cycle trigger: the cycle triggered before it has ended.
    pub fn trigger(&mut self, trigger: &CycleTrigger) {
        if let Some(fired) = self.firing.take() {
            self.last_fired = Some(fired);
            self.cycles += 1;
        }
        if trigger.schedule_version == self.schedule.version {
            self.firing = Some(
                trigger
                    .emissions(&self.schedule)
                    .iter()
                    .map(|e| e.tx_id)
                    .collect(),
            );
        }
    }
}

/// Encodes `value` and puts it on `key` through `session`; `false` (and a
/// debug log) if either failed, for the fleet to count.
async fn put_counted<T: Serialize>(session: &Session, key: &KeyExpr<'_>, value: &T) -> bool {
    let bytes = match ickon_proto::encode(value) {
        Ok(b) => b,
        Err(e) => {
            tracing::debug!("not sent on {key}: {e}");
            return false;
        }
    };
    match session.put(key, bytes).await {
        Ok(()) => true,
        Err(e) => {
            tracing::debug!("put on {key} failed: {e}");
            false
        }
    }
}
