//! The central unit as a sans-IO state machine: fed with events and the
//! current master time, it answers which cycle triggers and schedules to
//! publish, and what to tell the admin CLI. The Zenoh node only moves bytes.
//!
//! Membership: the schedule includes the cells whose liveliness token is
//! present (before any cell has announced itself, every cell of the site, so
//! that cells starting a little late lose nothing). When the set of live
//! cells differs from the scheduled one, a new schedule version is made that
//! takes effect [`CentralConfig::switch_after_cycles`] cycles later, so that
//! every cell switches at the same cycle.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use ickon_proto::msg::admin::{AdminAck, CellHealth, RobotHealth, StatusReport};
use ickon_proto::msg::control::{
    Burst, CellStatus, ClockReply, CycleTrigger, Schedule, SiteInfo, TransmitterEntry,
};
use ickon_proto::msg::robot::RobotPose;
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};

use crate::schedule::{ScheduleError, compute_schedule};

/// Tuning of the central unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CentralConfig {
    /// How long before a cycle starts its trigger goes out (covers the network
    /// and lets the cells program their timers).
    pub trigger_lead: Duration,
    /// Delay from start-up to the first cycle.
    pub start_delay: Duration,
    /// A membership change takes effect this many cycles after it is noticed.
    pub switch_after_cycles: u64,
}

impl Default for CentralConfig {
    fn default() -> Self {
        Self {
            trigger_lead: Duration::from_millis(60),
            start_delay: Duration::from_millis(500),
            switch_after_cycles: 2,
        }
    }
}

/// What the node must publish.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// A cycle trigger on `central/cycle`.
    Trigger(CycleTrigger),
    /// A new schedule on `central/schedule`.
    Schedule(Schedule),
}

#[derive(Debug, Default, Clone)]
struct CellState {
    up: bool,
    status: Option<CellStatus>,
    fired: BTreeSet<u64>,
    last_cycle_fired: u64,
    cycles_fired: u64,
    cycles_missed: u64,
}

#[derive(Debug, Default, Clone)]
struct RobotState {
    up: bool,
    pose: Option<RobotPose>,
    fix_times: VecDeque<Time>,
}

/// Fixes per second are counted over this window.
const FIX_RATE_WINDOW: Duration = Duration::from_millis(2_000);
/// Fired cycles remembered per cell, to count missed ones.
const FIRED_MEMORY: usize = 64;

/// The central unit's state.
pub struct CentralCore {
    config: CentralConfig,
    site: Site,
    site_toml: String,
    site_version: u32,
    schedules: Vec<Schedule>,
    next_cycle: u64,
    next_start: Time,
    paused: bool,
    cells: BTreeMap<String, CellState>,
    robots: BTreeMap<String, RobotState>,
    any_cell_seen: bool,
}

impl CentralCore {
    /// A central unit serving `site` (whose file text is `site_toml`), starting at `now`.
    pub fn new(
        site: Site,
        site_toml: String,
        config: CentralConfig,
        now: Time,
    ) -> Result<Self, ScheduleError> {
        let all: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        let schedule = compute_schedule(&site, &all, 1, 0)?;
        let cells = all
            .iter()
            .map(|id| (id.clone(), CellState::default()))
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
            any_cell_seen: false,
        })
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
            transmitters: self
                .site
                .transmitters
                .iter()
                .map(|t| TransmitterEntry {
                    tx_id: t.id,
                    cell_id: t.cell.clone(),
                    x_m: t.position_m[0],
                    y_m: t.position_m[1],
                    z_m: t.position_m[2],
                })
                .collect(),
        }
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

    /// When the node should call [`tick`](Self::tick) next: the next trigger time.
    pub fn next_wake(&self) -> Time {
        self.next_start - self.config.trigger_lead
    }

    /// Emits every trigger due at `now` (one per cycle, never two for one cycle).
    pub fn tick(&mut self, now: Time) -> Vec<Output> {
        let mut out = Vec::new();
        while now >= self.next_wake() {
            let cycle = self.next_cycle;
            let schedule = self.schedule_for(cycle).clone();
            if !self.paused {
                out.push(Output::Trigger(CycleTrigger {
                    cycle,
                    start: self.next_start,
                    schedule_version: schedule.version,
                }));
                self.count_missed(cycle);
            }
            self.next_cycle += 1;
            self.next_start = self.next_start + schedule.cycle_period;
        }
        out.extend(self.reconcile_membership());
        out
    }

    /// Counts, for the cycle two before `cycle`, the scheduled cells that did not fire.
    fn count_missed(&mut self, cycle: u64) {
        let Some(checked) = cycle.checked_sub(2) else {
            return;
        };
        let active = self.schedule_for(checked).active_cells.clone();
        for id in active {
            if let Some(c) = self.cells.get_mut(&id) {
                if c.up && !c.fired.contains(&checked) {
                    c.cycles_missed += 1;
                }
            }
        }
    }

    /// A new schedule when the live cells differ from the scheduled ones.
    fn reconcile_membership(&mut self) -> Option<Output> {
        if !self.any_cell_seen {
            return None;
        }
        let live: Vec<String> = self
            .site
            .cells
            .iter()
            .filter(|c| self.cells.get(&c.id).is_some_and(|s| s.up))
            .map(|c| c.id.clone())
            .collect();
        if live.is_empty() || live == self.latest_schedule().active_cells {
            return None;
        }
        let version = self.latest_schedule().version + 1;
        let effective = self.next_cycle + self.config.switch_after_cycles;
        let schedule = compute_schedule(&self.site, &live, version, effective).ok()?;
        tracing::info!(
            "schedule v{version} from cycle {effective}: cells {}",
            live.join(", ")
        );
        self.schedules.push(schedule.clone());
        // Older schedules than the one in force for the next cycle are no longer needed.
        let in_force = self.schedule_for(self.next_cycle).version;
        self.schedules.retain(|s| s.version >= in_force);
        Some(Output::Schedule(schedule))
    }

    /// A cell's liveliness token appeared (`up`) or disappeared.
    pub fn cell_alive(&mut self, id: &str, up: bool) {
        if let Some(c) = self.cells.get_mut(id) {
            c.up = up;
            self.any_cell_seen |= up;
            tracing::info!("cell {id} is {}", if up { "up" } else { "down" });
        } else {
            tracing::warn!("liveliness of unknown cell {id:?} ignored");
        }
    }

    /// A cell's status report.
    pub fn on_cell_status(&mut self, status: CellStatus) {
        if let Some(c) = self.cells.get_mut(&status.cell_id) {
            c.status = Some(status);
        }
    }

    /// A burst report.
    pub fn on_burst(&mut self, burst: &Burst) {
        if let Some(c) = self.cells.get_mut(&burst.cell_id) {
            if c.fired.insert(burst.cycle) {
                c.cycles_fired += 1;
                c.last_cycle_fired = c.last_cycle_fired.max(burst.cycle);
                while c.fired.len() > FIRED_MEMORY {
                    c.fired.pop_first();
                }
            }
        }
    }

    /// A robot's liveliness token appeared or disappeared.
    pub fn robot_alive(&mut self, id: &str, up: bool) {
        self.robots.entry(id.to_string()).or_default().up = up;
    }

    /// A robot published a pose.
    pub fn on_pose(&mut self, id: &str, pose: RobotPose) {
        self.robots.entry(id.to_string()).or_default().pose = Some(pose);
    }

    /// A robot published a fix at `now`.
    pub fn on_fix(&mut self, id: &str, now: Time) {
        let r = self.robots.entry(id.to_string()).or_default();
        r.fix_times.push_back(now);
        while r
            .fix_times
            .front()
            .is_some_and(|t| now.since(*t) > FIX_RATE_WINDOW)
        {
            r.fix_times.pop_front();
        }
    }

    /// The reply to a clock request that arrived at `t2` and leaves at `t3`.
    pub fn clock_reply(t1: Time, t2: Time, t3: Time) -> ClockReply {
        ClockReply { t1, t2, t3 }
    }

    /// The answer to `status`, `cells`, `robots` and `sync`.
    pub fn status(&self, now: Time) -> StatusReport {
        let schedule = self.schedule_for(self.next_cycle);
        StatusReport {
            site: self.site.name.clone(),
            cycle: self.next_cycle.saturating_sub(1),
            stamp: now,
            paused: self.paused,
            schedule_version: schedule.version,
            update_rate_hz: crate::schedule::update_rate_hz(schedule),
            cells: self
                .cells
                .iter()
                .map(|(id, c)| CellHealth {
                    id: id.clone(),
                    up: c.up && schedule.active_cells.contains(id),
                    sync_error_ns: c.status.as_ref().map_or(0, |s| s.offset_sigma_ns),
                    offset_ns: c.status.as_ref().map_or(0, |s| s.offset_ns),
                    last_cycle_fired: c.last_cycle_fired,
                    cycles_fired: c.cycles_fired,
                    cycles_missed: c.cycles_missed,
                })
                .collect(),
            robots: self
                .robots
                .iter()
                .map(|(id, r)| {
                    let recent = r
                        .fix_times
                        .iter()
                        .filter(|t| now.since(**t) <= FIX_RATE_WINDOW)
                        .count();
                    RobotHealth {
                        id: id.clone(),
                        up: r.up,
                        fixes_per_s: recent as f64 / FIX_RATE_WINDOW.as_secs_f64(),
                        estimator: r
                            .pose
                            .as_ref()
                            .map_or(String::new(), |p| p.estimator.clone()),
                        pose_valid: r.pose.is_some(),
                        x_m: r.pose.as_ref().map_or(0.0, |p| p.x_m),
                        y_m: r.pose.as_ref().map_or(0.0, |p| p.y_m),
                        theta_rad: r.pose.as_ref().map_or(0.0, |p| p.theta_rad),
                    }
                })
                .collect(),
        }
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
    pub fn reload(&mut self, toml_text: &str, file_name: &str) -> (AdminAck, Option<Output>) {
        let site = match Site::from_toml(toml_text, file_name) {
            Ok(s) => s,
            Err(e) => {
                let messages = match e {
                    ickon_proto::site::SiteError::Invalid { issues, file } => issues
                        .iter()
                        .map(|i| {
                            format!("{file}:{}:{}: {}: {}", i.line, i.column, i.field, i.message)
                        })
                        .collect(),
                    other => vec![other.to_string()],
                };
                return (
                    AdminAck {
                        ok: false,
                        messages,
                    },
                    None,
                );
            }
        };
        if site.name != self.site.name {
            return (
                AdminAck {
                    ok: false,
                    messages: vec![format!(
                        "site name {:?} differs from the running site {:?}: start a new central unit for another site",
                        site.name, self.site.name
                    )],
                },
                None,
            );
        }
        let live: Vec<String> = site
            .cells
            .iter()
            .filter(|c| !self.any_cell_seen || self.cells.get(&c.id).is_some_and(|s| s.up))
            .map(|c| c.id.clone())
            .collect();
        let version = self.latest_schedule().version + 1;
        let effective = self.next_cycle + self.config.switch_after_cycles;
        let active = if live.is_empty() {
            site.cells.iter().map(|c| c.id.clone()).collect()
        } else {
            live
        };
        let schedule = match compute_schedule(&site, &active, version, effective) {
            Ok(s) => s,
            Err(e) => {
                return (
                    AdminAck {
                        ok: false,
                        messages: vec![e.to_string()],
                    },
                    None,
                );
            }
        };
        for c in &site.cells {
            self.cells.entry(c.id.clone()).or_default();
        }
        self.cells.retain(|id, _| site.cell(id).is_some());
        self.site = site;
        self.site_toml = toml_text.to_string();
        self.site_version += 1;
        self.schedules.push(schedule.clone());
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

#[cfg(test)]
mod tests {
    use super::*;

    fn core() -> CentralCore {
        let site = Site::default_site();
        CentralCore::new(site, String::new(), CentralConfig::default(), Time(0)).unwrap()
    }

    fn triggers(out: &[Output]) -> Vec<CycleTrigger> {
        out.iter()
            .filter_map(|o| match o {
                Output::Trigger(t) => Some(*t),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn triggers_go_out_ahead_of_each_cycle_once() {
        let mut c = core();
        let lead = CentralConfig::default().trigger_lead;
        assert!(triggers(&c.tick(Time(0))).is_empty());
        let first = c.next_wake();
        let t = triggers(&c.tick(first));
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].cycle, 0);
        assert_eq!(t[0].start, first + lead);
        assert!(triggers(&c.tick(first)).is_empty(), "no second trigger");
        let period = c.latest_schedule().cycle_period;
        let t = triggers(&c.tick(first + period));
        assert_eq!(t[0].cycle, 1);
        assert_eq!(t[0].start, first + lead + period);
    }

    #[test]
    fn a_cell_that_goes_down_leaves_the_schedule_at_a_named_cycle() {
        let mut c = core();
        for id in ["c1", "c2", "c3", "c4"] {
            c.cell_alive(id, true);
        }
        let mut now = c.next_wake();
        c.tick(now);
        c.cell_alive("c2", false);
        let period = c.latest_schedule().cycle_period;
        now = now + period;
        let out = c.tick(now);
        let new = out
            .iter()
            .find_map(|o| match o {
                Output::Schedule(s) => Some(s.clone()),
                _ => None,
            })
            .expect("a new schedule");
        assert_eq!(new.version, 2);
        assert!(!new.active_cells.contains(&"c2".to_string()));
        assert_eq!(
            new.effective_cycle,
            2 + CentralConfig::default().switch_after_cycles
        );
        // Triggers before the switch keep version 1, after it version 2.
        let mut versions = Vec::new();
        for _ in 0..5 {
            now = now + period;
            versions.extend(
                triggers(&c.tick(now))
                    .iter()
                    .map(|t| (t.cycle, t.schedule_version)),
            );
        }
        for (cycle, v) in versions {
            assert_eq!(
                v,
                if cycle >= new.effective_cycle { 2 } else { 1 },
                "cycle {cycle}"
            );
        }
        let status = c.status(now);
        assert!(!status.cells.iter().find(|h| h.id == "c2").unwrap().up);
        // Back up: re-admitted with a newer version.
        c.cell_alive("c2", true);
        let out = c.tick(now + period);
        assert!(out.iter().any(
            |o| matches!(o, Output::Schedule(s) if s.version == 3 && s.active_cells.len() == 4)
        ));
    }

    #[test]
    fn missed_cycles_are_counted_for_live_cells_that_did_not_fire() {
        let mut c = core();
        c.cell_alive("c1", true);
        let mut now = c.next_wake();
        for cycle in 0..6u64 {
            c.tick(now);
            if cycle % 2 == 0 {
                c.on_burst(&Burst {
                    cell_id: "c1".into(),
                    tx_id: 11,
                    cycle,
                    scheduled: Time(0),
                    actual: Time(0),
                });
            }
            now = now + c.schedule_for(cycle).cycle_period;
        }
        let h = c
            .status(now)
            .cells
            .into_iter()
            .find(|h| h.id == "c1")
            .unwrap();
        assert_eq!(h.cycles_fired, 3);
        assert!(h.cycles_missed >= 1, "{h:?}");
    }

    #[test]
    fn pause_stops_triggers_and_resume_restarts_them() {
        let mut c = core();
        assert!(c.set_paused(true).ok);
        let now = c.next_wake();
        assert!(triggers(&c.tick(now)).is_empty());
        c.set_paused(false);
        let period = c.latest_schedule().cycle_period;
        assert_eq!(triggers(&c.tick(now + period)).len(), 1);
    }

    #[test]
    fn a_bad_reload_is_refused_and_the_site_stays() {
        let mut c = core();
        let bad = ickon_proto::site::DEFAULT_SITE_TOML.replacen("id = 12\n", "id = 11\n", 1);
        let (ack, out) = c.reload(&bad, "bad.toml");
        assert!(!ack.ok);
        assert!(ack.messages[0].contains("bad.toml:"), "{:?}", ack.messages);
        assert!(out.is_none());
        assert_eq!(c.site_info().version, 1);
        let (ack, out) = c.reload(ickon_proto::site::DEFAULT_SITE_TOML, "lab.toml");
        assert!(ack.ok, "{:?}", ack.messages);
        assert!(matches!(out, Some(Output::Schedule(s)) if s.version == 2));
        assert_eq!(c.site_info().version, 2);
    }

    #[test]
    fn fixes_per_second_count_a_sliding_window() {
        let mut c = core();
        for k in 0..10 {
            c.on_fix("r1", Time(k * 200_000_000));
        }
        let s = c.status(Time(1_800_000_000));
        let r = &s.robots[0];
        assert!((r.fixes_per_s - 5.0).abs() < 0.6, "{}", r.fixes_per_s);
    }
}
