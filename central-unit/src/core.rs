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
//! A cell is reported `up` while its token is present, it takes part in
//! the schedule of the last triggered cycle and it has not missed
//! [`crate::health::MISSED_IN_A_ROW_FOR_DOWN`] scheduled cycles in a row (a
//! hung cell keeps its token until the link lease expires; it stays in the
//! schedule, so that it is up again as soon as it fires); the cycle at which that last
//! changed is kept, so that the admin sees when a cell went down or came back.
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

use ickon_proto::epoch::{epoch_of, plausible_epoch};
use ickon_proto::msg::admin::{AdminAck, CoverageReport, StatusReport};
use ickon_proto::msg::control::{
    Burst, CellStatus, ClockReply, CycleTrigger, Schedule, SiteInfo, SurveyCalibration,
};
use ickon_proto::msg::robot::{Fix, PoseStatus, RobotPose};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};

use crate::health::{CellTracker, RobotTracker};
use crate::occupancy::{FiringConfig, RobotView, firing_plan};
use crate::schedule::{ScheduleError, compute_schedule, compute_uniform_schedule};
use crate::spacing::SpacingTable;
use crate::survey_calibration::{
    CalibrationConfig, FixSkipped, SavedCalibration, SavedMismatch, SurveyPublisher,
    fix_rate::FixRate,
};
use ickon_proto::msg::control::Firing;

/// Which schedule the central unit computes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum SchedulePolicy {
    /// Each transmitter as early as the geometry lets it ([`compute_schedule`]).
    #[default]
    Tight,
    /// The schedule from before issue 20, to measure against
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
    /// A burst report, its `actual` emission time on the master time base.
    Burst(Burst),
    /// A robot published a pose.
    Pose {
        /// The robot.
        robot: String,
        /// Its pose.
        pose: RobotPose,
    },
    /// A robot published a fix.
    Fix {
        /// The robot.
        robot: String,
        /// The fix (boxed: the other events are small).
        fix: Box<Fix>,
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
    /// Cycles triggered by this central unit, or heard from the active one
    /// while a standby (never counted again from 0): what each robot's
    /// share refills with.
    cycles_heard: u64,
}

/// Own triggers remembered to recognise them on the way back (a few cycles' worth).
const SENT_TRIGGERS_KEPT: usize = 16;

/// Cycles that may still be triggered late in one tick; older ones are skipped.
const MAX_LATE_CYCLES: i64 = 2;

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
            any_cell_seen: false,
            epoch,
            foreign_control: 0,
            sent_triggers: VecDeque::new(),
            next_reannounce: now + config.schedule_reannounce,
            standby: None,
            table: None,
            last_trigger: None,
            latest_now: now,
            survey: config
                .survey
                .map(|c| SurveyPublisher::new(&site_for_survey, c)),
            survey_skipped: BTreeMap::new(),
            survey_fix_rate: FixRate::default(),
            cycles_heard: 0,
        })
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

    /// When the node should call [`tick`](Self::tick) next: the next
    /// trigger time (the schedule is re-announced with the first trigger
    /// after its period, so it needs no wake-up of its own); for a standby,
    /// when the active one's lease runs out.
    pub fn next_wake(&self) -> Time {
        match &self.standby {
            Some(f) => f.lease_end(),
            None => self.next_trigger_at(),
        }
    }

    /// When the next trigger goes out.
    fn next_trigger_at(&self) -> Time {
        self.next_start - self.config.trigger_lead
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
                self.on_cell_status(status);
                Vec::new()
            }
            Event::Burst(burst) => {
                self.on_burst(&burst);
                Vec::new()
            }
            Event::Pose { robot, pose } => {
                self.on_pose(&robot, pose, now);
                Vec::new()
            }
            Event::Fix { robot, fix } => {
                self.on_fix(&robot, now);
                self.survey_fix(&robot, &fix);
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
                if schedule.epoch > self.epoch && plausible_epoch(schedule.epoch, now) {
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

    /// When the master clock stepped back by more than a cycle (an operator
    /// or NTP set it), the next trigger time lies that far ahead and the
    /// site would stay silent until the clock caught up. Instead the cycles
    /// start again at once in a new epoch, as after a restart: receivers
    /// drop the old epoch's cycle count, whose starts are now in the future.
    /// A standby only follows; smaller steps just delay one cycle.
    fn notice_clock_step_back(&mut self, now: Time) -> Vec<Output> {
        let period = self.schedule_for(self.next_cycle).cycle_period;
        let back = self.latest_now.since(now);
        if self.standby.is_some() {
            // A standby only follows: its time is whatever its clock says,
            // and a takeover starts from there.
            self.latest_now = now;
            return Vec::new();
        }
        if back <= period {
            self.latest_now = self.latest_now.max(now);
            return Vec::new();
        }
        self.latest_now = now;
        tracing::warn!(
            "the master clock stepped back by {:.3} s: cycles start again in a new epoch",
            back.as_secs_f64()
        );
        let out = self.new_epoch(now);
        // The first trigger of the new epoch after its schedule is out.
        self.next_start = now + self.config.schedule_announce + self.config.trigger_lead;
        self.next_reannounce = now + self.config.schedule_reannounce;
        out
    }

    /// Emits every trigger due at `now` (one per cycle, never two for one
    /// cycle); a standby emits nothing.
    fn tick(&mut self, now: Time) -> Vec<Output> {
        let mut out = self.notice_clock_step_back(now);
        if self.standby.is_some() {
            return out;
        }
        self.skip_stale_cycles(now);
        while now >= self.next_trigger_at() {
            let before = self.next_start;
            let cycle = self.next_cycle;
            let schedule = self.schedule_for(cycle).clone();
            let (firing, period) = self.plan_cycle(&schedule, now);
            let trigger = CycleTrigger {
                cycle,
                start: self.next_start,
                schedule_version: schedule.version,
                epoch: self.epoch,
                firing,
                cycle_period: period,
            };
            if !self.paused {
                if self.sent_triggers.len() == SENT_TRIGGERS_KEPT {
                    self.sent_triggers.pop_front();
                }
                self.sent_triggers.push_back(trigger.clone());
                out.push(Output::Trigger(trigger.clone()));
                self.count_missed(cycle);
            }
            self.last_trigger = Some(trigger);
            self.next_cycle = self.next_cycle.saturating_add(1);
            self.cycles_heard = self.cycles_heard.saturating_add(1);
            self.next_start = self.next_start + period;
            if self.next_start <= before {
                // At the end of time (saturated): nothing more to trigger.
                break;
            }
        }
        if now >= self.next_reannounce && !out.is_empty() {
            self.next_reannounce = now + self.config.schedule_reannounce;
            out.push(Output::Schedule(self.latest_schedule().clone()));
        }
        if let Some(survey) = self.survey.as_mut().and_then(|p| p.due(now, self.epoch)) {
            out.push(Output::Survey(survey));
        }
        out.extend(self.reconcile_membership(now));
        self.update_states();
        out
    }

    /// Gives a robot's fix to the survey calibration (a fix of a robot not
    /// on the site is counted by the health books, and still a fix of
    /// the site's transmitters), within the robot's share of the
    /// calibration: one fix a cycle (every robot the site does not list
    /// shares one such share).
    fn survey_fix(&mut self, robot: &str, fix: &Fix) {
        let key = if self.on_site(robot) { robot } else { "" };
        let Some(publisher) = self.survey.as_mut() else {
            return;
        };
        let taken = match self.survey_fix_rate.admit(key, self.cycles_heard) {
            Ok(()) => publisher.take_fix(fix),
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

    /// After a forward clock jump (or a process that was stopped), skips
    /// the cycles whose time is long past instead of triggering each of
    /// them late (a day's jump was 432 000 triggers in one tick, the end
    /// of time a loop without end); the cycle count moves on with the
    /// time, so that the cells' trigger gate still finds it in step.
    fn skip_stale_cycles(&mut self, now: Time) {
        let period = i128::from(
            self.schedule_for(self.next_cycle)
                .cycle_period
                .as_nanos()
                .max(1),
        );
        // In i128: the gap between two times may exceed i64 (a start taken
        // over from a forged trigger near i64::MIN, a clock near i64::MAX).
        let behind = i128::from(now.as_nanos()) - i128::from(self.next_trigger_at().as_nanos());
        let skip = behind / period - i128::from(MAX_LATE_CYCLES);
        if skip > 0 {
            self.next_cycle = self
                .next_cycle
                .saturating_add(u64::try_from(skip).unwrap_or(u64::MAX));
            let start = i128::from(self.next_start.as_nanos()) + skip * period;
            self.next_start = Time::from_nanos(i64::try_from(start).unwrap_or(i64::MAX));
        }
    }

    /// The transmitters that fire in the next cycle under `schedule` and
    /// the cycle's length: every emission of the schedule, or with
    /// occupancy-aware firing those robots can hear, packed anew.
    fn plan_cycle(&mut self, schedule: &Schedule, now: Time) -> (Vec<Firing>, Duration) {
        let all = || {
            schedule
                .emissions
                .iter()
                .map(|e| Firing {
                    tx_id: e.tx_id,
                    offset: e.offset,
                })
                .collect()
        };
        if !self.config.firing.occupancy {
            return (all(), schedule.cycle_period);
        }
        if self
            .table
            .as_ref()
            .is_none_or(|t| !same_cells(t, &schedule.active_cells))
        {
            self.table = Some(SpacingTable::new(&self.site, &schedule.active_cells));
        }
        let Some(table) = self.table.as_ref() else {
            return (all(), schedule.cycle_period);
        };
        let views: Vec<RobotView> = self
            .robots
            .values()
            .filter_map(|r| match r.last_pose() {
                // A pose no fix has confirmed may be far from the robot
                // (a restarted MSU): as good as none, so everything fires.
                Some((pose, at)) if pose.status != PoseStatus::Localising => {
                    Some(RobotView::Seen(pose, at, r.velocity()))
                }
                _ => r.alive.then_some(RobotView::New),
            })
            .collect();
        let guess = self
            .last_trigger
            .as_ref()
            .map_or(schedule.cycle_period, |t| t.period(schedule));
        let (offsets, period, need) =
            match firing_plan(table, &views, &self.config.firing, now, guess) {
                Some((p, need)) => (p.offsets, p.period, Some(need)),
                None => (
                    schedule
                        .emissions
                        .iter()
                        .filter_map(|e| Some((table.index_of(e.tx_id)?, e.offset)))
                        .collect(),
                    schedule.cycle_period,
                    None,
                ),
            };
        let spacing = |j: usize, i: usize| match &need {
            Some(n) => n.get(j).and_then(|r| r.get(i)).copied().flatten(),
            None => table.need(j, i),
        };
        // The previous cycle fired other transmitters at other offsets:
        // delay this one until every burst keeps its spacing from those.
        let mut delay = Duration::ZERO;
        if let Some(prev) = &self.last_trigger {
            let prev_period = prev.period(schedule);
            for f in &prev.firing {
                let Some(j) = table.index_of(f.tx_id) else {
                    continue;
                };
                for &(i, offset) in &offsets {
                    if let Some(n) = spacing(j, i) {
                        let earliest = f.offset + n;
                        let at = prev_period + offset + delay;
                        if earliest > at {
                            delay = delay + (earliest - at);
                        }
                    }
                }
            }
        }
        let firing = offsets
            .iter()
            .map(|&(i, offset)| Firing {
                tx_id: table.tx_ids[i],
                offset: offset + delay,
            })
            .collect();
        (firing, period + delay)
    }

    /// What the admin sees as the schedule: the newest schedule, or, once
    /// a cycle of it has been triggered, that cycle's firing set at its
    /// offsets and its length (the rate the site runs at now).
    pub fn current_firing(&self) -> Schedule {
        let latest = self.latest_schedule();
        match &self.last_trigger {
            Some(t) if t.schedule_version == latest.version => t.schedule_of_cycle(latest),
            _ => latest.clone(),
        }
    }

    /// The trigger of the last cycle (sent or, while paused, not).
    pub fn last_trigger(&self) -> Option<&CycleTrigger> {
        self.last_trigger.as_ref()
    }

    /// Counts, for the cycle two before `cycle` (its bursts have had time to
    /// arrive), the scheduled cells that did not fire.
    fn count_missed(&mut self, cycle: u64) {
        let Some(checked) = cycle.checked_sub(2) else {
            return;
        };
        let active = self.schedule_for(checked).active_cells.clone();
        for id in active {
            if let Some(c) = self.cells.get_mut(&id) {
                c.check_fired(checked);
            }
        }
    }

    /// The first cycle whose trigger leaves at least `schedule_announce` after `now`.
    fn first_announceable_cycle(&self, now: Time) -> u64 {
        let period = self.schedule_for(self.next_cycle).cycle_period;
        let mut cycle = self.next_cycle;
        let mut trigger_at = self.next_trigger_at();
        // A positive period is guaranteed by the scheduler; the bound keeps a
        // degenerate one from looping.
        for _ in 0..1_000 {
            if trigger_at.since(now) >= self.config.schedule_announce {
                break;
            }
            cycle += 1;
            trigger_at = trigger_at + period;
        }
        cycle
    }

    /// A new schedule when the live cells differ from the scheduled ones.
    fn reconcile_membership(&mut self, now: Time) -> Option<Output> {
        if !self.any_cell_seen {
            return None;
        }
        let live: Vec<String> = self
            .site
            .cells
            .iter()
            .filter(|c| self.cells.get(&c.id).is_some_and(|s| s.alive))
            .map(|c| c.id.clone())
            .collect();
        if live.is_empty() || live == self.latest_schedule().active_cells {
            return None;
        }
        // A forged schedule may have pushed the version to the last one.
        let Some(version) = self.latest_schedule().version.checked_add(1) else {
            tracing::warn!("no schedule version left in epoch {}", self.epoch);
            return None;
        };
        let effective = self.first_announceable_cycle(now);
        let schedule = Schedule {
            epoch: self.epoch,
            ..make_schedule(self.config.schedule, &self.site, &live, version, effective).ok()?
        };
        tracing::info!(
            "schedule v{version} from cycle {effective}: cells {}",
            live.join(", ")
        );
        self.push_schedule(schedule.clone());
        Some(Output::Schedule(schedule))
    }

    /// Adds a schedule and forgets those no cycle from the last triggered on uses.
    fn push_schedule(&mut self, schedule: Schedule) {
        self.schedules.push(schedule);
        let oldest_used = self.schedule_for(self.last_cycle()).version;
        self.schedules.retain(|s| s.version >= oldest_used);
    }

    /// Recomputes which cells are up and notes the cycle of every change.
    fn update_states(&mut self) {
        let cycle = self.last_cycle();
        let scheduled = self.schedule_for(cycle).active_cells.clone();
        for (id, c) in &mut self.cells {
            let up = c.alive && scheduled.contains(id) && !c.hung();
            if up != c.up {
                c.up = up;
                c.state_since_cycle = cycle;
            }
        }
    }

    /// A cell's liveliness token appeared (`up`) or disappeared at `now`;
    /// the schedule that follows from it, if any.
    fn cell_alive(&mut self, id: &str, up: bool, now: Time) -> Vec<Output> {
        let Some(c) = self.cells.get_mut(id) else {
            tracing::warn!("liveliness of unknown cell {id:?} ignored");
            return Vec::new();
        };
        c.alive = up;
        self.any_cell_seen |= up;
        tracing::info!("cell {id} is {}", if up { "up" } else { "down" });
        let out: Vec<Output> = self.reconcile_membership(now).into_iter().collect();
        self.update_states();
        out
    }

    /// A cell's status report.
    fn on_cell_status(&mut self, status: CellStatus) {
        if let Some(c) = self.cells.get_mut(&status.cell_id) {
            c.on_status(status);
        }
    }

    /// A burst report, its `actual` emission time on the master time base.
    /// Bursts of another epoch answer another central unit's triggers.
    fn on_burst(&mut self, burst: &Burst) {
        if burst.epoch != self.epoch {
            return;
        }
        if let Some(c) = self.cells.get_mut(&burst.cell_id) {
            c.on_burst(burst);
        }
    }

    /// A robot's liveliness token appeared or disappeared.
    fn robot_alive(&mut self, id: &str, up: bool) {
        if let Some(r) = self.robot_mut(id) {
            r.alive = up;
        }
    }

    /// The tracker of robot `id` if the site has it. Robots the site does
    /// not know are counted, not tracked: the table stays as large as the
    /// site, whatever anyone publishes.
    /// Whether `id` is one of the site's robots.
    fn on_site(&self, id: &str) -> bool {
        self.site.robots.iter().any(|r| r.id == id)
    }

    fn robot_mut(&mut self, id: &str) -> Option<&mut RobotTracker> {
        if self.on_site(id) {
            Some(self.robots.entry(id.to_string()).or_default())
        } else {
            self.unknown_robot_messages += 1;
            None
        }
    }

    /// Messages from robot ids the site does not know, ignored so far.
    pub fn unknown_robot_messages(&self) -> u64 {
        self.unknown_robot_messages
    }

    /// A robot published a pose, received at `now`.
    fn on_pose(&mut self, id: &str, pose: RobotPose, now: Time) {
        if let Some(r) = self.robot_mut(id) {
            r.on_pose(pose, now);
        }
    }

    /// A robot published a fix at `now`.
    fn on_fix(&mut self, id: &str, now: Time) {
        if let Some(r) = self.robot_mut(id) {
            r.on_fix(now);
        }
    }

    /// The reply of the central unit of `epoch` to a clock request that
    /// arrived at `t2` and leaves at `t3`.
    pub fn clock_reply(epoch: u64, t1: Time, t2: Time, t3: Time) -> ClockReply {
        ClockReply { t1, t2, t3, epoch }
    }

    /// A schedule heard on `central/schedule`: nothing if it is one of its
    /// own; otherwise counted, and the own schedule re-announced at once,
    /// under a version above the foreign one's when that claimed a newer
    /// version (receivers take only a newer version over it).
    fn on_schedule_seen(&mut self, seen: Schedule, now: Time) -> Vec<Output> {
        if seen.epoch == self.epoch && self.schedules.contains(&seen) {
            return Vec::new();
        }
        let latest = self.latest_schedule().clone();
        if seen.epoch == self.epoch && seen.version < latest.version {
            // One of its own, dropped since (or a forged old version, which
            // every receiver refuses as going backwards).
            if !self.schedules.iter().any(|s| s.version == seen.version) {
                return Vec::new();
            }
        }
        self.foreign_control += 1;
        if self.foreign_control.is_power_of_two() {
            tracing::warn!(
                "a schedule v{} of epoch {} that this central unit (epoch {}) did not send; {} so far",
                seen.version,
                seen.epoch,
                self.epoch,
                self.foreign_control
            );
        }
        self.next_reannounce = now + self.config.schedule_reannounce;
        if seen.epoch != self.epoch || seen.version <= latest.version {
            return vec![Output::Schedule(latest)];
        }
        let Some(version) = seen.version.checked_add(1) else {
            // No version above it: only a new epoch displaces it.
            return self.new_epoch(now);
        };
        let effective = self.first_announceable_cycle(now);
        let healed = Schedule {
            version,
            effective_cycle: effective,
            ..latest
        };
        tracing::info!("schedule re-issued as v{version} from cycle {effective}");
        self.push_schedule(healed.clone());
        vec![Output::Schedule(healed)]
    }

    /// Starts a new epoch at `now`: cycles count from 0 again and the
    /// schedule in force is re-issued as version 1, from the next cycle.
    pub(crate) fn new_epoch(&mut self, now: Time) -> Vec<Output> {
        self.epoch = epoch_of(now, Some(self.epoch));
        let current = self.schedule_for(self.next_cycle).clone();
        let schedule = Schedule {
            version: 1,
            effective_cycle: 0,
            epoch: self.epoch,
            ..current
        };
        self.schedules = vec![schedule.clone()];
        self.next_cycle = 0;
        self.sent_triggers.clear();
        tracing::info!("new epoch {}", self.epoch);
        vec![Output::Schedule(schedule)]
    }

    /// A trigger heard on `central/cycle`: counted if it is not one of its own.
    fn on_trigger_seen(&mut self, seen: &CycleTrigger) {
        if self.sent_triggers.contains(seen) {
            return;
        }
        self.foreign_control += 1;
        // Logged at 1, 2, 4, 8, ... so that a flood costs a few lines.
        if self.foreign_control.is_power_of_two() {
            tracing::warn!(
                "a trigger for cycle {} of epoch {} that this central unit (epoch {}) did not send; {} so far",
                seen.cycle,
                seen.epoch,
                self.epoch,
                self.foreign_control
            );
        }
    }

    /// The answer to `status`, `cells`, `robots` and `sync`.
    pub fn status(&self, now: Time) -> StatusReport {
        let schedule = self.schedule_for(self.last_cycle());
        StatusReport {
            site: self.site.name.clone(),
            cycle: self.last_cycle(),
            stamp: now,
            paused: self.paused,
            schedule_version: schedule.version,
            update_rate_hz: crate::schedule::update_rate_hz(schedule),
            cells: self.cells.iter().map(|(id, c)| c.health(id)).collect(),
            robots: self
                .robots
                .iter()
                .map(|(id, r)| r.health(id, now))
                .collect(),
            epoch: self.epoch,
            foreign_control: self.foreign_control,
            active: self.standby.is_none(),
        }
    }

    /// The answer to `coverage`: the floor as the transmitters of the
    /// schedule in force cover it, on a grid of about `resolution_m`.
    pub fn coverage(&self, resolution_m: f64) -> CoverageReport {
        let schedule = self.schedule_for(self.next_cycle);
        crate::coverage::coverage(
            &self.site,
            &schedule.active_cells,
            resolution_m,
            schedule.version,
        )
    }

    /// Stops (`true`) or resumes cycle triggers; cycle numbers keep counting.
    pub fn set_paused(&mut self, paused: bool) -> AdminAck {
        let was = self.paused;
        self.paused = paused;
        let word = if paused { "paused" } else { "resumed" };
        AdminAck {
            ok: true,
            messages: vec![if was == paused {
                format!("cycles already {word}")
            } else {
                format!("cycles {word} from cycle {}", self.next_cycle)
            }],
        }
    }

    /// Replaces the site with a new file if it is valid; a bad file is refused
    /// with every reason and the running site stays.
    pub fn reload(
        &mut self,
        toml_text: &str,
        file_name: &str,
        now: Time,
    ) -> (AdminAck, Option<Output>) {
        let refuse = |messages: Vec<String>| {
            (
                AdminAck {
                    ok: false,
                    messages,
                },
                None,
            )
        };
        let site = match Site::from_toml(toml_text, file_name) {
            Ok(s) => s,
            Err(ickon_proto::site::SiteError::Invalid { issues, file }) => {
                return refuse(
                    issues
                        .iter()
                        .map(|i| {
                            format!("{file}:{}:{}: {}: {}", i.line, i.column, i.field, i.message)
                        })
                        .collect(),
                );
            }
            Err(other) => return refuse(vec![other.to_string()]),
        };
        if site.name != self.site.name {
            return refuse(vec![format!(
                "site name {:?} differs from the running site {:?}: start a new central unit for another site",
                site.name, self.site.name
            )]);
        }
        let live: Vec<String> = site
            .cells
            .iter()
            .filter(|c| !self.any_cell_seen || self.cells.get(&c.id).is_some_and(|s| s.alive))
            .map(|c| c.id.clone())
            .collect();
        let active = if live.is_empty() {
            site.cells.iter().map(|c| c.id.clone()).collect()
        } else {
            live
        };
        let Some(version) = self.latest_schedule().version.checked_add(1) else {
            return refuse(vec![format!(
                "no schedule version left in epoch {}",
                self.epoch
            )]);
        };
        let effective = self.first_announceable_cycle(now);
        let schedule = match make_schedule(self.config.schedule, &site, &active, version, effective)
        {
            Ok(s) => Schedule {
                epoch: self.epoch,
                ..s
            },
            Err(e) => return refuse(vec![e.to_string()]),
        };
        for c in &site.cells {
            self.cells.entry(c.id.clone()).or_default();
        }
        self.cells.retain(|id, _| site.cell(id).is_some());
        self.robots
            .retain(|id, _| site.robots.iter().any(|r| &r.id == id));
        if let Some(c) = self.config.survey {
            // Other transmitters, or the same ones moved: start again.
            self.survey = Some(SurveyPublisher::new(&site, c));
        }
        self.site = site;
        self.table = None;
        self.site_toml = toml_text.to_string();
        self.site_version += 1;
        self.push_schedule(schedule.clone());
        (
            AdminAck {
                ok: true,
                messages: vec![format!(
                    "site {file_name} loaded as version {}; schedule v{version} from cycle {effective}",
                    self.site_version
                )],
            },
            Some(Output::Schedule(schedule)),
        )
    }
}

pub mod standby;

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

/// Whether `table` holds the transmitters of exactly `cells`.
fn same_cells(table: &SpacingTable, cells: &[String]) -> bool {
    let have: std::collections::BTreeSet<&String> = table.cells.iter().collect();
    have.len() == cells.len() && have.iter().all(|c| cells.contains(c))
}

#[cfg(test)]
mod tests;
