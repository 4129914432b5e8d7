//! What the admin CLI asks: status, coverage, pause, and reloading the
//! site.

use ickon_proto::msg::admin::{
    AdminAck, CoverageReport, RobotHealth, RobotPage, RobotsRequest, STATUS_ROBOTS, StatusReport,
    TransmitterStatus, TransmittersReport,
};
use ickon_proto::msg::control::Schedule;
use ickon_proto::site::Site;
use ickon_proto::time::Time;

use crate::survey_calibration::SurveyPublisher;

use super::{CentralCore, Output, make_schedule};

/// What computing the survey calibrations has cost so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct SurveyCost {
    publications: u64,
    total_us: f64,
    max_us: f64,
}

impl SurveyCost {
    /// The mean per publication, microseconds (0 before the first).
    fn mean_us(&self) -> f64 {
        if self.publications == 0 {
            0.0
        } else {
            self.total_us / self.publications as f64
        }
    }
}

impl CentralCore {
    /// The answer to `robots` with a request: a page of the robots in the
    /// state asked, by id or nearest first to a place, and the whole
    /// fleet's counts by state. A page beyond the last, a negative one or
    /// an unknown state is refused with the reason. Every robot's health
    /// is made once per request (the fleet's size, never its square).
    pub fn robots_page(&self, now: Time, request: &RobotsRequest) -> RobotPage {
        crate::robot_pages::page(
            self.robots
                .iter()
                .map(|(id, r)| self.robot_health(id, r, now)),
            request,
        )
    }

    /// One robot's health as the admin sees it.
    fn robot_health(&self, id: &str, r: &crate::health::RobotTracker, now: Time) -> RobotHealth {
        let check = self.survey.as_ref().map(|p| p.robot_check(id));
        RobotHealth {
            fixes_over_rate: self.survey_fix_rate.refused(id),
            survey_check: check.map_or("", |c| c.check.label()).to_string(),
            fixes_quarantined: check.map_or(0, |c| c.fixes_quarantined),
            survey_misfit_m: check.and_then(|c| c.misfit_m).unwrap_or(-1.0),
            survey_bound_m: check.and_then(|c| c.bound_m).unwrap_or(-1.0),
            ..r.health(id, now)
        }
    }

    /// The answer to `status`, `cells` and `sync`: [`Self::status`] with
    /// only the worst [`STATUS_ROBOTS`] robots listed (and the whole
    /// fleet's counts), so that an operator's console refreshing it costs
    /// the same at ten robots and at ten thousand, bar one pass over them.
    pub fn status_summary(&self, now: Time) -> StatusReport {
        self.status_listing(now, STATUS_ROBOTS)
    }

    /// The status with every robot (the viewers', the answer to `robots`
    /// without a request).
    pub fn status(&self, now: Time) -> StatusReport {
        self.status_listing(now, usize::MAX)
    }

    /// The status listing at most `listed` robots, the worst.
    fn status_listing(&self, now: Time, listed: usize) -> StatusReport {
        let (robots, robot_counts, robots_posed) = crate::robot_pages::worst(
            self.robots
                .iter()
                .map(|(id, r)| self.robot_health(id, r, now)),
            listed,
        );
        let schedule = self.schedule_for(self.last_cycle());
        StatusReport {
            site: self.site.name.clone(),
            cycle: self.last_cycle(),
            stamp: now,
            paused: self.paused,
            schedule_version: schedule.version,
            update_rate_hz: crate::schedule::update_rate_hz(schedule),
            cells: self.cells.iter().map(|(id, c)| c.health(id)).collect(),
            robots,
            robot_counts,
            robots_posed,
            epoch: self.epoch,
            foreign_control: self.foreign_control,
            active: self.standby.is_none(),
            survey_publications: self.survey_cost.publications,
            survey_publish_mean_us: self.survey_cost.mean_us(),
            survey_publish_max_us: self.survey_cost.max_us,
            speed_of_sound_m_s: self.published_speed().0,
            speed_of_sound_sigma_m_s: self.published_speed().1,
            site_speed_of_sound_m_s: self.site.speed_of_sound_m_s,
            transmitters_left_out: self
                .survey
                .as_ref()
                .map(|p| p.left_out().iter().copied().collect())
                .unwrap_or_default(),
        }
    }

    /// The site's cells, in its order.
    fn cell_ids(&self) -> Vec<String> {
        self.site.cells.iter().map(|c| c.id.clone()).collect()
    }

    /// The speed of sound published to the MSUs and its sigma, m/s
    /// (`(0, 0)`: none, the site's).
    fn published_speed(&self) -> (f64, f64) {
        self.survey
            .as_ref()
            .and_then(SurveyPublisher::published_speed)
            .map_or((0.0, 0.0), |s| (s.speed_m_s, s.sigma_m_s))
    }

    /// The answer to `transmitters`: every transmitter's health, from the
    /// fleet's fixes, and the air's speed of sound.
    pub fn transmitters(&self, now: Time) -> TransmittersReport {
        let (speed, sigma) = self.published_speed();
        let transmitters = match self.survey.as_ref() {
            None => Vec::new(),
            Some(p) => p
                .transmitters(now)
                .into_iter()
                .zip(&self.site.transmitters)
                .map(|(r, t)| TransmitterStatus {
                    tx_id: r.tx_id,
                    cell_id: t.cell.clone(),
                    condition: r.condition.label().to_string(),
                    left_out: p.left_out().contains(&r.tx_id),
                    evidence: crate::transmitter_health::TransmitterHealth::evidence(&r),
                    due: r.due,
                    heard_pct: r.heard_pct.unwrap_or(-1.0),
                    expected_pct: r.expected_pct.unwrap_or(-1.0),
                    rejected_pct: r.rejected_pct.unwrap_or(-1.0),
                    residuals_known: r.residual_mean_m.is_some(),
                    residual_mean_m: r.residual_mean_m.unwrap_or(0.0),
                    residual_std_m: r.residual_std_m.unwrap_or(0.0),
                    last_heard_s_ago: r.last_heard_s_ago.unwrap_or(-1.0),
                    offset_m: p
                        .published_offsets()
                        .and_then(|o| o.get(&r.tx_id).copied())
                        .unwrap_or([0.0; 3]),
                })
                .collect(),
        };
        TransmittersReport {
            site: self.site.name.clone(),
            stamp: now,
            learning: self.survey.is_some(),
            fixes_taken: self
                .survey
                .as_ref()
                .map_or(0, |p| p.calibration().fixes_taken()),
            speed_of_sound_m_s: speed,
            speed_of_sound_sigma_m_s: sigma,
            site_speed_of_sound_m_s: self.site.speed_of_sound_m_s,
            transmitters,
            air_sensors: self.air.report(now, &self.cell_ids()),
            air_sensor_speed_m_s: self
                .air
                .evidence(now, self.site.speed_of_sound_m_s)
                .map_or(0.0, |e| self.site.speed_of_sound_m_s * (1.0 + e.scale)),
        }
    }

    /// Notes that the step that computed and published a survey
    /// calibration took `took` (measured by the node around
    /// [`CentralCore::handle`]: the core reads no clock of its own).
    pub fn note_survey_cost(&mut self, took: std::time::Duration) {
        let us = took.as_secs_f64() * 1e6;
        let cost = &mut self.survey_cost;
        cost.publications += 1;
        cost.total_us += us;
        cost.max_us = cost.max_us.max(us);
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
        match parse_reloaded_site(toml_text, file_name) {
            Ok(site) => self.reload_site(site, toml_text, file_name, now),
            Err(refused) => (refused, None),
        }
    }

    /// [`reload`](Self::reload) with the file already parsed and validated
    /// by [`parse_reloaded_site`] (the node does that off its loop).
    pub fn reload_site(
        &mut self,
        site: Site,
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
        self.air
            .follow_cells(site.cells.iter().map(|c| c.id.as_str()));
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

/// Parses and validates a site file sent to `reload`: the costly part of a
/// reload (a site file may be [`ickon_proto::site::MAX_SITE_FILE_BYTES`]),
/// apart so that the node can run it off its loop. A bad file is refused
/// with every reason.
pub fn parse_reloaded_site(toml_text: &str, file_name: &str) -> Result<Site, AdminAck> {
    let refuse = |messages: Vec<String>| AdminAck {
        ok: false,
        messages,
    };
    match Site::from_toml(toml_text, file_name) {
        Ok(s) => Ok(s),
        Err(ickon_proto::site::SiteError::Invalid { issues, file }) => Err(refuse(
            issues
                .iter()
                .map(|i| format!("{file}:{}:{}: {}: {}", i.line, i.column, i.field, i.message))
                .collect(),
        )),
        Err(other) => Err(refuse(vec![other.to_string()])),
    }
}
