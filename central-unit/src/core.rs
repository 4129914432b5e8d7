//! The central unit as a sans-IO state machine: fed with events and the
//! current master time, it answers which cycle triggers and schedules to
//! publish, and what to tell the admin CLI. The Zenoh node only moves bytes.
//!
//! Membership: the schedule includes the cells whose liveliness token is
//! present (before any cell has announced itself, every cell of the site, so
//! that cells starting a little late lose nothing). As soon as the set of
//! live cells differs from the scheduled one, a new schedule version is made
//! that takes effect at the first cycle whose trigger is at least
//! [`CentralConfig::schedule_announce`] away, so that every cell has it
//! before it is used and all switch at the same cycle.
//!
//! A cell is reported `down` when its token is absent, it takes no part in
//! the schedule of the last triggered cycle, it has missed
//! [`crate::health::MISSED_IN_A_ROW_FOR_DOWN`] cycles in a row that it was
//! due to fire in, or its reports (status, bursts) stopped for
//! [`crate::health::REPORTS_SILENT_FOR_DOWN`] (a hung cell keeps its token
//! until the link lease expires; it stays in the schedule, so that it is
//! back as soon as it reports). Otherwise it is `up` when the last
//! triggered cycle named one of its transmitters, `idle` when it did not
//! (occupancy-aware firing leaves cells no robot can hear quiet: not firing
//! is what they were asked to do). Missed cycles count only the cycles a
//! cell was due in. The cycle at which the state last changed is kept, so
//! that the admin sees when a cell went down or came back.
//!
//! Epochs ([`ickon_proto::epoch`]): every trigger and schedule carries the
//! central unit's epoch, its start on the master time base, so that a
//! restarted central unit is recognised at its first message. The central
//! unit hears its own keys too: a schedule or trigger it did not send is
//! counted ([`CentralCore::foreign_control`]) and answered: the schedule is
//! re-announced at once, under a higher version if the foreign one claimed
//! a newer one (every receiver refuses a known version with other content,
//! so only that can displace it). The newest schedule is also re-announced
//! every [`CentralConfig::schedule_reannounce`], so a lost one heals.

use std::collections::{BTreeMap, VecDeque};

use ickon_proto::epoch::{check_schedule, epoch_of, plausible_epoch};
use ickon_proto::msg::control::{
    AirTemperature, Burst, CellStatus, CycleTrigger, Schedule, SiteInfo, SurveyCalibration,
};
use ickon_proto::msg::robot::{Fix, MsuStatus, RobotSummary};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};

use crate::air_temperature::AirTemperatures;
use crate::health::{CellTracker, RobotTracker};
use crate::occupancy::FiringConfig;
use crate::schedule::{ScheduleError, compute_schedule, compute_uniform_schedule};
use crate::selection::{FiringHistory, PlanStats};
use crate::spacing::SpacingTable;
use crate::survey_calibration::{CalibrationConfig, SurveyPublisher, fix_rate::FixRate};

/// Which schedule the central unit computes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum SchedulePolicy {
    /// Each transmitter as early as the geometry lets it ([`compute_schedule`]).
    #[default]
    Tight,
    /// One slot per emission, cells coloured apart, to measure against
    /// ([`crate::schedule::compute_uniform_schedule`]).
    Uniform,
}

/// Tuning of the central unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentralConfig {
    /// How long before a cycle starts its trigger goes out (covers the network
    /// and lets the cells program their timers).
    pub trigger_lead: Duration,
    /// Delay from start-up to the first cycle.
    pub start_delay: Duration,
    /// A new schedule is published at least this long before the trigger of
    /// the first cycle that uses it.
    pub schedule_announce: Duration,
    /// The newest schedule is published again this often, so that a
    /// receiver that missed it (or was handed a forged one) heals.
    pub schedule_reannounce: Duration,
    /// Which schedule to compute.
    pub schedule: SchedulePolicy,
    /// Which transmitters fire each cycle.
    pub firing: FiringConfig,
    /// The fleet's calibration of the transmitters' positions
    /// ([`crate::survey_calibration`]); `None`: not learnt, not published.
    pub survey: Option<CalibrationConfig>,
}

impl Default for CentralConfig {
    fn default() -> Self {
        Self {
            trigger_lead: Duration::from_millis(60),
            start_delay: Duration::from_millis(500),
            schedule_announce: Duration::from_millis(100),
            schedule_reannounce: Duration::from_millis(1_000),
            schedule: SchedulePolicy::default(),
            firing: FiringConfig::default(),
            survey: Some(CalibrationConfig::default()),
        }
    }
}

/// What the central unit is told. Queries (site, schedule, admin) are
/// answered from its state by the methods of the same names; everything
/// else arrives as an event.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// Nothing but time passed: do what is due (see [`CentralCore::next_wake`]).
    Tick,
    /// A cell's liveliness token appeared (`up`) or went.
    CellAlive {
        /// The cell.
        id: String,
        /// Present or gone.
        up: bool,
    },
    /// A robot's liveliness token appeared (`up`) or went.
    RobotAlive {
        /// The robot.
        id: String,
        /// Present or gone.
        up: bool,
    },
    /// A cell's status report.
    CellStatus(CellStatus),
    /// A reading of a cell board's air temperature sensor.
    AirTemperature(AirTemperature),
    /// A burst report, its `actual` emission time on the master time base.
    Burst(Burst),
    /// A robot's summary ([`RobotSummary`]): its pose, velocity and
    /// newest fixes, checked by the robot's [`crate::summary_gate`].
    Summary {
        /// The robot.
        robot: String,
        /// Its summary (boxed: the other events are small).
        summary: Box<RobotSummary>,
    },
    /// A fix of a robot handed over on its own (the virtual-time engine's
    /// single-robot runs; on the mesh fixes come in summaries).
    Fix {
        /// The robot.
        robot: String,
        /// The fix (boxed: the other events are small).
        fix: Box<Fix>,
    },
    /// A robot's agent reported its state.
    RobotStatus {
        /// The robot.
        robot: String,
        /// Its report.
        status: MsuStatus,
    },
    /// A schedule was published on `central/schedule` (its own included).
    ScheduleSeen(Schedule),
    /// A trigger was published on `central/cycle` (its own included).
    TriggerSeen(CycleTrigger),
    /// The active central unit's liveliness token went (a standby takes over).
    ActiveGone,
}

/// What the node must publish.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// A cycle trigger on `central/cycle`.
    Trigger(CycleTrigger),
    /// A new schedule on `central/schedule`.
    Schedule(Schedule),
    /// The fleet's survey calibration on `central/survey`.
    Survey(SurveyCalibration),
}

impl Output {
    /// The epoch it belongs to.
    pub fn epoch(&self) -> u64 {
        match self {
            Self::Trigger(t) => t.epoch,
            Self::Schedule(s) => s.epoch,
            Self::Survey(s) => s.epoch,
        }
    }
}

/// The central unit's state (`Clone`: the fuzz target copies a built core
/// per case instead of building the spacing table again).
#[derive(Clone)]
pub struct CentralCore {
    config: CentralConfig,
    site: Site,
    site_toml: String,
    site_version: u32,
    schedules: Vec<Schedule>,
    next_cycle: u64,
    next_start: Time,
    paused: bool,
    cells: BTreeMap<String, CellTracker>,
    robots: BTreeMap<String, RobotTracker>,
    unknown_robot_messages: u64,
    /// Summaries dropped by the robots' gates, by reason.
    summaries_dropped: BTreeMap<&'static str, u64>,
    any_cell_seen: bool,
    epoch: u64,
    foreign_control: u64,
    /// The triggers sent last, to tell them from foreign ones when they come back.
    sent_triggers: VecDeque<CycleTrigger>,
    next_reannounce: Time,
    /// `Some` while this central unit is a hot standby (see [`standby`]).
    pub(crate) standby: Option<standby::Follower>,
    /// The spacings of the transmitters of the cells of the schedule last
    /// triggered, for packing occupancy-aware cycles (built when first needed).
    table: Option<SpacingTable>,
    /// When each transmitter of `table` last fired (the rotation of the
    /// transmitters chosen for what robots need).
    history: FiringHistory,
    /// What the firing plans chose, for the reports.
    plan_stats: PlanStats,
    last_trigger: Option<CycleTrigger>,
    /// The latest `now` seen, to notice the master clock stepping back.
    latest_now: Time,
    /// The fleet's survey calibration, when the configuration asks for it.
    survey: Option<SurveyPublisher>,
    /// Fixes the survey calibration could not take, by reason (debugging
    /// a calibration that does not move).
    survey_skipped: BTreeMap<&'static str, u64>,
    /// Each robot's share of the survey calibration.
    survey_fix_rate: FixRate,
    /// What computing the survey calibrations cost, as the node measured it.
    survey_cost: admin::SurveyCost,
    /// The last tick triggered a cycle: the survey calibration, if due, is
    /// computed in the next tick, after the trigger is published.
    survey_deferred: bool,
    /// Cycles triggered by this central unit, or heard from the active one
    /// while a standby (never counted again from 0): what each robot's
    /// share refills with.
    cycles_heard: u64,
    /// The cell boards' air temperature sensors.
    air: AirTemperatures,
}

impl CentralCore {
    /// A central unit serving `site` (whose file text is `site_toml`), starting at `now`.
    pub fn new(
        site: Site,
        site_toml: String,
        config: CentralConfig,
        now: Time,
    ) -> Result<Self, ScheduleError> {
        let epoch = epoch_of(now, None);
        let site_for_survey = site.clone();
        let all: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        let schedule = Schedule {
            epoch,
            ..make_schedule(config.schedule, &site, &all, 1, 0)?
        };
        let cells = all
            .iter()
            .map(|id| (id.clone(), CellTracker::default()))
            .collect();
        Ok(Self {
            config,
            site,
            site_toml,
            site_version: 1,
            schedules: vec![schedule],
            next_cycle: 0,
            next_start: now + config.start_delay,
            paused: false,
            cells,
            robots: BTreeMap::new(),
            unknown_robot_messages: 0,
            summaries_dropped: BTreeMap::new(),
            any_cell_seen: false,
            epoch,
            foreign_control: 0,
            sent_triggers: VecDeque::new(),
            next_reannounce: now + config.schedule_reannounce,
            standby: None,
            table: None,
            history: FiringHistory::default(),
            plan_stats: PlanStats::default(),
            last_trigger: None,
            latest_now: now,
            survey: config
                .survey
                .map(|c| SurveyPublisher::new(&site_for_survey, c)),
            survey_skipped: BTreeMap::new(),
            survey_fix_rate: FixRate::default(),
            survey_cost: admin::SurveyCost::default(),
            survey_deferred: false,
            cycles_heard: 0,
            air: AirTemperatures::new(all.iter().map(String::as_str)),
        })
    }

    /// What the firing plans of the cycles triggered so far chose.
    pub fn plan_stats(&self) -> &PlanStats {
        &self.plan_stats
    }

    /// This central unit's epoch (see [`ickon_proto::epoch`]).
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// Schedules and triggers heard on the central unit's keys that it did
    /// not send.
    pub fn foreign_control(&self) -> u64 {
        self.foreign_control
    }

    /// The site being served.
    pub fn site(&self) -> &Site {
        &self.site
    }

    /// The answer of `central/site`.
    pub fn site_info(&self) -> SiteInfo {
        SiteInfo {
            site: self.site.name.clone(),
            version: self.site_version,
            site_toml: self.site_toml.clone(),
        }
    }

    /// Whether it is the active central unit (not a standby).
    pub fn is_active(&self) -> bool {
        self.standby.is_none()
    }

    /// The newest schedule (possibly not yet in force).
    pub fn latest_schedule(&self) -> &Schedule {
        self.schedules.last().expect("a schedule always exists")
    }

    /// The schedule in force for `cycle`.
    pub fn schedule_for(&self, cycle: u64) -> &Schedule {
        self.schedules
            .iter()
            .rev()
            .find(|s| s.effective_cycle <= cycle)
            .unwrap_or(&self.schedules[0])
    }

    /// The last cycle triggered (0 before the first).
    pub fn last_cycle(&self) -> u64 {
        self.next_cycle.saturating_sub(1)
    }

    /// Takes `event` at master time `now`, then emits whatever is due.
    pub fn handle(&mut self, now: Time, event: Event) -> Vec<Output> {
        let mut out = self.notice_clock_step_back(now);
        out.extend(self.handle_event(now, event));
        // What an epoch superseded within this call said (a clock step back
        // and then a takeover, say) every receiver would refuse: only the
        // current epoch's outputs go.
        out.retain(|o| o.epoch() == self.epoch);
        out
    }

    fn handle_event(&mut self, now: Time, event: Event) -> Vec<Output> {
        let mut out = match event {
            Event::Tick => Vec::new(),
            Event::CellAlive { id, up } => self.cell_alive(&id, up, now),
            Event::RobotAlive { id, up } => {
                self.robot_alive(&id, up);
                Vec::new()
            }
            Event::CellStatus(status) => {
                self.on_cell_status(status, now);
                Vec::new()
            }
            Event::Burst(burst) => {
                self.on_burst(&burst, now);
                Vec::new()
            }
            Event::AirTemperature(reading) => {
                // Refusals are counted and logged by the sensors' books.
                let _ = self
                    .air
                    .observe(&reading.cell_id, reading.temperature_c, now);
                Vec::new()
            }
            Event::Summary { robot, summary } => {
                self.on_summary(&robot, &summary, now);
                Vec::new()
            }
            Event::RobotStatus { robot, status } => {
                self.on_robot_status(&robot, status);
                Vec::new()
            }
            Event::Fix { robot, fix } => {
                self.on_fix(&robot, now);
                self.survey_fix(&robot, &fix, now);
                Vec::new()
            }
            Event::ScheduleSeen(schedule) if self.standby.is_some() => {
                self.follow_schedule(schedule);
                Vec::new()
            }
            Event::TriggerSeen(trigger) if self.standby.is_some() => {
                self.follow_trigger(trigger, now);
                Vec::new()
            }
            // A newer epoch beyond the horizon was forged: counted as
            // foreign control below, not a reason to stand by.
            Event::ScheduleSeen(schedule) => {
                // A schedule no cell could fire is no sign of another
                // central unit: only counted as foreign control.
                if schedule.epoch > self.epoch
                    && plausible_epoch(schedule.epoch, now)
                    && check_schedule(&schedule).is_ok()
                {
                    self.step_down(&schedule);
                    return Vec::new();
                }
                self.on_schedule_seen(schedule, now)
            }
            Event::TriggerSeen(trigger) => {
                if trigger.epoch > self.epoch && plausible_epoch(trigger.epoch, now) {
                    self.step_down_for(trigger, now);
                    return Vec::new();
                }
                self.on_trigger_seen(&trigger);
                Vec::new()
            }
            Event::ActiveGone if self.standby.is_some() => self.take_over(now),
            Event::ActiveGone => Vec::new(),
        };
        if self.standby.is_some() {
            // A standby keeps its books (cells, robots) but publishes
            // nothing, not even the schedules its membership view makes.
            return if self.lease_expired(now) {
                self.take_over(now)
            } else {
                Vec::new()
            };
        }
        if now >= self.next_wake() {
            out.extend(self.tick(now));
        }
        out
    }
}

mod admin;
pub use admin::parse_reloaded_site;
pub use robots::RobotFootprint;
mod cycles;
mod foreign;
mod membership;
mod robots;

pub mod standby;

#[cfg(test)]
mod air_tests;
#[cfg(test)]
mod fleet_memory_tests;
#[cfg(test)]
mod forged_tests;

/// The schedule of `policy`.
fn make_schedule(
    policy: SchedulePolicy,
    site: &Site,
    cells: &[String],
    version: u32,
    effective_cycle: u64,
) -> Result<Schedule, ScheduleError> {
    match policy {
        SchedulePolicy::Tight => compute_schedule(site, cells, version, effective_cycle),
        SchedulePolicy::Uniform => compute_uniform_schedule(site, cells, version, effective_cycle),
    }
}

#[cfg(test)]
mod tests;
