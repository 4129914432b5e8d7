//! An MSU core driven outside the live agent: the virtual-time engine, the
//! fleet loop and the MCAP replay hand it their time-ordered inputs as
//! [`Event`]s, exactly as the agent's event loop does, and every input the
//! core refuses is counted by kind (and reported by the harness), never
//! dropped unseen.

use std::collections::BTreeMap;

use ickon_proto::msg::robot::{Fix, RobotPose};

use crate::core::MsuCore;
use crate::events::{Event, InputKind, Output};

/// An MSU core with the count of the inputs it refused.
pub struct MsuDriver {
    core: MsuCore,
    refused: BTreeMap<InputKind, u64>,
    first_refusal: Option<String>,
}

/// What one input gave: the fix and the pose the live agent would publish.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Fed {
    /// The cycle's fix (arrivals only).
    pub fix: Option<Fix>,
    /// The pose published after the input (a fix or an odometry sample).
    pub pose: Option<RobotPose>,
}

impl MsuDriver {
    /// Drives `core`.
    pub fn new(core: MsuCore) -> Self {
        Self {
            core,
            refused: BTreeMap::new(),
            first_refusal: None,
        }
    }

    /// Hands one input to the core through its single entry point.
    pub fn feed(&mut self, event: Event) -> Fed {
        let mut fed = Fed::default();
        for output in self.core.handle(event) {
            match output {
                Output::Fix(fix) => fed.fix = Some(fix),
                Output::Pose(pose) => fed.pose = Some(pose),
                Output::Refused { input, error } => {
                    *self.refused.entry(input).or_default() += 1;
                    self.first_refusal
                        .get_or_insert_with(|| format!("{input:?}: {error}"));
                }
            }
        }
        fed
    }

    /// The core, to read its estimates.
    pub fn core(&self) -> &MsuCore {
        &self.core
    }

    /// Inputs refused so far, by kind.
    pub fn refused(&self) -> &BTreeMap<InputKind, u64> {
        &self.refused
    }

    /// The first refusal, with its reason, to report beside the counts.
    pub fn first_refusal(&self) -> Option<&str> {
        self.first_refusal.as_deref()
    }

    /// One line for a report: how many inputs of each kind were refused,
    /// and the first reason; `None` when nothing was refused.
    pub fn refusal_summary(&self) -> Option<String> {
        if self.refused.is_empty() {
            return None;
        }
        let counts: Vec<String> = self
            .refused
            .iter()
            .map(|(kind, n)| format!("{n} {kind:?}"))
            .collect();
        Some(format!(
            "refused {} (first: {})",
            counts.join(", "),
            self.first_refusal.as_deref().unwrap_or("-")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::robot::Imu;
    use ickon_proto::time::Time;

    #[test]
    fn refused_inputs_are_counted_by_kind_with_the_first_reason() {
        let mut driver = MsuDriver::new(crate::core::tests::core_with("gyro-ckf"));
        let bad = Imu {
            stamp: Time::from_secs_f64(1.0),
            gyro_z_rad_s: f64::NAN,
        };
        assert_eq!(driver.feed(Event::Imu(bad)), Fed::default());
        driver.feed(Event::Imu(bad));
        assert_eq!(driver.refused().get(&InputKind::Imu), Some(&2));
        assert_eq!(driver.refused().len(), 1);
        let summary = driver.refusal_summary().unwrap();
        assert!(
            summary.starts_with("refused 2 Imu (first: Imu: "),
            "{summary}"
        );
        let good = Imu {
            stamp: Time::from_secs_f64(1.01),
            gyro_z_rad_s: 0.1,
        };
        driver.feed(Event::Imu(good));
        assert_eq!(driver.refused().get(&InputKind::Imu), Some(&2));
    }

    #[test]
    fn nothing_refused_gives_no_summary() {
        let driver = MsuDriver::new(crate::core::tests::core_with("msu-raw"));
        assert_eq!(driver.refusal_summary(), None);
        assert_eq!(driver.first_refusal(), None);
    }
}
