//! [`MsuCore`]: the MSU as one state machine fed with messages (it never
//! reads a clock). It is two parts: a [`FixSolver`] (arrivals -> raw fix,
//! published whenever it is valid) and a [`FusionHost`] (fix, range
//! differences, odometry, gyro and obstacle ranges -> one or several
//! estimators -> pose). An estimator refusing an input never withholds a fix.

use ickon_fusion::estimator::{EncoderSample, Estimator, GyroSample, Input, RangeSample};
use ickon_proto::msg::control::{
    CellStatus, CycleTrigger, MAX_LATE_M, MAX_SURVEY_OFFSET_M, Schedule, SurveyCalibration,
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
    /// number, negative, or an offset beyond [`MAX_SURVEY_OFFSET_M`] or a
    /// lateness beyond [`MAX_LATE_M`].
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
                .all(|v| v.is_finite() && v.abs() <= MAX_SURVEY_OFFSET_M)
            {
                return Err(refuse(format!(
                    "transmitter {}: offset {:?} m is not a number or beyond {MAX_SURVEY_OFFSET_M} m",
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
pub(crate) mod tests {
    use super::*;
    use ickon_fusion::estimator::WheelGeometry;
    use ickon_fusion::estimator::build_by_name;
    use ickon_proto::msg::control::Emission;
    use ickon_proto::msg::control::TransmitterEntry;
    use ickon_proto::msg::robot::{Arrival, FixQuality};
    use ickon_proto::time::{Duration, Time};

    pub(super) const C: f64 = 343.0;
    pub(super) const TX: [(u32, [f64; 3]); 5] = [
        (1, [0.0, 0.0, 2.8]),
        (2, [5.0, 0.0, 2.6]),
        (3, [5.0, 4.0, 2.8]),
        (4, [0.0, 4.0, 2.6]),
        (5, [2.5, 2.0, 2.7]),
    ];

    fn core() -> MsuCore {
        core_with("msu-raw")
    }

    pub(crate) fn core_with(estimator: &str) -> MsuCore {
        let config = MsuConfig {
            speed_of_sound_m_s: C,
            height_m: 0.5,
            receiver_angles_rad: (0..6).map(|i| f64::from(i) * 60f64.to_radians()).collect(),
            transmitters: TX
                .iter()
                .map(|(id, p)| TransmitterEntry {
                    tx_id: *id,
                    cell_id: "a".into(),
                    x_m: p[0],
                    y_m: p[1],
                    z_m: p[2],
                })
                .collect(),
            wheels: WheelGeometry {
                wheel_base_m: 0.33,
                left_m_per_tick: 1e-4,
                right_m_per_tick: 1e-4,
            },
            timing_sigma_s: 10e-6,
            residual_gate_m: 0.05,
            floor_bounds_m: Some([[0.0, 0.0], [5.0, 4.0]]),
            max_fix_sigma_m: 0.5,
            walls: Vec::new(),
            columns: Vec::new(),
        };
        let mut core = MsuCore::new(config, build_by_name(estimator).unwrap());
        core.set_schedule(schedule()).unwrap();
        core
    }

    pub(super) fn schedule() -> Schedule {
        Schedule {
            version: 1,
            effective_cycle: 0,
            cycle_period: Duration::from_millis(200),
            slot_length: Duration::from_millis(40),
            emissions: TX
                .iter()
                .enumerate()
                .map(|(i, (id, _))| Emission {
                    tx_id: *id,
                    cell_id: "a".into(),
                    offset: Duration::from_millis(40 * i as i64),
                    slot: i as u32,
                })
                .collect(),
            active_cells: vec!["a".into()],
            epoch: 1,
        }
    }

    pub(super) fn arrivals(p: [f64; 3], late_m: &[(u32, f64)]) -> UltrasoundArrivals {
        arrivals_from(&TX, p, late_m)
    }

    /// The arrivals at `p` from transmitters hanging at `tx` (the table's
    /// positions, or where a wrong survey put them).
    pub(super) fn arrivals_from(
        tx: &[(u32, [f64; 3])],
        p: [f64; 3],
        late_m: &[(u32, f64)],
    ) -> UltrasoundArrivals {
        let start_s = 10.0;
        let arrivals = tx
            .iter()
            .enumerate()
            .map(|(i, (id, t))| {
                let d =
                    ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt();
                let extra = late_m
                    .iter()
                    .find(|(k, _)| k == id)
                    .map_or(0.0, |(_, e)| *e);
                Arrival {
                    tx_id: *id,
                    receiver_id: 0,
                    t_arrival: Time::from_secs_f64(start_s + 0.04 * i as f64 + (d + extra) / C),
                }
            })
            .collect();
        UltrasoundArrivals { seq: 7, arrivals }
    }

    #[test]
    fn exact_arrivals_give_an_exact_fix_and_the_estimator_takes_it() {
        let mut core = core();
        let fix = core
            .on_arrivals(&arrivals([1.7, 2.9, 0.5], &[]))
            .unwrap()
            .unwrap();
        assert!(
            (fix.x_m - 1.7).abs() < 1e-5 && (fix.y_m - 2.9).abs() < 1e-5,
            "{fix:?}"
        );
        assert_eq!(fix.used.len(), 5);
        assert_eq!(fix.quality, FixQuality::Good);
        let pose = core.pose().unwrap();
        assert!((pose.x_m - 1.7).abs() < 1e-5);
        assert_eq!(pose.fix_seq, 7);
    }

    #[test]
    fn a_reflected_arrival_is_rejected_when_the_others_agree() {
        let mut core = core();
        let fix = core
            .on_arrivals(&arrivals([3.2, 1.1, 0.5], &[(3, 0.6)]))
            .unwrap()
            .unwrap();
        assert_eq!(fix.rejected, vec![3]);
        assert!(
            (fix.x_m - 3.2).abs() < 1e-4 && (fix.y_m - 1.1).abs() < 1e-4,
            "{fix:?}"
        );
    }

    #[test]
    fn a_tightly_coupled_estimator_converges_on_range_differences_alone() {
        let mut core = core_with("tdoa-ekf");
        let truth = [2.2, 1.4, 0.5];
        for k in 0..20 {
            let mut msg = arrivals(truth, &[]);
            msg.seq = k;
            for a in &mut msg.arrivals {
                a.t_arrival =
                    a.t_arrival + ickon_proto::time::Duration::from_millis(200 * k as i64);
            }
            let _ = core.on_arrivals(&msg);
        }
        let pose = core
            .pose()
            .expect("the filter started from the differences");
        let err = ((pose.x_m - truth[0]).powi(2) + (pose.y_m - truth[1]).powi(2)).sqrt();
        assert!(err < 0.01, "error {err} m: {pose:?}");
    }

    #[test]
    fn a_restarted_msu_takes_its_pose_from_its_first_fixes_not_the_start_pose() {
        // The MSU restarted with the site's start pose, 3 m from the robot.
        let truth = [3.6, 2.9, 0.5];
        for name in ["tdoa-ekf", "ickon-akf"] {
            let mut estimator =
                ickon_fusion::estimator::EstimatorConfig::default_for(name).unwrap();
            estimator.set_initial_pose([0.8, 1.0, 0.0]);
            if let ickon_fusion::estimator::EstimatorConfig::TdoaEkf(p) = &mut estimator {
                p.receiver_height_m = 0.5;
            }
            let mut core = core_with("msu-raw");
            core.host = FusionHost::new(vec![ickon_fusion::estimator::build(&estimator).unwrap()]);
            let mut placed = None;
            for k in 0..10_u64 {
                let mut msg = arrivals(truth, &[]);
                msg.seq = k;
                for a in &mut msg.arrivals {
                    a.t_arrival = a.t_arrival + Duration::from_millis(200 * k as i64);
                }
                core.on_arrivals(&msg).unwrap();
                let pose = core.pose().expect("started at the start pose");
                let err = (pose.x_m - truth[0]).hypot(pose.y_m - truth[1]);
                // Until a fix confirms it, the pose says it is a guess; a
                // placed filter whose heading is still unknown (this robot
                // stands still, so its track never gives one) is not
                // confirmed either.
                if pose.status != PoseStatus::Localising {
                    assert!(err < 0.05, "{name} cycle {k}: {pose:?}");
                } else if err < 0.05 {
                    assert!(
                        pose.covariance[8].sqrt() > CONFIRMED_HEADING_SIGMA_RAD,
                        "{name} cycle {k}: placed and heading known: {pose:?}"
                    );
                }
                if err < 0.05 {
                    placed.get_or_insert(k);
                } else {
                    assert!(
                        placed.is_none(),
                        "{name}: lost again at cycle {k}: {pose:?}"
                    );
                }
            }
            // Placed at the second agreeing cycle (ickon-akf's start check);
            // tdoa-ekf asks three against a start pose, spanning a second
            // (cycles of 0.2 s here: the sixth).
            let want = if name == "tdoa-ekf" { 5 } else { 1 };
            assert_eq!(placed, Some(want), "{name}");
        }
    }

    #[test]
    fn a_valid_fix_is_published_when_the_estimator_refuses_it() {
        for name in ["ickon-akf", "gyro-ckf", "tdoa-ekf"] {
            let mut core = core_with(name);
            // Gyro samples an hour ahead: the estimator's history moves past
            // every real input, so it refuses the cycle's fix as too late.
            for k in 0..3 {
                let _ = core.on_imu(&Imu {
                    stamp: Time::from_secs_f64(3_600.0 + f64::from(k)),
                    gyro_z_rad_s: 0.0,
                });
            }
            let refused_before = core.host().refused(0);
            let fix = core
                .on_arrivals(&arrivals([1.7, 2.9, 0.5], &[]))
                .unwrap()
                .unwrap_or_else(|| panic!("{name}: the cycle's fix is valid"));
            assert!((fix.x_m - 1.7).abs() < 1e-5, "{name}: {fix:?}");
            assert!(
                core.host().refused(0) > refused_before,
                "{name}: the estimator took an input from an hour ago"
            );
        }
    }

    #[test]
    fn every_hosted_estimator_gets_the_same_fix() {
        let config = core().solver.config().clone();
        let names = ["msu-raw", "ickon-akf", "tdoa-ekf"];
        let mut core = MsuCore::with_estimators(
            config,
            names.iter().map(|n| build_by_name(n).unwrap()).collect(),
        );
        core.set_schedule(schedule()).unwrap();
        let fix = core
            .on_arrivals(&arrivals([3.1, 1.2, 0.5], &[]))
            .unwrap()
            .unwrap();
        assert_eq!(core.host().len(), 3);
        let raw = core.pose_of(0).unwrap();
        assert_eq!((raw.x_m, raw.y_m), (fix.x_m, fix.y_m));
        assert_eq!(raw.estimator, "msu-raw");
        assert_eq!(
            core.pose_of(2).map(|p| p.estimator),
            Some("tdoa-ekf".into())
        );
    }

    #[test]
    fn one_sample_stamped_an_hour_ahead_does_not_silence_the_robot() {
        let mut core = core_with("tdoa-ekf");
        let fix = |core: &mut MsuCore, k: u64| {
            let mut msg = arrivals([2.2, 1.4, 0.5], &[]);
            msg.seq = k;
            for a in &mut msg.arrivals {
                a.t_arrival = a.t_arrival + Duration::from_millis(200 * k as i64);
            }
            core.on_arrivals(&msg)
        };
        for k in 0..5 {
            let _ = fix(&mut core, k);
        }
        let refused_before = core.host().refused(0);
        let bogus = core.on_imu(&Imu {
            stamp: Time::from_secs_f64(3_610.0),
            gyro_z_rad_s: 0.0,
        });
        assert!(
            matches!(bogus, Err(MsuError::FromTheFuture { .. })),
            "{bogus:?}"
        );
        assert_eq!(core.refused_from_the_future(), 1);
        // Real inputs go on being fused.
        for k in 5..10 {
            assert!(fix(&mut core, k).unwrap().is_some());
        }
        assert_eq!(core.host().refused(0), refused_before, "nothing wedged");
        let pose = core.pose().unwrap();
        assert!(pose.stamp.as_secs_f64() < 100.0, "{pose:?}");
    }

    #[test]
    fn the_event_contract_publishes_the_fix_then_its_pose_and_reports_refusals() {
        use crate::events::{Event, InputKind, Output};
        let mut core = core_with("ickon-akf");
        let out = core.handle(Event::Arrivals(arrivals([1.7, 2.9, 0.5], &[])));
        assert!(
            matches!(out.as_slice(), [Output::Fix(f), Output::Pose(p)] if f.stamp == p.stamp),
            "{out:?}"
        );
        let out = core.handle(Event::Imu(Imu {
            stamp: Time::from_secs_f64(3_610.0),
            gyro_z_rad_s: 0.0,
        }));
        assert!(
            matches!(
                out.as_slice(),
                [Output::Refused {
                    input: InputKind::Imu,
                    error: MsuError::FromTheFuture { .. }
                }]
            ),
            "{out:?}"
        );
        let out = core.handle(Event::Arrivals(UltrasoundArrivals {
            seq: 8,
            arrivals: vec![],
        }));
        assert!(
            matches!(
                out.as_slice(),
                [Output::Refused {
                    input: InputKind::Arrivals,
                    ..
                }]
            ),
            "{out:?}"
        );
    }

    #[test]
    fn a_pose_carries_the_exact_nanosecond_of_the_input_it_answers() {
        use crate::events::{Event, Output};
        let mut core = core_with("odometry");
        // Unix time with odd nanoseconds: as f64 seconds it keeps only
        // about a quarter of a microsecond.
        let t0 = Time::from_nanos(1_764_000_000_123_456_789);
        for k in 0..20_i64 {
            let stamp = t0 + Duration::from_nanos(k * 10_000_001);
            let out = core.handle(Event::Odometry(Odometry {
                stamp,
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: 0.0,
                left_ticks: 10 * k,
                right_ticks: 11 * k,
            }));
            match out.as_slice() {
                [Output::Pose(p)] => assert_eq!(p.stamp, stamp, "sample {k}"),
                other => panic!("sample {k}: {other:?}"),
            }
        }
    }

    #[test]
    fn arrivals_before_any_schedule_are_an_error() {
        let mut c = core();
        c.solver.clear_schedule();
        assert_eq!(
            c.on_arrivals(&arrivals([1.0, 1.0, 0.5], &[])),
            Err(MsuError::NoSchedule)
        );
    }

    #[test]
    fn an_empty_schedule_under_the_current_version_is_refused_and_fixes_go_on() {
        let mut c = core();
        let empty = Schedule {
            emissions: Vec::new(),
            ..schedule()
        };
        let out = c.handle(crate::events::Event::Schedule(empty));
        assert!(
            matches!(
                out.as_slice(),
                [crate::events::Output::Refused {
                    input: crate::events::InputKind::Schedule,
                    error: MsuError::Schedule(_)
                }]
            ),
            "{out:?}"
        );
        assert!(matches!(
            c.on_arrivals(&arrivals([1.0, 1.0, 0.5], &[])),
            Ok(Some(_))
        ));
    }
}
