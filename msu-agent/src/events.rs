//! The MSU core's contract, as every node's: one [`Event`] in, [`Output`]s
//! back. The core has no clock of its own (its time is its inputs' stamps,
//! judged by [`crate::time_gate`]), so unlike the central unit and the cell
//! it takes no `now`. What to publish when is decided here, not in the
//! adapter: a fix whenever the cycle gives a valid one, then the pose that
//! absorbed it (the latency a user of the pose sees), and the pose after
//! each odometry sample (the robot's own rate); gyro and obstacle samples
//! move the estimate without a publication of their own.

use ickon_proto::msg::control::{CellStatus, CycleTrigger, Schedule, SurveyCalibration};
use ickon_proto::msg::robot::{Fix, Imu, ObstacleRanges, Odometry, RobotPose, UltrasoundArrivals};

use crate::beacons::{BeaconDistances, KitPosition};
use crate::core::MsuCore;
use crate::error::MsuError;

/// Something that happened to the MSU.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A (new) schedule from the central unit.
    Schedule(Schedule),
    /// A cycle trigger from the central unit (which transmitters fire).
    Trigger(CycleTrigger),
    /// One cycle's arrivals from the receivers.
    Arrivals(UltrasoundArrivals),
    /// The robot's wheel odometry.
    Odometry(Odometry),
    /// The robot's gyro.
    Imu(Imu),
    /// The robot's obstacle sensors.
    Range(ObstacleRanges),
    /// A cell's status (its sync sigma: how far its bursts may be off).
    CellStatus(CellStatus),
    /// The fleet's survey calibration from the central unit.
    Survey(SurveyCalibration),
    /// Distances to beacons from a ranging source.
    BeaconDistances(BeaconDistances),
    /// A ranging kit's own position.
    KitPosition(KitPosition),
}

/// Which kind of input an [`Output::Refused`] concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum InputKind {
    /// An arrivals message.
    Arrivals,
    /// An odometry sample.
    Odometry,
    /// A gyro sample.
    Imu,
    /// An obstacle-ranges sample.
    Range,
    /// A schedule.
    Schedule,
    /// A cell's status.
    CellStatus,
    /// A survey calibration.
    Survey,
    /// A reading of distances to beacons.
    BeaconDistances,
    /// A ranging kit's own position.
    KitPosition,
}

/// What the core asks its adapter to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Publish a raw fix (`robot/<id>/fix`).
    Fix(Fix),
    /// Publish the fused pose (`robot/<id>/pose`).
    Pose(RobotPose),
    /// An input could not be used (count it; log it at a bounded rate).
    Refused {
        /// What kind of input.
        input: InputKind,
        /// Why.
        error: MsuError,
    },
}

impl MsuCore {
    /// Handles one event and says what to publish.
    pub fn handle(&mut self, event: Event) -> Vec<Output> {
        let mut out = Vec::new();
        let refused = |input, error| Output::Refused { input, error };
        match event {
            Event::Schedule(s) => {
                if let Err(e) = self.set_schedule(s) {
                    out.push(refused(InputKind::Schedule, e));
                }
            }
            Event::Trigger(t) => self.on_trigger(t),
            Event::Arrivals(msg) => match self.on_arrivals(&msg) {
                Ok(Some(fix)) => {
                    out.push(Output::Fix(fix));
                    out.extend(self.pose().map(Output::Pose));
                }
                Ok(None) => {}
                Err(e) => out.push(refused(InputKind::Arrivals, e)),
            },
            Event::Odometry(msg) => match self.on_odometry(&msg) {
                Ok(()) => out.extend(self.pose().map(Output::Pose)),
                Err(e) => out.push(refused(InputKind::Odometry, e)),
            },
            Event::Imu(msg) => {
                if let Err(e) = self.on_imu(&msg) {
                    out.push(refused(InputKind::Imu, e));
                }
            }
            Event::Range(msg) => {
                if let Err(e) = self.on_range(&msg) {
                    out.push(refused(InputKind::Range, e));
                }
            }
            Event::CellStatus(status) => {
                if let Err(e) = self.on_cell_status(&status) {
                    out.push(refused(InputKind::CellStatus, e));
                }
            }
            Event::BeaconDistances(msg) => {
                if let Err(e) = self.on_beacon_distances(&msg) {
                    out.push(refused(InputKind::BeaconDistances, e));
                }
                out.extend(self.pose().map(Output::Pose));
            }
            Event::KitPosition(p) => {
                if let Err(e) = self.on_kit_position(&p) {
                    out.push(refused(InputKind::KitPosition, e));
                }
                out.extend(self.pose().map(Output::Pose));
            }
            Event::Survey(survey) => {
                if let Err(e) = self.on_survey_calibration(&survey) {
                    out.push(refused(InputKind::Survey, e));
                }
            }
        }
        out
    }
}
