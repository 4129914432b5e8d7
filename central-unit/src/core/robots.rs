//! The robots: liveliness, summaries and fixes, their share of the survey
//! calibration, and the clock replies they ask for.

use std::collections::BTreeMap;

use ickon_proto::msg::control::ClockReply;
use ickon_proto::msg::robot::{Fix, MsuStatus, RobotSummary};
use ickon_proto::time::Time;

use crate::health::RobotTracker;
use crate::survey_calibration::{FixSkipped, SavedCalibration, SavedMismatch, SurveyPublisher};

use super::CentralCore;

/// What the central unit holds per robot, summed over the fleet
/// ([`CentralCore::robot_footprint`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RobotFootprint {
    /// Robots tracked (the site's robots seen, up or down).
    pub trackers: usize,
    /// Fix reports held for the robots' fix rates.
    pub fix_reports: usize,
    /// Robots with a share of the survey calibration's fixes.
    pub fix_shares: usize,
    /// Robots the fleet's check holds a window or a standing of.
    pub checked: usize,
    /// Fixes the fleet's check holds.
    pub fixes_held: usize,
}

impl CentralCore {
    /// Gives a robot's fix to the survey calibration (a fix of a robot not
    /// on the site is counted by the health books, and still a fix of
    /// the site's transmitters), within the robot's share of the
    /// calibration: one fix a cycle (every robot the site does not list
    /// shares one such share).
    /// Within its share, the fix is offered to the fleet's check
    /// ([`crate::survey_calibration::consensus`]) before it may teach the
    /// calibration.
    pub(super) fn survey_fix(&mut self, robot: &str, fix: &Fix, now: Time) {
        let key = if self.on_site(robot) { robot } else { "" };
        let Some(publisher) = self.survey.as_mut() else {
            return;
        };
        let taken = match self.survey_fix_rate.admit(key, self.cycles_heard) {
            Ok(()) => publisher.offer_fix(key, fix, now),
            Err(refused) => {
                if refused.is_power_of_two() {
                    let who = if key.is_empty() {
                        "robots the site does not list".to_string()
                    } else {
                        format!("robot {key}")
                    };
                    tracing::warn!(
                        "{who} sent more fixes than one a cycle: {refused} kept from the survey \
                         calibration so far (a broken MSU, or fixes forged under its name)"
                    );
                }
                Err(FixSkipped::OverRate)
            }
        };
        if let Err(skipped) = taken {
            *self.survey_skipped.entry(skipped.label()).or_default() += 1;
        }
    }

    /// The survey calibration learnt so far, `None` when it is off.
    pub fn survey(&self) -> Option<&SurveyPublisher> {
        self.survey.as_ref()
    }

    /// What to keep of the survey calibration across a restart (`None`
    /// when it is off).
    pub fn survey_saved(&self) -> Option<SavedCalibration> {
        self.survey.as_ref().map(|p| p.saved(&self.site))
    }

    /// Goes on from a survey calibration kept across a restart; `Ok(false)`
    /// when the calibration is off.
    pub fn restore_survey(&mut self, saved: &SavedCalibration) -> Result<bool, SavedMismatch> {
        match self.survey.as_mut() {
            Some(p) => p.restore(&self.site, saved).map(|()| true),
            None => Ok(false),
        }
    }

    /// Fixes the survey calibration did not take, by reason.
    pub fn survey_skipped(&self) -> &BTreeMap<&'static str, u64> {
        &self.survey_skipped
    }

    /// A robot's liveliness token appeared or disappeared.
    pub(super) fn robot_alive(&mut self, id: &str, up: bool) {
        if let Some(r) = self.robot_mut(id) {
            r.set_alive(up);
        }
        if !up && self.on_site(id) {
            if let Some(publisher) = self.survey.as_mut() {
                publisher.forget_robot(id);
            }
            self.survey_fix_rate.forget(id);
        }
    }

    /// Whether `id` is one of the site's robots (a robot tracked already
    /// is: the table holds only the site's, and a reload keeps only those).
    fn on_site(&self, id: &str) -> bool {
        self.robots.contains_key(id) || self.site.robots.iter().any(|r| r.id == id)
    }

    /// The tracker of robot `id` if the site has it. Robots the site does
    /// not know are counted, not tracked: the table stays as large as the
    /// site, whatever anyone publishes.
    fn robot_mut(&mut self, id: &str) -> Option<&mut RobotTracker> {
        if self.on_site(id) {
            Some(self.robots.entry(id.to_string()).or_default())
        } else {
            self.unknown_robot_messages += 1;
            None
        }
    }

    /// What the core holds per robot, summed over the fleet: the tables a
    /// fleet that came and went must leave as small as it found them.
    pub fn robot_footprint(&self) -> RobotFootprint {
        RobotFootprint {
            trackers: self.robots.len(),
            fix_reports: self.robots.values().map(|r| r.fix_reports_held()).sum(),
            fix_shares: self.survey_fix_rate.len(),
            checked: self.survey.as_ref().map_or(0, |p| p.robots_checked()),
            fixes_held: self.survey.as_ref().map_or(0, |p| p.fixes_held()),
        }
    }

    /// Messages from robot ids the site does not know, ignored so far.
    pub fn unknown_robot_messages(&self) -> u64 {
        self.unknown_robot_messages
    }

    /// A robot's summary, received at `now`: taken when its gate lets it
    /// through, its fixes then offered to the survey calibration; dropped
    /// and counted otherwise (logged at a bounded rate per robot). The
    /// fixes of a robot the site does not list share one share of the
    /// calibration, as its fixes always did.
    pub(super) fn on_summary(&mut self, id: &str, summary: &RobotSummary, now: Time) {
        let taken = match self.robot_mut(id) {
            Some(r) => r
                .on_summary(summary, now)
                .map_err(|d| (d, r.summaries_dropped)),
            None => Ok(()),
        };
        match taken {
            Ok(()) => {
                for fix in &summary.fixes {
                    self.survey_fix(id, fix, now);
                }
            }
            Err((dropped, of_robot)) => {
                *self.summaries_dropped.entry(dropped.label()).or_default() += 1;
                if of_robot.is_power_of_two() {
                    tracing::warn!(
                        "robot {id}: summary dropped ({}): {of_robot} of its summaries dropped so far \
                         (a robot that floods or stamps from the future, or another sender under its id)",
                        dropped.label()
                    );
                }
            }
        }
    }

    /// The stamp of the last pose taken of robot `id` (from its summary).
    pub fn last_pose_stamp(&self, id: &str) -> Option<Time> {
        self.robots.get(id)?.last_pose().map(|(p, _)| p.stamp)
    }

    /// Summaries the robots' gates dropped, by reason
    /// ([`crate::summary_gate::Dropped::label`]).
    pub fn summaries_dropped(&self) -> &BTreeMap<&'static str, u64> {
        &self.summaries_dropped
    }

    /// A robot's agent reported its state.
    pub(super) fn on_robot_status(&mut self, id: &str, status: MsuStatus) {
        if let Some(r) = self.robot_mut(id) {
            r.on_status(status);
        }
    }

    /// A robot published a fix at `now`.
    pub(super) fn on_fix(&mut self, id: &str, now: Time) {
        if let Some(r) = self.robot_mut(id) {
            r.on_fix(now);
        }
    }

    /// The reply of the central unit of `epoch` to a clock request that
    /// arrived at `t2` and leaves at `t3`.
    pub fn clock_reply(epoch: u64, t1: Time, t2: Time, t3: Time) -> ClockReply {
        ClockReply { t1, t2, t3, epoch }
    }
}
