//! Admin queryables under `central/admin/<command>`.
//!
//! Queries carry no payload except `reload`, which carries a
//! [`ReloadRequest`], and `coverage`, which may carry a [`CoverageRequest`].
//! `status`, `cells`, `robots` and `sync` answer a [`StatusReport`];
//! `schedule` answers a [`Schedule`](crate::msg::control::Schedule);
//! `coverage` a [`CoverageReport`]; `transmitters` a
//! [`TransmittersReport`]; `links` a [`LinksReport`]; `pause`, `resume`
//! and `reload` an [`AdminAck`].

use serde::{Deserialize, Serialize};

use crate::time::Time;

/// What a cell is doing, as the central unit sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum CellState {
    /// Not heard from: its liveliness token is absent, its reports
    /// stopped, or it did not fire in the cycles it was due to fire.
    #[default]
    Down,
    /// Alive, in the schedule, and due to fire in the last triggered cycle.
    Up,
    /// Alive and in the schedule, but the last triggered cycle did not ask
    /// it to fire (occupancy-aware firing: no robot near it). Healthy.
    Idle,
}

impl CellState {
    /// Its name in the admin's text and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Self::Down => "down",
            Self::Up => "up",
            Self::Idle => "idle",
        }
    }

    /// Whether the cell is alive and working (`up` or `idle`).
    pub fn alive(self) -> bool {
        self != Self::Down
    }
}

/// The answer to `links`: each node's link to its Zenoh router as the node
/// last reported it ([`RouterLink`](crate::msg::control::RouterLink)), in
/// id order. An answer of its own, not fields of [`StatusReport`], so that
/// an admin and a central unit of either version still read each other's
/// status; a central unit that does not know `links` does not answer it.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct LinksReport {
    /// The cells that reported their link.
    pub cells: Vec<crate::msg::control::RouterLink>,
    /// The robots that reported their link.
    pub robots: Vec<crate::msg::control::RouterLink>,
}

/// Health of one cell as the central unit sees it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellHealth {
    /// Cell id.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub id: String,
    /// Whether it is up, idle or down.
    pub state: CellState,
    /// The last triggered cycle when `state` last changed (0: never changed).
    pub state_since_cycle: u64,
    /// The cell's own estimate of its sync uncertainty (one sigma), nanoseconds.
    pub sync_sigma_ns: i64,
    /// Estimated offset master minus local clock, nanoseconds.
    pub offset_ns: i64,
    /// Estimated drift of the cell clock against the master, parts per billion.
    pub drift_ppb: i64,
    /// Bursts behind the residual figures below (0: none measured yet).
    pub residual_samples: u32,
    /// Largest |actual - scheduled| emission time of the recent bursts,
    /// nanoseconds: the residual sync error against the true time base.
    pub residual_max_ns: i64,
    /// Root mean square of the same residuals, nanoseconds.
    pub residual_rms_ns: i64,
    /// Last cycle it reported firing.
    pub last_cycle_fired: u64,
    /// Cycles fired since the central unit started.
    pub cycles_fired: u64,
    /// Cycles in which it was due to fire (the trigger named one of its
    /// transmitters) and did not.
    pub cycles_missed: u64,
    /// Slots the cell skipped because their trigger came too late (its own count).
    pub slots_skipped: u64,
    /// Control messages the cell refused (its own count, see
    /// [`CellStatus::inputs_refused`](crate::msg::control::CellStatus::inputs_refused)).
    pub inputs_refused: u64,
    /// Its transmitter device in plain words (its own report, see
    /// [`CellStatus::device`](crate::msg::control::CellStatus::device));
    /// empty for the simulated driver.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub device: String,
}

/// Health of one robot as the central unit sees it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotHealth {
    /// Robot id.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub id: String,
    /// Whether its liveliness token is present.
    pub up: bool,
    /// Fixes per second over the last few seconds.
    pub fixes_per_s: f64,
    /// Estimator named in its last pose.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub estimator: String,
    /// Whether a pose was received.
    pub pose_valid: bool,
    /// Last pose, metres.
    pub x_m: f64,
    /// Last pose, metres.
    pub y_m: f64,
    /// Last pose, radians.
    pub theta_rad: f64,
    /// Why the robot is stale, in plain words (no pose for a while, or its
    /// MSU says an input stalled); empty when it is not.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub stale: String,
    /// Its fixes kept out of the survey calibration because it sent more
    /// than its share (about one a cycle), since the central unit started.
    pub fixes_over_rate: u64,
    /// Where it stands with the fleet's check of its fixes before they
    /// teach the survey calibration: `checking`, `agrees`, `quarantined`,
    /// `unchecked: no other robot to compare`; empty when the central unit
    /// learns no calibration.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub survey_check: String,
    /// Its fixes kept out of the survey calibration while quarantined,
    /// since the central unit started (or its site was reloaded).
    pub fixes_quarantined: u64,
    /// The median misfit of its recent fixes against the fleet's
    /// calibration, metres (negative: not checked yet).
    pub survey_misfit_m: f64,
    /// The misfit beyond which it is quarantined (while quarantined: within
    /// which it is released), metres (negative: no bound, nothing to
    /// compare with).
    pub survey_bound_m: f64,
    /// Its receivers (a receiver board, a ranging kit) in plain words, as
    /// its agent last reported them; empty for the simulated world's.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub receivers: String,
    /// Its summaries the central unit dropped (floods, repeats, stamps
    /// from the future, another sender under its id), since it started.
    pub summaries_dropped: u64,
}

impl RobotHealth {
    /// Its state in one word: `down` (token gone), `stale` (see
    /// [`RobotHealth::stale`]) or `up`.
    pub fn state(&self) -> &'static str {
        match (self.up, self.stale.is_empty()) {
            (false, _) => "down",
            (true, true) => "up",
            (true, false) => "stale",
        }
    }
}

/// Most robots the answer to `status` lists (the worst of the fleet):
/// every robot of a site of a few dozen, a page of a large fleet's.
pub const STATUS_ROBOTS: usize = 100;

/// Robots a page of `robots` holds when the request does not say.
pub const DEFAULT_PAGE_SIZE: u32 = 50;
/// Most robots a page of `robots` holds.
pub const MAX_PAGE_SIZE: u32 = 1_000;
/// The states a `robots` request may ask for.
pub const ROBOT_STATES: [&str; 3] = ["up", "stale", "down"];

/// The payload of `robots`: which page of which robots, in which order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotsRequest {
    /// The page, from 0 (signed, so that a negative one reaches the
    /// central unit as a clear refusal rather than a wrapped number).
    pub page: i64,
    /// Robots a page, 1 to [`MAX_PAGE_SIZE`].
    pub page_size: u32,
    /// Only the robots in this state (one of [`ROBOT_STATES`]); empty: all.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub state: String,
    /// Nearest first to (`near_x_m`, `near_y_m`) instead of by id (robots
    /// without a pose last).
    pub near: bool,
    /// See `near`, metres.
    pub near_x_m: f64,
    /// See `near`, metres.
    pub near_y_m: f64,
}

impl Default for RobotsRequest {
    fn default() -> Self {
        Self {
            page: 0,
            page_size: DEFAULT_PAGE_SIZE,
            state: String::new(),
            near: false,
            near_x_m: 0.0,
            near_y_m: 0.0,
        }
    }
}

impl RobotsRequest {
    /// Why the request cannot be answered, if it cannot (the page beyond
    /// the last is told apart by the answer, which knows the fleet).
    pub fn problem(&self) -> Option<String> {
        if self.page < 0 {
            return Some(format!(
                "page {} is negative: pages count from 0",
                self.page
            ));
        }
        if !(1..=MAX_PAGE_SIZE).contains(&self.page_size) {
            return Some(format!(
                "page size {} is not in 1 to {MAX_PAGE_SIZE}",
                self.page_size
            ));
        }
        if !self.state.is_empty() && !ROBOT_STATES.contains(&self.state.as_str()) {
            return Some(format!(
                "state {:?} is none of {}",
                self.state,
                ROBOT_STATES.join(", ")
            ));
        }
        if self.near && !(self.near_x_m.is_finite() && self.near_y_m.is_finite()) {
            return Some("the place to sort near is not a number".into());
        }
        None
    }
}

/// The fleet's robots by state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct RobotCounts {
    /// Up: token present, tracked.
    pub up: u64,
    /// Stale: token present, its poses stopped or its MSU says an input stalled.
    pub stale: u64,
    /// Down: token gone.
    pub down: u64,
}

/// The answer to `robots` with a [`RobotsRequest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotPage {
    /// Why the request was refused (a negative page, one beyond the last,
    /// an unknown state); empty when it was answered.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub error: String,
    /// The page answered.
    pub page: i64,
    /// Pages the matching robots fill (at least 1).
    pub pages: u64,
    /// Robots matching the request, on every page.
    pub matching: u64,
    /// The whole fleet by state.
    pub counts: RobotCounts,
    /// The robots of the page.
    pub robots: Vec<RobotHealth>,
}

/// Answer to `status`, `cells`, `robots` and `sync`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatusReport {
    /// Site name.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub site: String,
    /// Last cycle triggered.
    pub cycle: u64,
    /// Master time when the report was made.
    pub stamp: Time,
    /// Whether cycle triggers are paused.
    pub paused: bool,
    /// Version of the schedule in force.
    pub schedule_version: u32,
    /// Cycles per second of the schedule in force.
    pub update_rate_hz: f64,
    /// Every cell of the site.
    pub cells: Vec<CellHealth>,
    /// The robots seen: every one in the viewers' status and the answer to
    /// `robots`; the worst [`STATUS_ROBOTS`] (down, then stale, then the
    /// fewest fixes a second; in id order) in the answer to `status`,
    /// `cells` and `sync`, whose size does not grow with the fleet.
    pub robots: Vec<RobotHealth>,
    /// Every robot seen, by state (whatever `robots` lists).
    pub robot_counts: RobotCounts,
    /// Of those, the robots with a pose.
    pub robots_posed: u64,
    /// The answering central unit's epoch (its start or term, master time, ns).
    pub epoch: u64,
    /// Control messages on the central unit's keys that it did not send
    /// (a schedule or trigger of its epoch it never made, or of another
    /// central unit), since it started.
    pub foreign_control: u64,
    /// Whether the answering central unit is the active one (`false`: a
    /// hot standby).
    pub active: bool,
    /// Survey calibrations it computed and published since it started.
    pub survey_publications: u64,
    /// How long the step that computed and published one took on the
    /// central unit, microseconds: the mean over them (0 before the first).
    pub survey_publish_mean_us: f64,
    /// The same, the longest.
    pub survey_publish_max_us: f64,
    /// The speed of sound the MSUs are told to solve with, m/s (0: none
    /// learnt or published, the site's).
    pub speed_of_sound_m_s: f64,
    /// Its one-sigma uncertainty, m/s.
    pub speed_of_sound_sigma_m_s: f64,
    /// The site file's speed of sound, m/s.
    pub site_speed_of_sound_m_s: f64,
    /// Transmitters left out of the fixes (dead, weak or moved), by id.
    pub transmitters_left_out: Vec<u32>,
}

/// What the fleet saw of one transmitter (`transmitters`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransmitterStatus {
    /// Transmitter id.
    pub tx_id: u32,
    /// Its cell.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// `unknown`, `healthy`, `dead`, `weak` or `moved`.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub condition: String,
    /// Whether its arrivals are left out of the fixes.
    pub left_out: bool,
    /// The evidence behind the condition, in words.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub evidence: String,
    /// Fixes a robot was near it in (recent, forgotten over tens of seconds).
    pub due: f64,
    /// Share of them it was heard in, percent (-1: none yet).
    pub heard_pct: f64,
    /// Share its cell's others were heard in from the same fixes, percent (-1: none).
    pub expected_pct: f64,
    /// Share of its heard arrivals the robots rejected, percent (-1: none heard).
    pub rejected_pct: f64,
    /// Whether its residuals below are known.
    pub residuals_known: bool,
    /// Mean of its residuals in the fixes that used it, metres.
    pub residual_mean_m: f64,
    /// Their standard deviation, metres.
    pub residual_std_m: f64,
    /// Seconds since a robot last heard it (-1: never).
    pub last_heard_s_ago: f64,
    /// What the survey calibration adds to its surveyed position, metres.
    pub offset_m: [f64; 3],
}

/// Answer to `transmitters`: every transmitter's health and the air.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransmittersReport {
    /// Site name.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub site: String,
    /// Master time when the report was made.
    pub stamp: Time,
    /// Whether the central unit learns a survey calibration at all (when
    /// not, nothing below is measured).
    pub learning: bool,
    /// Fixes of the fleet behind the calibration.
    pub fixes_taken: u64,
    /// The speed of sound the MSUs are told to solve with, m/s (0: the site's).
    pub speed_of_sound_m_s: f64,
    /// Its one-sigma uncertainty, m/s.
    pub speed_of_sound_sigma_m_s: f64,
    /// The site file's speed of sound, m/s.
    pub site_speed_of_sound_m_s: f64,
    /// Every transmitter, in the site's order.
    pub transmitters: Vec<TransmitterStatus>,
    /// The air temperature sensor of every cell's board, in the site's
    /// order of cells.
    pub air_sensors: Vec<BoardAirStatus>,
    /// The speed of sound the boards' fresh readings say (their median's),
    /// m/s (0: none fresh).
    pub air_sensor_speed_m_s: f64,
}

/// A cell board's air temperature sensor, as the central unit judged its
/// readings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardAirStatus {
    /// The cell.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// `no sensor` (nothing heard), `used` (a fresh accepted reading),
    /// `not used` (none fresh) or `stuck`.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub state: String,
    /// The last accepted reading, degrees Celsius (not a number: none).
    pub temperature_c: f64,
    /// Seconds since it came (-1: never).
    pub accepted_s_ago: f64,
    /// Readings accepted.
    pub accepted: u64,
    /// Readings refused as not a number.
    pub refused_not_a_number: u64,
    /// Readings refused as outside -40..85 C.
    pub refused_out_of_range: u64,
    /// Readings refused as a stuck sensor's.
    pub refused_stuck: u64,
    /// Readings refused as a jump of more than 20 C in a second.
    pub refused_jump: u64,
}

/// Optional query payload of `coverage`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CoverageRequest {
    /// Wanted grid spacing, metres (the central unit may enlarge it to bound
    /// the work; the report says what was used).
    pub resolution_m: f64,
}

/// Answer to `coverage`: a grid over the floor, row-major from the lower-left
/// corner, evaluated for the transmitters of the schedule in force.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoverageReport {
    /// Version of the schedule whose transmitters were counted.
    pub schedule_version: u32,
    /// x of the first grid point, metres.
    pub origin_x_m: f64,
    /// y of the first grid point, metres.
    pub origin_y_m: f64,
    /// Grid spacing, metres.
    pub resolution_m: f64,
    /// Receiver height the grid is evaluated at (the MSU's), metres.
    pub height_m: f64,
    /// Number of columns (along x).
    pub columns: u32,
    /// Number of rows (along y).
    pub rows: u32,
    /// Whether each grid point lies in a cell (points off the floor have no figures).
    pub on_floor: Vec<bool>,
    /// Transmitters audible in line of sight at each grid point.
    pub visible: Vec<u32>,
    /// Horizontal dilution of precision of the 2D TDOA fix at each grid
    /// point, metres of position error per metre of range noise (0 where no
    /// fix is possible).
    pub hdop: Vec<f64>,
}

/// Query payload of `reload`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReloadRequest {
    /// Name of the file, for messages.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub file_name: String,
    /// The new site file (TOML).
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub site_toml: String,
}

/// Answer to `pause`, `resume` and `reload`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AdminAck {
    /// Whether the command took effect.
    pub ok: bool,
    /// What happened, or every reason it was refused.
    #[serde(deserialize_with = "crate::wire_string::deserialize_vec")]
    pub messages: Vec<String>,
}
