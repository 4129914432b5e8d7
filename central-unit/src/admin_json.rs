//! The JSON documents of the admin answers, shared by `ickon admin --json`
//! and the web map's `/api/*` endpoints so that both say the same thing in
//! the same shape.
//!
//! JSON uses the units of the wire messages converted for people where a
//! name says so (`sync_error_us`, `offset_us`, `drift_ppm`, `period_ms`);
//! a figure that is not known yet is `null`, never a made-up zero.

use ickon_proto::msg::admin::{
    BoardAirStatus, CellHealth, CoverageReport, RobotCounts, RobotHealth, RobotPage, StatusReport,
    TransmittersReport,
};
use ickon_proto::msg::control::Schedule;
use serde::Serialize;

/// One cell in JSON.
#[derive(Debug, Clone, Serialize)]
pub struct CellJson {
    /// Cell id.
    pub id: String,
    /// `up` (due to fire in the last cycle), `idle` (alive, not due: no
    /// robot near it under occupancy-aware firing) or `down` (its token
    /// or its reports stopped, or it did not fire when due).
    pub state: &'static str,
    /// The last triggered cycle when `state` last changed.
    pub state_since_cycle: u64,
    /// Largest |actual - scheduled| of its recent bursts, microseconds.
    pub sync_error_us: Option<f64>,
    /// RMS of the same residuals, microseconds.
    pub sync_error_rms_us: Option<f64>,
    /// Bursts behind the two figures above.
    pub residual_samples: u32,
    /// The cell's own one-sigma estimate, microseconds.
    pub sync_sigma_us: f64,
    /// Estimated offset master minus cell clock, microseconds.
    pub offset_us: f64,
    /// Estimated drift of the cell clock, ppm.
    pub drift_ppm: f64,
    /// Cycles fired since the central unit started.
    pub cycles_fired: u64,
    /// Last cycle it fired.
    pub last_cycle_fired: u64,
    /// Cycles it was due to fire in and did not.
    pub cycles_missed: u64,
    /// Slots it skipped (its own count).
    pub slots_skipped: u64,
    /// Control messages it refused (its own count).
    pub inputs_refused: u64,
    /// Its transmitter device in plain words (empty: the simulated driver).
    pub device: String,
}

impl From<&CellHealth> for CellJson {
    fn from(c: &CellHealth) -> Self {
        let measured = c.residual_samples > 0;
        Self {
            id: c.id.clone(),
            state: c.state.name(),
            state_since_cycle: c.state_since_cycle,
            sync_error_us: measured.then_some(c.residual_max_ns as f64 / 1e3),
            sync_error_rms_us: measured.then_some(c.residual_rms_ns as f64 / 1e3),
            residual_samples: c.residual_samples,
            sync_sigma_us: c.sync_sigma_ns as f64 / 1e3,
            offset_us: c.offset_ns as f64 / 1e3,
            drift_ppm: c.drift_ppb as f64 / 1e3,
            cycles_fired: c.cycles_fired,
            last_cycle_fired: c.last_cycle_fired,
            cycles_missed: c.cycles_missed,
            slots_skipped: c.slots_skipped,
            inputs_refused: c.inputs_refused,
            device: c.device.clone(),
        }
    }
}

/// A robot's last pose in JSON.
#[derive(Debug, Clone, Serialize)]
pub struct PoseJson {
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub theta_rad: f64,
}

/// One robot in JSON.
#[derive(Debug, Clone, Serialize)]
pub struct RobotJson {
    /// Robot id.
    pub id: String,
    /// `up`, `stale` (live, but its poses stopped or its MSU says an input
    /// stalled) or `down`.
    pub state: &'static str,
    /// Why it is stale, when it is.
    pub stale: Option<String>,
    /// Fixes per second over the last few seconds.
    pub fixes_per_s: f64,
    /// Its fixes kept out of the survey calibration as over its rate.
    pub fixes_over_rate: u64,
    /// Where it stands with the fleet's check of its fixes: `checking`,
    /// `agrees`, `quarantined` or `unchecked: no other robot to compare`
    /// (`None`: the central unit learns no survey calibration).
    pub survey_check: Option<String>,
    /// Its fixes kept out of the survey calibration while quarantined.
    pub fixes_quarantined: u64,
    /// The median misfit of its recent fixes against the fleet's
    /// calibration, mm (`None`: not checked yet).
    pub survey_misfit_mm: Option<f64>,
    /// The misfit beyond which it is quarantined (while quarantined: within
    /// which it is released), mm (`None`: nothing to compare with).
    pub survey_bound_mm: Option<f64>,
    /// Estimator named in its last pose.
    pub estimator: Option<String>,
    /// Its last pose, if any.
    pub pose: Option<PoseJson>,
    /// Its receivers (a receiver board, a ranging kit) in plain words, as
    /// its agent reported them; absent for the simulated world's.
    pub receivers: Option<String>,
    /// Its summaries the central unit dropped (floods, repeats, stamps
    /// from the future, another sender under its id).
    pub summaries_dropped: u64,
}

/// `robots --json`, a page of them.
#[derive(Debug, Clone, Serialize)]
pub struct RobotPageJson {
    /// The page, from 0.
    pub page: i64,
    /// Pages the matching robots fill.
    pub pages: u64,
    /// Robots matching the request, on every page.
    pub matching: u64,
    /// The whole fleet by state.
    pub counts: RobotCountsJson,
    /// The robots of the page.
    pub robots: Vec<RobotJson>,
}

/// The fleet by state.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RobotCountsJson {
    /// Up.
    pub up: u64,
    /// Stale.
    pub stale: u64,
    /// Down.
    pub down: u64,
}

impl From<&RobotPage> for RobotPageJson {
    fn from(p: &RobotPage) -> Self {
        Self {
            page: p.page,
            pages: p.pages,
            matching: p.matching,
            counts: RobotCountsJson {
                up: p.counts.up,
                stale: p.counts.stale,
                down: p.counts.down,
            },
            robots: p.robots.iter().map(RobotJson::from).collect(),
        }
    }
}

impl From<&RobotHealth> for RobotJson {
    fn from(r: &RobotHealth) -> Self {
        Self {
            id: r.id.clone(),
            state: r.state(),
            stale: (!r.stale.is_empty()).then(|| r.stale.clone()),
            fixes_per_s: r.fixes_per_s,
            fixes_over_rate: r.fixes_over_rate,
            survey_check: (!r.survey_check.is_empty()).then(|| r.survey_check.clone()),
            fixes_quarantined: r.fixes_quarantined,
            survey_misfit_mm: (r.survey_misfit_m >= 0.0).then(|| round_mm(r.survey_misfit_m)),
            survey_bound_mm: (r.survey_bound_m >= 0.0).then(|| round_mm(r.survey_bound_m)),
            estimator: (!r.estimator.is_empty()).then(|| r.estimator.clone()),
            pose: r.pose_valid.then_some(PoseJson {
                x_m: r.x_m,
                y_m: r.y_m,
                theta_rad: r.theta_rad,
            }),
            receivers: (!r.receivers.is_empty()).then(|| r.receivers.clone()),
            summaries_dropped: r.summaries_dropped,
        }
    }
}

/// The speed of sound the robots solve with, and whether it is learnt: the
/// published one (`published_m_s`, 0 when none is) or else the site
/// file's.
pub fn speed_in_use(published_m_s: f64, site_m_s: f64) -> (f64, bool) {
    if published_m_s > 0.0 {
        (published_m_s, true)
    } else {
        (site_m_s, false)
    }
}

/// Metres as millimetres to a tenth.
fn round_mm(m: f64) -> f64 {
    (m * 10_000.0).round() / 10.0
}

/// `status --json` (and `cells`, `robots`, `sync`, which leave a part out).
#[derive(Debug, Clone, Serialize)]
pub struct StatusJson {
    /// Site name.
    pub site: String,
    /// The answering central unit's epoch (its start, master time, ns).
    pub epoch: u64,
    /// Control messages on its keys it did not send, since it started.
    pub foreign_control: u64,
    /// Whether the answering central unit is the active one (`false`: a standby).
    pub active: bool,
    /// Last cycle triggered.
    pub cycle: u64,
    /// Whether cycle triggers are paused.
    pub paused: bool,
    /// Version of the schedule in force.
    pub schedule_version: u32,
    /// Cycles per second of the schedule in force.
    pub update_rate_hz: f64,
    /// Survey calibrations computed and published since it started.
    pub survey_publications: u64,
    /// How long the step that computed and published one took,
    /// microseconds: mean and longest (`null` before the first).
    pub survey_publish_mean_us: Option<f64>,
    /// See `survey_publish_mean_us`.
    pub survey_publish_max_us: Option<f64>,
    /// The speed of sound the MSUs solve with, m/s: the one learnt from the
    /// fleet's fixes, or the site file's (`speed_of_sound_learnt` says which).
    pub speed_of_sound_m_s: f64,
    /// Its one-sigma uncertainty, m/s (`null`: the site file's, not learnt).
    pub speed_of_sound_sigma_m_s: Option<f64>,
    /// Whether `speed_of_sound_m_s` is learnt.
    pub speed_of_sound_learnt: bool,
    /// The site file's speed of sound, m/s.
    pub site_speed_of_sound_m_s: f64,
    /// Transmitters left out of the fixes (dead, weak or moved).
    pub transmitters_left_out: Vec<u32>,
    /// Every cell, when asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<Vec<CellJson>>,
    /// The robots listed (`admin status`: the worst of a large fleet),
    /// when asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robots: Option<Vec<RobotJson>>,
    /// Every robot seen, by state: `up`, `stale`, `down`.
    pub robot_counts: RobotCounts,
    /// Of those, the robots with a pose.
    pub robots_posed: u64,
}

impl StatusJson {
    /// The document of `s`, with its cells and/or robots.
    pub fn new(s: &StatusReport, cells: bool, robots: bool) -> Self {
        let (speed, learnt) = speed_in_use(s.speed_of_sound_m_s, s.site_speed_of_sound_m_s);
        Self {
            site: s.site.clone(),
            epoch: s.epoch,
            foreign_control: s.foreign_control,
            active: s.active,
            cycle: s.cycle,
            paused: s.paused,
            schedule_version: s.schedule_version,
            update_rate_hz: s.update_rate_hz,
            survey_publications: s.survey_publications,
            survey_publish_mean_us: (s.survey_publications > 0).then_some(s.survey_publish_mean_us),
            survey_publish_max_us: (s.survey_publications > 0).then_some(s.survey_publish_max_us),
            speed_of_sound_m_s: speed,
            speed_of_sound_sigma_m_s: learnt.then_some(s.speed_of_sound_sigma_m_s),
            speed_of_sound_learnt: learnt,
            site_speed_of_sound_m_s: s.site_speed_of_sound_m_s,
            transmitters_left_out: s.transmitters_left_out.clone(),
            cells: cells.then(|| s.cells.iter().map(CellJson::from).collect()),
            robots: robots.then(|| s.robots.iter().map(RobotJson::from).collect()),
            robot_counts: s.robot_counts,
            robots_posed: s.robots_posed,
        }
    }
}

/// `schedule --json`.
#[derive(Debug, Clone, Serialize)]
pub struct ScheduleJson {
    /// Schedule version.
    pub version: u32,
    /// First cycle it is used in.
    pub effective_cycle: u64,
    /// Cycle period, milliseconds.
    pub period_ms: f64,
    /// Slot length, milliseconds.
    pub slot_ms: f64,
    /// Cycles per second.
    pub update_rate_hz: f64,
    /// Cells that fire.
    pub active_cells: Vec<String>,
    /// Every emission of a cycle.
    pub emissions: Vec<EmissionJson>,
}

/// One emission of a schedule in JSON.
#[derive(Debug, Clone, Serialize)]
pub struct EmissionJson {
    /// Transmitter id.
    pub tx_id: u32,
    /// Its cell.
    pub cell_id: String,
    /// Its slot.
    pub slot: u32,
    /// Its offset from the cycle start, milliseconds.
    pub offset_ms: f64,
}

impl From<&Schedule> for ScheduleJson {
    fn from(s: &Schedule) -> Self {
        let ms = |d: ickon_proto::time::Duration| d.as_secs_f64() * 1e3;
        Self {
            version: s.version,
            effective_cycle: s.effective_cycle,
            period_ms: ms(s.cycle_period),
            slot_ms: ms(s.slot_length),
            update_rate_hz: crate::schedule::update_rate_hz(s),
            active_cells: s.active_cells.clone(),
            emissions: s
                .emissions
                .iter()
                .map(|e| EmissionJson {
                    tx_id: e.tx_id,
                    cell_id: e.cell_id.clone(),
                    slot: e.slot,
                    offset_ms: ms(e.offset),
                })
                .collect(),
        }
    }
}

/// Figures of a coverage grid over the points on the floor.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CoverageSummary {
    /// Grid points on the floor.
    pub floor_points: usize,
    /// Of those, points where a 2D fix is possible (HDOP > 0).
    pub fix_points: usize,
    /// `fix_points / floor_points`.
    pub fix_share: f64,
    /// Fewest transmitters heard at a floor point.
    pub visible_min: Option<u32>,
    /// Median HDOP where a fix is possible.
    pub hdop_median: Option<f64>,
    /// 95th percentile of the HDOP where a fix is possible.
    pub hdop_p95: Option<f64>,
    /// Largest HDOP where a fix is possible.
    pub hdop_max: Option<f64>,
}

/// Summarises a coverage grid.
pub fn coverage_summary(r: &CoverageReport) -> CoverageSummary {
    let floor: Vec<usize> = (0..r.on_floor.len()).filter(|&i| r.on_floor[i]).collect();
    let mut hdops: Vec<f64> = floor
        .iter()
        .filter_map(|&i| r.hdop.get(i).copied())
        .filter(|&h| h > 0.0)
        .collect();
    hdops.sort_by(f64::total_cmp);
    let rank = |p: f64| -> Option<f64> {
        let n = hdops.len();
        (n > 0).then(|| hdops[(((p / 100.0) * n as f64).ceil() as usize).clamp(1, n) - 1])
    };
    CoverageSummary {
        floor_points: floor.len(),
        fix_points: hdops.len(),
        fix_share: if floor.is_empty() {
            0.0
        } else {
            hdops.len() as f64 / floor.len() as f64
        },
        visible_min: floor
            .iter()
            .filter_map(|&i| r.visible.get(i).copied())
            .min(),
        hdop_median: rank(50.0),
        hdop_p95: rank(95.0),
        hdop_max: hdops.last().copied(),
    }
}

/// `coverage --json`.
#[derive(Debug, Serialize)]
pub struct CoverageJson<'a> {
    /// Version of the schedule whose transmitters were counted.
    pub schedule_version: u32,
    /// Grid spacing, metres.
    pub resolution_m: f64,
    /// Receiver height, metres.
    pub height_m: f64,
    /// x of the first grid point, metres.
    pub origin_x_m: f64,
    /// y of the first grid point, metres.
    pub origin_y_m: f64,
    /// Columns (along x).
    pub columns: u32,
    /// Rows (along y).
    pub rows: u32,
    /// Figures over the floor.
    pub summary: CoverageSummary,
    /// Whether each point is on the floor (row-major from the lower left).
    pub on_floor: &'a [bool],
    /// Transmitters in line of sight at each point.
    pub visible: &'a [u32],
    /// HDOP at each point (0: no fix).
    pub hdop: &'a [f64],
}

impl<'a> From<&'a CoverageReport> for CoverageJson<'a> {
    fn from(r: &'a CoverageReport) -> Self {
        Self {
            schedule_version: r.schedule_version,
            resolution_m: r.resolution_m,
            height_m: r.height_m,
            origin_x_m: r.origin_x_m,
            origin_y_m: r.origin_y_m,
            columns: r.columns,
            rows: r.rows,
            summary: coverage_summary(r),
            on_floor: &r.on_floor,
            visible: &r.visible,
            hdop: &r.hdop,
        }
    }
}

/// One transmitter in `transmitters --json` and `/api/transmitters`.
#[derive(Debug, Clone, Serialize)]
pub struct TransmitterJson {
    /// Transmitter id.
    pub id: u32,
    /// Its cell.
    pub cell: String,
    /// `unknown`, `healthy`, `dead`, `weak` or `moved`.
    pub condition: String,
    /// Whether its arrivals are left out of the fixes.
    pub left_out: bool,
    /// The evidence behind the condition, in words.
    pub evidence: String,
    /// Recent fixes a robot was near it in.
    pub due: f64,
    /// Share of them it was heard in, percent.
    pub heard_pct: Option<f64>,
    /// Share its cell's others were heard in from the same fixes, percent.
    pub expected_pct: Option<f64>,
    /// Share of its heard arrivals the robots rejected, percent.
    pub rejected_pct: Option<f64>,
    /// Mean of its residuals in the fixes that used it, mm.
    pub residual_mean_mm: Option<f64>,
    /// Their standard deviation, mm.
    pub residual_std_mm: Option<f64>,
    /// Seconds since a robot last heard it.
    pub last_heard_s_ago: Option<f64>,
    /// What the survey calibration adds to its surveyed position, mm.
    pub offset_mm: [f64; 3],
}

/// `transmitters --json` and `/api/transmitters`.
#[derive(Debug, Clone, Serialize)]
pub struct TransmittersJson {
    /// Site name.
    pub site: String,
    /// Whether the central unit learns from the fleet's fixes at all.
    pub learning: bool,
    /// Fixes of the fleet behind the calibration.
    pub fixes_taken: u64,
    /// The speed of sound the MSUs solve with, m/s.
    pub speed_of_sound_m_s: f64,
    /// Its one-sigma uncertainty, m/s (`null`: the site file's).
    pub speed_of_sound_sigma_m_s: Option<f64>,
    /// Whether `speed_of_sound_m_s` is learnt.
    pub speed_of_sound_learnt: bool,
    /// The site file's speed of sound, m/s.
    pub site_speed_of_sound_m_s: f64,
    /// Every transmitter, in the site's order.
    pub transmitters: Vec<TransmitterJson>,
    /// The speed of sound the cell boards' fresh air temperatures say, m/s
    /// (`null`: none fresh).
    pub air_sensor_speed_m_s: Option<f64>,
    /// Every cell board's air temperature sensor, in the site's order.
    pub air_sensors: Vec<AirSensorJson>,
}

/// One cell board's air temperature sensor in `transmitters --json` and
/// `/api/transmitters`.
#[derive(Debug, Clone, Serialize)]
pub struct AirSensorJson {
    /// The cell.
    pub cell: String,
    /// `no sensor`, `used`, `not used` or `stuck`.
    pub state: String,
    /// The last accepted reading, degrees Celsius.
    pub temperature_c: Option<f64>,
    /// Seconds since it came.
    pub accepted_s_ago: Option<f64>,
    /// Readings accepted.
    pub accepted: u64,
    /// Readings refused: not a number, outside -40..85 C, stuck, jumping.
    pub refused: AirRefusedJson,
}

/// Refused readings of one board's sensor, by reason.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct AirRefusedJson {
    /// Not a number (no valid reading).
    pub not_a_number: u64,
    /// Outside -40..85 C.
    pub out_of_range: u64,
    /// The same value too many readings in a row.
    pub stuck: u64,
    /// More than 20 C in a second from the last accepted.
    pub jump: u64,
}

impl AirSensorJson {
    /// Whether the board refused any reading.
    pub fn refused_any(&self) -> bool {
        let r = self.refused;
        r.not_a_number + r.out_of_range + r.stuck + r.jump > 0
    }
}

impl From<&BoardAirStatus> for AirSensorJson {
    fn from(b: &BoardAirStatus) -> Self {
        Self {
            cell: b.cell_id.clone(),
            state: b.state.clone(),
            temperature_c: b.temperature_c.is_finite().then_some(b.temperature_c),
            accepted_s_ago: (b.accepted_s_ago >= 0.0).then_some(b.accepted_s_ago),
            accepted: b.accepted,
            refused: AirRefusedJson {
                not_a_number: b.refused_not_a_number,
                out_of_range: b.refused_out_of_range,
                stuck: b.refused_stuck,
                jump: b.refused_jump,
            },
        }
    }
}

impl From<&TransmittersReport> for TransmittersJson {
    fn from(r: &TransmittersReport) -> Self {
        let known = |v: f64| (v >= 0.0).then_some(v);
        let (speed, learnt) = speed_in_use(r.speed_of_sound_m_s, r.site_speed_of_sound_m_s);
        Self {
            site: r.site.clone(),
            learning: r.learning,
            fixes_taken: r.fixes_taken,
            speed_of_sound_m_s: speed,
            speed_of_sound_sigma_m_s: learnt.then_some(r.speed_of_sound_sigma_m_s),
            speed_of_sound_learnt: learnt,
            site_speed_of_sound_m_s: r.site_speed_of_sound_m_s,
            transmitters: r
                .transmitters
                .iter()
                .map(|t| TransmitterJson {
                    id: t.tx_id,
                    cell: t.cell_id.clone(),
                    condition: t.condition.clone(),
                    left_out: t.left_out,
                    evidence: t.evidence.clone(),
                    due: (t.due * 10.0).round() / 10.0,
                    heard_pct: known(t.heard_pct),
                    expected_pct: known(t.expected_pct),
                    rejected_pct: known(t.rejected_pct),
                    residual_mean_mm: t.residuals_known.then(|| round_mm(t.residual_mean_m)),
                    residual_std_mm: t.residuals_known.then(|| round_mm(t.residual_std_m)),
                    last_heard_s_ago: known(t.last_heard_s_ago),
                    offset_mm: t.offset_m.map(round_mm),
                })
                .collect(),
            air_sensor_speed_m_s: (r.air_sensor_speed_m_s > 0.0).then_some(r.air_sensor_speed_m_s),
            air_sensors: r.air_sensors.iter().map(AirSensorJson::from).collect(),
        }
    }
}
