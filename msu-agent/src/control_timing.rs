//! From which cycle the news of the central unit and the cells takes
//! effect: a survey calibration, a cell's sync sigma.
//!
//! Each changes how the next arrivals are solved. Taken at once, the
//! result would depend on whether the news or a cycle's arrivals reached
//! the MSU first, and a recorder of the site can see that race end the
//! other way (the arrivals come from the robot, the news from other
//! nodes, each over its own route), so a replay of the recording would not
//! be the agent's run. So while the MSU follows the central unit's
//! triggers, each takes effect from a cycle named by the news itself:
//! - a calibration, from the first cycle whose trigger came after it (the
//!   central unit sends both at one priority, so every subscriber hears
//!   them in one order);
//! - a cell's sync sigma, from the first cycle that starts after the
//!   status was made (its stamp, on the master time base the triggers
//!   share).
//!
//! When the whole schedule fires (no triggers to follow), the arrivals
//! name no cycle, and news takes effect at the next arrivals, as before.

use std::collections::BTreeMap;

use ickon_proto::msg::control::{CycleTrigger, SurveyCalibration};
use ickon_proto::time::Time;

/// News waiting for its first cycle.
#[derive(Debug, Clone, Default)]
pub struct PendingControl {
    /// A calibration and `(epoch, cycle)` of the newest trigger heard before it.
    survey: Option<(SurveyCalibration, (u64, u64))>,
    /// Each clock's newest reported sync sigma (seconds) and the status's stamp.
    sync_sigma_s: BTreeMap<u32, (Time, f64)>,
}

/// What takes effect for the cycle about to be solved.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DueControl {
    /// The calibration to solve with from now on.
    pub survey: Option<SurveyCalibration>,
    /// `(clock, sync sigma in seconds)` to take from now on.
    pub sync_sigma_s: Vec<(u32, f64)>,
}

impl PendingControl {
    /// Holds `calibration` until the first cycle triggered after
    /// `newest_trigger` (`(epoch, cycle)`; a newer calibration replaces it).
    pub fn hold_survey(&mut self, calibration: &SurveyCalibration, newest_trigger: (u64, u64)) {
        self.survey = Some((calibration.clone(), newest_trigger));
    }

    /// `(epoch, version)` of the calibration held, if any.
    pub fn survey_held(&self) -> Option<(u64, u32)> {
        self.survey.as_ref().map(|(c, _)| (c.epoch, c.version))
    }

    /// Forgets a held calibration unless it is of `epoch` (a new central
    /// unit starts from the surveyed positions).
    pub fn keep_survey_of(&mut self, epoch: Option<u64>) {
        if self
            .survey
            .as_ref()
            .is_some_and(|(c, _)| Some(c.epoch) != epoch)
        {
            self.survey = None;
        }
    }

    /// Forgets a held calibration (a newer one was applied at once).
    pub fn forget_survey(&mut self) {
        self.survey = None;
    }

    /// Forgets the sync sigma held for `clock` (a newer one was taken at once).
    pub fn forget_sync_sigma(&mut self, clock: u32) {
        self.sync_sigma_s.remove(&clock);
    }

    /// Holds the sync sigma `sigma_s` of `clock`, reported in a status made
    /// at `stamp`, until the first cycle that starts after it (the newest
    /// report of a clock replaces the one held).
    pub fn hold_sync_sigma(&mut self, clock: u32, stamp: Time, sigma_s: f64) {
        self.sync_sigma_s.insert(clock, (stamp, sigma_s));
    }

    /// What takes effect for a cycle of trigger `matched`; `None`: the
    /// arrivals name no cycle (the whole schedule fires), and everything
    /// held takes effect.
    pub fn due(&mut self, matched: Option<&CycleTrigger>) -> DueControl {
        let survey_due = |heard: &(u64, u64)| matched.is_none_or(|t| (t.epoch, t.cycle) > *heard);
        let survey = match &self.survey {
            Some((_, heard)) if survey_due(heard) => self.survey.take().map(|(c, _)| c),
            _ => None,
        };
        let sync_due = |stamp: Time| matched.is_none_or(|t| stamp <= t.start);
        let sync_sigma_s = self
            .sync_sigma_s
            .iter()
            .filter(|(_, (stamp, _))| sync_due(*stamp))
            .map(|(&clock, &(_, sigma))| (clock, sigma))
            .collect::<Vec<_>>();
        for (clock, _) in &sync_sigma_s {
            self.sync_sigma_s.remove(clock);
        }
        DueControl {
            survey,
            sync_sigma_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trigger(cycle: u64, start_ms: i64) -> CycleTrigger {
        let mut t = crate::cycle_match::tests::trigger_in(1, cycle, &[(1, 0)]);
        t.start = Time::from_nanos(start_ms * 1_000_000);
        t
    }

    fn calibration(version: u32) -> SurveyCalibration {
        SurveyCalibration {
            epoch: 1,
            version,
            fixes_taken: 10,
            offsets: Vec::new(),
            speed_of_sound_m_s: 0.0,
            speed_of_sound_sigma_m_s: 0.0,
        }
    }

    #[test]
    fn news_takes_effect_from_the_cycle_it_names_and_not_before() {
        let mut pending = PendingControl::default();
        pending.hold_survey(&calibration(3), (1, 43));
        pending.hold_sync_sigma(2, Time::from_nanos(4_350_000_000), 40e-6);
        pending.hold_sync_sigma(3, Time::from_nanos(4_250_000_000), 30e-6);
        // Cycle 43 (started at 4.3 s) was triggered before the calibration,
        // and started before clock 2's status was made.
        let due = pending.due(Some(&trigger(43, 4_300)));
        assert_eq!(due.survey, None);
        assert_eq!(due.sync_sigma_s, vec![(3, 30e-6)]);
        // A newer report of clock 2 replaces the one held.
        pending.hold_sync_sigma(2, Time::from_nanos(4_380_000_000), 50e-6);
        let due = pending.due(Some(&trigger(44, 4_400)));
        assert_eq!(due.survey.map(|c| c.version), Some(3));
        assert_eq!(due.sync_sigma_s, vec![(2, 50e-6)]);
        assert_eq!(
            pending.due(Some(&trigger(45, 4_500))),
            DueControl::default()
        );
    }

    #[test]
    fn without_a_cycle_everything_held_takes_effect_and_a_new_epoch_drops_the_calibration() {
        let mut pending = PendingControl::default();
        pending.hold_survey(&calibration(3), (1, 43));
        pending.keep_survey_of(Some(1));
        assert_eq!(pending.survey_held(), Some((1, 3)));
        // A status stamped far in the future waits for a cycle after it...
        pending.hold_sync_sigma(1, Time::from_nanos(i64::MAX), 1e-3);
        assert!(
            pending
                .due(Some(&trigger(44, 4_400)))
                .sync_sigma_s
                .is_empty()
        );
        // ...until the cell's next report replaces it.
        pending.hold_sync_sigma(1, Time::from_nanos(4_450_000_000), 20e-6);
        let due = pending.due(None);
        assert_eq!(due.sync_sigma_s, vec![(1, 20e-6)]);
        assert_eq!(due.survey, None, "taken with cycle 44");
        pending.hold_survey(&calibration(4), (1, 50));
        pending.keep_survey_of(Some(2));
        assert_eq!(pending.survey_held(), None);
    }
}
