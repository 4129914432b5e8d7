//! [`MsuCore`]: the MSU as one state machine fed with messages (it never
//! reads a clock). It is two parts: a [`FixSolver`] (arrivals -> raw fix,
//! published whenever it is valid) and a [`FusionHost`] (fix, range
//! differences, odometry, gyro and obstacle ranges -> one or several
//! estimators -> pose). An estimator refusing an input never withholds a fix.

use ickon_fusion::estimator::{EncoderSample, Estimator, GyroSample, Input, RangeSample};
use ickon_proto::msg::control::{
    CellStatus, CycleTrigger, MAX_LATE_M, MAX_RESURVEYED_OFFSET_M, MAX_SOUND_SPEED_CHANGE,
    Schedule, SurveyCalibration,
};
use ickon_proto::msg::robot::{
    Fix, Imu, ObstacleRanges, Odometry, PoseStatus, RobotPose, UltrasoundArrivals,
};
use ickon_proto::time::{Duration, Time};

pub use crate::config::MsuConfig;
pub use crate::error::MsuError;
use crate::fusion_clock::FusionClock;
use crate::host::FusionHost;
use crate::solver::FixSolver;
use crate::time_gate::{TimeGate, Verdict};

/// Largest sync sigma a cell status may report: 10 ms, 3.4 m of sound.
pub const MAX_CELL_SYNC_SIGMA: Duration = Duration::from_millis(10);

/// An input stream silent for longer than this (by the stamps of the
/// others) makes the pose stale: a few cycles of the slowest site (1.6
/// cycles/s) without a fix, or dozens of odometry periods.
pub const STALE_AFTER: Duration = Duration::from_millis(3_000);

/// How fast the position uncertainty of a stale pose grows beyond what the
/// estimator says, m/s: the estimator's own growth assumes its models hold,
/// and a robot without fixes for seconds is exactly when they may not
/// (slip, a wrong wheel scale). About a tenth of the robot's top speed.
pub const STALE_GROWTH_M_PER_S: f64 = 0.05;

/// A fix and the estimator's pose agree (the pose is confirmed) when they
/// are within this many standard deviations of both, added (the bound the
/// estimators' own start check uses), the pose's counted at most as the
/// fix's.
const AGREE_SIGMAS: f64 = 3.0;

/// Largest heading sigma of a confirmed pose, radians (30 deg): the
/// receiver-id heading's own half-width, so a heading from the start pose,
/// the track or the receivers qualifies and an unknown one (a filter placed
/// at a fix, heading still to be found) does not.
const CONFIRMED_HEADING_SIGMA_RAD: f64 = 0.52;

/// Fastest a wheeled indoor robot drives, m/s (as the fix solver's motion
/// check): bounds the distance between a fix and a newer pose when there is
/// no odometry to tell it.
const MAX_SPEED_M_S: f64 = 2.0;

/// The per-robot MSU state machine.
pub struct MsuCore {
    solver: FixSolver,
    host: FusionHost,
    fix_seq: u64,
    time_gate: TimeGate,
    /// Wire time to fusion time and back, exactly.
    clock: FusionClock,
    /// Stamp of the newest valid fix, of the newest odometry sample, and
    /// of the first input taken (MSU clock).
    last_fix: Option<Time>,
    last_odometry: Option<Time>,
    first_input: Option<Time>,
    /// Whether a fix has agreed with the primary estimator's pose yet
    /// (until then every pose is [`PoseStatus::Localising`]).
    localised: bool,
}

impl MsuCore {
    /// A core hosting `estimator`.
    pub fn new(config: MsuConfig, estimator: Box<dyn Estimator>) -> Self {
        Self::with_estimators(config, vec![estimator])
    }

    /// A core hosting several estimators fed alike (the first is the
    /// primary: its pose is [`pose`](Self::pose) and its refusals are
    /// returned); `ickon eval` compares estimators on one solve per cycle.
    pub fn with_estimators(config: MsuConfig, estimators: Vec<Box<dyn Estimator>>) -> Self {
        Self {
            solver: FixSolver::new(config),
            host: FusionHost::new(estimators),
            fix_seq: 0,
            time_gate: TimeGate::default(),
            clock: FusionClock::default(),
            last_fix: None,
            last_odometry: None,
            first_input: None,
            localised: false,
        }
    }

    /// Takes the schedule the arrivals are matched against, if the rules
    /// of [`ickon_proto::epoch`] allow it (an altered or backward one is
    /// refused, and the one in force stays).
    pub(crate) fn set_schedule(&mut self, schedule: Schedule) -> Result<(), MsuError> {
        self.solver
            .set_schedule(schedule)
            .map_err(MsuError::Schedule)
    }

    /// A cycle trigger heard from the central unit (which transmitters fire
    /// when): arrivals are solved with the trigger that explains them.
    ///
    /// A trigger before the robot's first input is ignored, like a cell's
    /// status: a recording's replay starts at the first input the agent
    /// took and cannot tell the triggers the agent heard before it from
    /// those sent before it listened.
    pub(crate) fn on_trigger(&mut self, trigger: CycleTrigger) {
        if self.first_input.is_some() {
            self.solver.note_trigger(trigger);
        }
    }

    /// A cell's status: the sync sigma it reports becomes the prior of its
    /// clock bias in `tdoa-ekf` (see `ickon_fusion`'s `clock_slots.rs`). A
    /// sigma that is negative or over [`MAX_CELL_SYNC_SIGMA`] (no cell
    /// that far off fires usefully), or a cell not of this site, is refused.
    ///
    /// A status before the robot's first input is ignored: a recording's
    /// replay starts at the first input the agent took, and the statuses it
    /// had heard before that cannot be told from those it had not (each
    /// cell reports every second, so the next one comes soon).
    pub(crate) fn on_cell_status(&mut self, status: &CellStatus) -> Result<(), MsuError> {
        let refuse = |reason| MsuError::CellStatus {
            cell: status.cell_id.clone(),
            reason,
        };
        let sigma_ns = status.offset_sigma_ns;
        if !(0..=MAX_CELL_SYNC_SIGMA.as_nanos()).contains(&sigma_ns) {
            return Err(refuse("sync sigma negative or over 10 ms"));
        }
        let Some(clock) = self.solver.clock_of_cell(&status.cell_id) else {
            return Err(refuse("not a cell of this site"));
        };
        if self.first_input.is_some() {
            self.solver
                .take_clock_sync_sigma(clock, status.stamp, sigma_ns as f64 * 1e-9);
        }
        Ok(())
    }

    /// A status heard under the key of cell `key_cell` (`None`: a key that
    /// is not a cell's status key), if it names that cell. A cell may
    /// publish only under its own key (the router's access control); a
    /// status naming another cell is forged, and is refused by the live
    /// agent and the recording's replay alike.
    pub fn status_under_key(
        key_cell: Option<&str>,
        status: CellStatus,
    ) -> Result<CellStatus, MsuError> {
        if key_cell == Some(status.cell_id.as_str()) {
            Ok(status)
        } else {
            Err(MsuError::CellStatus {
                cell: status.cell_id,
                reason: "heard under another cell's key",
            })
        }
    }

    /// The primary estimator's name.
    pub fn estimator_name(&self) -> &'static str {
        self.host.name(0).unwrap_or("none")
    }

    /// The estimators.
    pub fn host(&self) -> &FusionHost {
        &self.host
    }

    /// Inputs refused for being stamped far ahead of the others.
    pub fn refused_from_the_future(&self) -> u64 {
        self.time_gate.refused()
    }

    /// Lets `stamp` through the time gate, or says why not.
    fn gate(&mut self, stamp: Time) -> Result<(), MsuError> {
        match self.time_gate.check(stamp.as_secs_f64()) {
            Verdict::Accept => {
                self.first_input.get_or_insert(stamp);
                Ok(())
            }
            Verdict::FromTheFuture { ahead_s } => Err(MsuError::FromTheFuture { ahead_s }),
        }
    }

    /// Whether a pose at `stamp` is tracked, and if not why: not yet
    /// confirmed by a fix ([`PoseStatus::Localising`]), or which input
    /// stalled; and how long fixes have been silent beyond [`STALE_AFTER`]
    /// (zero when they are coming).
    pub fn staleness(&self, stamp: Time) -> (PoseStatus, Duration) {
        let silent = |last: Option<Time>| {
            let since = last
                .or(self.first_input)
                .map_or(Duration::ZERO, |t| stamp.since(t));
            (since > STALE_AFTER).then(|| since - STALE_AFTER)
        };
        let no_fixes = silent(self.last_fix);
        let status = if !self.localised {
            PoseStatus::Localising
        } else if no_fixes.is_some() {
            PoseStatus::NoFixes
        } else if silent(self.last_odometry).is_some() {
            PoseStatus::NoOdometry
        } else {
            PoseStatus::Tracking
        };
        (status, no_fixes.unwrap_or(Duration::ZERO))
    }

    /// Whether the primary estimator's pose agrees with a fix at `xy_m`
    /// of one-sigma `fix_sigma_m` measured at `fix_t_s` (see
    /// [`AGREE_SIGMAS`]). The pose is newer than the fix (a cycle's fix
    /// comes after its last arrival, the pose moves with every odometry
    /// sample), so the distance the wheels drove in between is allowed too;
    /// without odometry, what the fastest robot could drive.
    fn agrees_with(&self, xy_m: [f64; 2], fix_sigma_m: f64, fix_t_s: f64) -> bool {
        let Some(p) = self.host.pose(0) else {
            return false;
        };
        let c = &p.covariance;
        let heading_sigma_rad = c[(2, 2)].sqrt();
        // NaN (or a negative variance) counts as unknown.
        if heading_sigma_rad.is_nan() || heading_sigma_rad > CONFIRMED_HEADING_SIGMA_RAD {
            // Placed, heading unknown: odometry would carry the pose the
            // wrong way, so the estimator has not found the robot yet.
            return false;
        }
        let own_sigma_m = (c[(0, 0)] + c[(1, 1)]).max(0.0).sqrt();
        // A pose older than the fix (an estimator that did not take it)
        // gets no allowance: it claims where the robot was, then.
        let newer_s = (p.t_s - fix_t_s).max(0.0);
        let driven_m = if newer_s > 0.0 {
            self.solver
                .travelled_m(fix_t_s, p.t_s)
                .unwrap_or(MAX_SPEED_M_S * newer_s)
        } else {
            0.0
        };
        let apart_m = (p.x_m - xy_m[0]).hypot(p.y_m - xy_m[1]);
        // The estimator's own sigma counts only up to the fix's: a filter
        // that says it is lost (metres of sigma) would agree with anything.
        apart_m <= AGREE_SIGMAS * (own_sigma_m.min(fix_sigma_m) + fix_sigma_m) + driven_m
    }

    /// Solves one cycle and hands the fix and the cycle's range differences
    /// to the estimators. `Ok(Some(fix))` for every valid fix, whether or
    /// not an estimator took it (refusals are counted by the host);
    /// `Ok(None)`: no fix this cycle; `Err`: the message cannot be used.
    pub(crate) fn on_arrivals(
        &mut self,
        msg: &UltrasoundArrivals,
    ) -> Result<Option<Fix>, MsuError> {
        if let Some(last) = msg.arrivals.iter().map(|a| a.t_arrival).max() {
            self.gate(last)?;
        }
        let hint = self.host.pose(0).map(|p| [p.x_m, p.y_m]);
        let solved = self.solver.solve(msg, hint, &mut self.clock)?;
        for sample in solved.range_differences {
            // A refused difference (a reflection failing the physical check,
            // an outlier at the gate, one too late for the history) leaves
            // the estimator as it was; the host counts it.
            let _ = self.host.feed(&Input::RangeDifference(sample));
        }
        let Some((fix, wire)) = solved.fix else {
            return Ok(None);
        };
        self.fix_seq = msg.seq;
        self.last_fix = Some(self.last_fix.map_or(wire.stamp, |t| t.max(wire.stamp)));
        let (fix_xy_m, fix_sigma_m, fix_t_s) = (
            [fix.x_m(), fix.y_m()],
            fix.covariance_xy_m2().trace().max(0.0).sqrt(),
            fix.t_s,
        );
        if let Err(e) = self.host.feed(&Input::Fix(fix)) {
            tracing::debug!("fix of cycle {} not fused: {e}", msg.seq);
        }
        // Once confirmed, later disagreements are the estimator's to weigh.
        if !self.localised && self.agrees_with(fix_xy_m, fix_sigma_m, fix_t_s) {
            self.localised = true;
            tracing::info!(
                "pose confirmed by the fix of cycle {} at ({:.2}, {:.2}) m",
                msg.seq,
                fix_xy_m[0],
                fix_xy_m[1]
            );
        }
        Ok(Some(wire))
    }

    /// Takes the fleet's survey calibration (`central/survey`): the fix
    /// solver uses its corrected transmitter positions from the next cycle
    /// (while triggers are followed, the first cycle triggered after it:
    /// [`crate::solver::FixSolver::take_survey_calibration`]).
    /// `Ok(true)`: taken; `Ok(false)`: not newer than the one taken
    /// (the central unit repeats it every second), no schedule yet to tell
    /// the central unit in charge, or none of the robot's inputs yet (as
    /// with a cell's status: a recording's replay starts at the first input
    /// the agent took, and cannot tell a calibration the agent heard before
    /// it from one it had not subscribed to yet; the repeat will do).
    /// Refused, and nothing changes: a
    /// calibration of another epoch than the schedules followed, an
    /// unknown or repeated transmitter, an offset or sigma that is not a
    /// number, negative, or an offset beyond [`MAX_RESURVEYED_OFFSET_M`] or a
    /// lateness beyond [`MAX_LATE_M`], a speed of sound more than
    /// [`MAX_SOUND_SPEED_CHANGE`] from the site's.
    pub(crate) fn on_survey_calibration(
        &mut self,
        c: &SurveyCalibration,
    ) -> Result<bool, MsuError> {
        let refuse = |reason: String| MsuError::Survey {
            epoch: c.epoch,
            version: c.version,
            reason,
        };
        match self.solver.schedule_epoch() {
            // Before the first schedule: the next repeat will do.
            None => return Ok(false),
            Some(epoch) if epoch != c.epoch => {
                return Err(refuse(
                    "not of the central unit whose schedules are followed".into(),
                ));
            }
            Some(_) => {}
        }
        if self
            .solver
            .newest_survey_calibration()
            .is_some_and(|taken| taken >= (c.epoch, c.version))
        {
            return Ok(false);
        }
        if c.version == 0 {
            return Err(refuse("version 0 names the surveyed positions".into()));
        }
        let known = &self.solver.config().transmitters;
        let mut seen = std::collections::BTreeSet::new();
        for o in &c.offsets {
            if !known.iter().any(|t| t.tx_id == o.tx_id) {
                return Err(refuse(format!(
                    "transmitter {} is not in the table",
                    o.tx_id
                )));
            }
            if !seen.insert(o.tx_id) {
                return Err(refuse(format!("transmitter {} appears twice", o.tx_id)));
            }
            if !o
                .offset_m
                .iter()
                .all(|v| v.is_finite() && v.abs() <= MAX_RESURVEYED_OFFSET_M)
            {
                return Err(refuse(format!(
                    "transmitter {}: offset {:?} m is not a number or beyond {MAX_RESURVEYED_OFFSET_M} m",
                    o.tx_id, o.offset_m
                )));
            }
            if !o.sigma_m.iter().all(|v| v.is_finite() && *v >= 0.0) {
                return Err(refuse(format!(
                    "transmitter {}: sigma {:?} m is not a number or negative",
                    o.tx_id, o.sigma_m
                )));
            }
            if !(o.late_m.is_finite() && o.late_m.abs() <= MAX_LATE_M) {
                return Err(refuse(format!(
                    "transmitter {}: lateness {} m is not a number or beyond {MAX_LATE_M} m",
                    o.tx_id, o.late_m
                )));
            }
            if !(o.late_sigma_m.is_finite() && o.late_sigma_m >= 0.0) {
                return Err(refuse(format!(
                    "transmitter {}: lateness sigma {} m is not a number or negative",
                    o.tx_id, o.late_sigma_m
                )));
            }
        }
        let site_m_s = self.solver.site_speed_of_sound_m_s();
        if c.speed_of_sound_m_s != 0.0
            && !(c.speed_of_sound_m_s.is_finite()
                && (c.speed_of_sound_m_s / site_m_s - 1.0).abs() <= MAX_SOUND_SPEED_CHANGE)
        {
            return Err(refuse(format!(
                "speed of sound {} m/s is not a number or more than {} % from the site's {site_m_s:.2} m/s",
                c.speed_of_sound_m_s,
                MAX_SOUND_SPEED_CHANGE * 100.0
            )));
        }
        if !(c.speed_of_sound_sigma_m_s.is_finite() && c.speed_of_sound_sigma_m_s >= 0.0) {
            return Err(refuse(format!(
                "speed of sound sigma {} m/s is not a number or negative",
                c.speed_of_sound_sigma_m_s
            )));
        }
        if self.first_input.is_none() {
            return Ok(false);
        }
        self.solver.take_survey_calibration(c);
        Ok(true)
    }

    /// `(epoch, version)` of the survey calibration the fixes are solved
    /// with; `None`: the surveyed positions.
    pub fn survey_calibration(&self) -> Option<(u64, u32)> {
        self.solver.survey_calibration()
    }

    /// `(epoch, version)` of the newest survey calibration taken, whether
    /// its first cycle has come or not.
    pub fn newest_survey_calibration(&self) -> Option<(u64, u32)> {
        self.solver.newest_survey_calibration()
    }

    /// Feeds wheel odometry (its encoder ticks, with the nominal geometry).
    pub(crate) fn on_odometry(&mut self, odom: &Odometry) -> Result<(), MsuError> {
        self.gate(odom.stamp)?;
        self.last_odometry = Some(self.last_odometry.map_or(odom.stamp, |t| t.max(odom.stamp)));
        let geometry = self.solver.config().wheels;
        let input = Input::Encoders(EncoderSample {
            t_s: self.clock.to_fusion(odom.stamp),
            left_ticks: odom.left_ticks,
            right_ticks: odom.right_ticks,
            geometry,
        });
        self.solver.odometry(&input);
        self.host.feed(&input)?;
        Ok(())
    }

    /// Feeds one gyro sample.
    pub(crate) fn on_imu(&mut self, imu: &Imu) -> Result<(), MsuError> {
        self.gate(imu.stamp)?;
        self.host.feed(&Input::Gyro(GyroSample {
            t_s: self.clock.to_fusion(imu.stamp),
            rate_rad_s: imu.gyro_z_rad_s,
        }))?;
        Ok(())
    }

    /// Feeds one obstacle-sensor sample.
    pub(crate) fn on_range(&mut self, r: &ObstacleRanges) -> Result<(), MsuError> {
        self.gate(r.stamp)?;
        self.host.feed(&Input::Range(RangeSample {
            t_s: self.clock.to_fusion(r.stamp),
            left_ultrasonic_m: r.left_valid.then_some(r.left_m),
            right_ultrasonic_m: r.right_valid.then_some(r.right_m),
            left_ir_m: r.left_ir_valid.then_some(r.left_ir_m),
            right_ir_m: r.right_ir_valid.then_some(r.right_ir_m),
            planned_heading_rad: None,
        }))?;
        Ok(())
    }

    /// The primary estimator's fused pose, once it is initialised.
    pub fn pose(&self) -> Option<RobotPose> {
        self.pose_of(0)
    }

    /// The speed of sound the fixes are solved with now, m/s: the survey
    /// calibration's when one applies, else the site's.
    pub fn speed_of_sound_m_s(&self) -> f64 {
        self.solver.config().speed_of_sound_m_s
    }

    /// Estimator `i`'s fused pose, once it is initialised. A stale pose
    /// says why ([`PoseStatus`]); without fixes its position variance grows
    /// by `(STALE_GROWTH_M_PER_S * t)^2`, `t` the time beyond [`STALE_AFTER`].
    pub fn pose_of(&self, i: usize) -> Option<RobotPose> {
        let p = self.host.pose(i)?;
        let mut c = p.covariance;
        let stamp = self.clock.to_wire(p.t_s);
        let (status, over) = self.staleness(stamp);
        if over > Duration::ZERO {
            let grown = (STALE_GROWTH_M_PER_S * over.as_secs_f64()).powi(2);
            c[(0, 0)] += grown;
            c[(1, 1)] += grown;
        }
        Some(RobotPose {
            stamp,
            x_m: p.x_m,
            y_m: p.y_m,
            theta_rad: p.theta_rad,
            covariance: [
                c[(0, 0)],
                c[(0, 1)],
                c[(0, 2)],
                c[(1, 0)],
                c[(1, 1)],
                c[(1, 2)],
                c[(2, 0)],
                c[(2, 1)],
                c[(2, 2)],
            ],
            estimator: self.host.name(i).unwrap_or("none").to_owned(),
            fix_seq: self.fix_seq,
            status,
        })
    }
}

#[cfg(test)]
mod beacon_tests;
mod beacons;
#[cfg(test)]
mod firing_tests;
#[cfg(test)]
mod hidden_tests;
#[cfg(test)]
mod stale_tests;
#[cfg(test)]
mod survey_tests;
#[cfg(test)]
mod sync_tests;

#[cfg(test)]
pub(crate) mod tests;
