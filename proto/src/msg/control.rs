//! Control plane: central unit <-> cell controllers.

use serde::{Deserialize, Serialize};

use crate::codec::{DecodeError, decode_layouts, decode_older};
use crate::time::{Duration, Time};

pub mod survey_before_air;
pub mod survey_before_lateness;
pub mod survey_older;

/// One row of the transmitter lookup table the MSU uses to turn an id into a position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransmitterEntry {
    /// Transmitter id, as decoded from its burst.
    pub tx_id: u32,
    /// Cell the transmitter belongs to.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// Position in the site frame, metres.
    pub x_m: f64,
    /// Position in the site frame, metres.
    pub y_m: f64,
    /// Height above the floor, metres.
    pub z_m: f64,
}

/// Largest correction of a surveyed coordinate a calibration may make,
/// metres: the fleet's calibration refines a survey; a transmitter several
/// decimetres off needs surveying again, and a calibration that says so
/// is broken or forged (the MSU refuses it; the central unit leaves such a
/// transmitter at its surveyed position and says so).
pub const MAX_SURVEY_OFFSET_M: f64 = 0.25;

/// Largest offset a calibration may publish for a transmitter the fleet's
/// fixes surveyed again after it was knocked out of place, metres (the
/// part of it the calibration learns stays within [`MAX_SURVEY_OFFSET_M`]):
/// a forklift moves one by decimetres; one moved further is mounted
/// elsewhere and is surveyed again by hand. The MSU refuses a calibration
/// that says more.
pub const MAX_RESURVEYED_OFFSET_M: f64 = 1.0;

/// The largest lateness of a transmitter's bursts a calibration may
/// correct, metres of path (about 0.73 ms): a cell whose bursts are that
/// late is failing its own synchronisation, which it reports in its status
/// (the MSU refuses a calibration that says more; the central unit
/// publishes 0 for such a transmitter).
pub const MAX_LATE_M: f64 = 0.25;

/// One transmitter's survey correction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TransmitterOffset {
    /// Transmitter id.
    pub tx_id: u32,
    /// What to add to its surveyed position (x, y, z), metres.
    pub offset_m: [f64; 3],
    /// One-sigma uncertainty of each corrected coordinate, metres.
    pub sigma_m: [f64; 3],
    /// How much later than its schedule says every burst of the
    /// transmitter arrives, in metres of path: its cell's sync error, which
    /// no clock exchange sees (a path slower one way than the other) but
    /// the fleet's fixes do. The MSU subtracts it from the transmitter's
    /// pseudo-ranges. Only differences between cells matter (what all
    /// share, every range difference cancels).
    pub late_m: f64,
    /// One-sigma uncertainty of `late_m`, metres.
    pub late_sigma_m: f64,
    /// The fleet has found the transmitter dead, weak or moved: the MSUs
    /// leave its arrivals out of their fixes until it is healthy again.
    pub left_out: bool,
}

/// The largest relative change of the speed of sound from the site's that
/// a calibration may publish (5 %, about 28 degrees Celsius): air further
/// off is no hall's, and a calibration that says so is broken or forged
/// (the MSU refuses it; the central unit publishes the site's speed).
pub const MAX_SOUND_SPEED_CHANGE: f64 = 0.05;

/// `central/survey`: the fleet's calibration of the transmitters' surveyed
/// positions, learnt by the central unit from every robot's fixes
/// (`ickon_central::survey_calibration`); the MSUs solve with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurveyCalibration {
    /// The epoch of the central unit that made it; `(epoch, version)` names
    /// a calibration.
    pub epoch: u64,
    /// Increases with every calibration of that epoch (from 1).
    pub version: u32,
    /// Fixes of the fleet behind it.
    pub fixes_taken: u64,
    /// One per transmitter of the site.
    pub offsets: Vec<TransmitterOffset>,
    /// The speed of sound the fleet's fixes say the air has now, m/s (the
    /// MSUs turn arrival times into ranges with it); 0: none learnt, the
    /// site's.
    pub speed_of_sound_m_s: f64,
    /// One-sigma uncertainty of `speed_of_sound_m_s`, m/s.
    pub speed_of_sound_sigma_m_s: f64,
}

impl SurveyCalibration {
    /// Decodes a `central/survey` payload: the current layout, the one
    /// before it carried the speed of sound and which transmitters are
    /// left out (read with the site's speed and none left out), or the one
    /// before transmitters carried their lateness (read with no lateness).
    /// None can be mistaken for another: each layout's offsets are longer
    /// than the one before's. A payload of none fails with the current
    /// layout's error.
    pub fn decode(payload: &[u8]) -> Result<Self, DecodeError> {
        decode_layouts(
            payload,
            &[
                decode_older::<survey_before_air::CalibrationWithoutAir, _>,
                decode_older::<survey_before_lateness::CalibrationWithoutLateness, _>,
            ],
        )
    }

    /// The speed of sound to solve with on a site whose own is
    /// `site_m_s`: the learnt one when there is one, else the site's.
    pub fn speed_of_sound_or(&self, site_m_s: f64) -> f64 {
        if self.speed_of_sound_m_s > 0.0 {
            self.speed_of_sound_m_s
        } else {
            site_m_s
        }
    }
}

/// `central/site`: the site model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SiteInfo {
    /// Site name (the `<site>` of every key).
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub site: String,
    /// Increases every time the central unit loads a new site file.
    pub version: u32,
    /// The site file itself (TOML), so every process validates it with the
    /// same code and builds the transmitter table from it.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub site_toml: String,
}

/// When one transmitter fires inside a cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Emission {
    /// Transmitter id.
    pub tx_id: u32,
    /// Cell of the transmitter.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// Offset of the emission from the cycle start.
    pub offset: Duration,
    /// Index of the slot the emission sits in.
    pub slot: u32,
}

/// `central/schedule`: the versioned emission schedule of the whole site.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Schedule {
    /// Version; a new schedule has a higher one.
    pub version: u32,
    /// The first cycle this schedule applies to; earlier cycles keep the previous one.
    pub effective_cycle: u64,
    /// Time between two cycle starts.
    pub cycle_period: Duration,
    /// Length of one slot (longest audible flight time plus the guard).
    pub slot_length: Duration,
    /// Every emission of a cycle; cells sharing a slot do not hear each other.
    pub emissions: Vec<Emission>,
    /// Cells that take part in this schedule (cells marked down are left out).
    #[serde(deserialize_with = "crate::wire_string::deserialize_vec")]
    pub active_cells: Vec<String>,
    /// The epoch of the central unit that made it (see [`CycleTrigger::epoch`]):
    /// versions count within an epoch, so `(epoch, version)` names a schedule.
    pub epoch: u64,
}

/// One transmitter named by a cycle trigger, and when it fires.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Firing {
    /// Transmitter id.
    pub tx_id: u32,
    /// Offset of the emission from the cycle start.
    pub offset: Duration,
}

/// `central/cycle`: the trigger of one cycle.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CycleTrigger {
    /// Cycle number, increasing by one per cycle.
    pub cycle: u64,
    /// Cycle start on the master time base.
    pub start: Time,
    /// The schedule version this cycle uses.
    pub schedule_version: u32,
    /// The epoch of the central unit that sent it: its start (or the start
    /// of its term as the active one) on the master time base, nanoseconds.
    /// Epochs only grow, so a restarted or newly active central unit is
    /// recognised at its first message, and cycle numbers count from 0
    /// within each epoch.
    pub epoch: u64,
    /// The transmitters that fire in this cycle and their offsets, when the
    /// central unit fires only where robots are (occupancy firing); empty: every
    /// emission of the schedule fires at its scheduled offset.
    pub firing: Vec<Firing>,
    /// This cycle's length; zero: the schedule's `cycle_period`.
    pub cycle_period: Duration,
}

impl CycleTrigger {
    /// The emissions of this cycle: the named firings (their cells taken
    /// from `schedule`, transmitters it does not know left out), or the
    /// whole schedule when none are named.
    pub fn emissions(&self, schedule: &Schedule) -> Vec<Emission> {
        if self.firing.is_empty() {
            return schedule.emissions.clone();
        }
        self.firing
            .iter()
            .enumerate()
            .filter_map(|(k, f)| {
                let e = schedule.emissions.iter().find(|e| e.tx_id == f.tx_id)?;
                Some(Emission {
                    offset: f.offset,
                    slot: u32::try_from(k).unwrap_or(u32::MAX),
                    ..e.clone()
                })
            })
            .collect()
    }

    /// This cycle's length under `schedule`.
    pub fn period(&self, schedule: &Schedule) -> Duration {
        if self.cycle_period > Duration::ZERO {
            self.cycle_period
        } else {
            schedule.cycle_period
        }
    }

    /// `schedule` as it applies to this cycle: only the named firings, at
    /// their offsets, and this cycle's length (what an MSU solves with).
    pub fn schedule_of_cycle(&self, schedule: &Schedule) -> Schedule {
        Schedule {
            emissions: self.emissions(schedule),
            cycle_period: self.period(schedule),
            ..schedule.clone()
        }
    }
}

/// Query payload on `central/clock`: the first timestamp of an NTP-style exchange.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClockRequest {
    /// Who asks.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// t1: when the request left, on the requester's clock.
    pub t1: Time,
}

/// Reply on `central/clock`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockReply {
    /// t1 echoed from the request.
    pub t1: Time,
    /// t2: when the request arrived, on the master clock.
    pub t2: Time,
    /// t3: when the reply left, on the master clock.
    pub t3: Time,
    /// The epoch of the answering central unit: a cell keeps only the
    /// answers of the central unit whose triggers it follows.
    pub epoch: u64,
}

/// `cell/<id>/burst`: one transmitter fired.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Burst {
    /// Cell that fired.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// Transmitter that fired.
    pub tx_id: u32,
    /// Cycle number.
    pub cycle: u64,
    /// When it should have fired, on the master time base.
    pub scheduled: Time,
    /// When it really fired on the true time base (known only to a simulation;
    /// hardware drivers report their best estimate on the master time base).
    pub actual: Time,
    /// The epoch of the trigger it answers: `(epoch, cycle)` names a cycle.
    pub epoch: u64,
}

/// `cell/<id>/air`: a reading of the air temperature sensor on a cell's
/// transmitter board, forwarded by the cell controller as the board sent
/// it (the central unit judges it: a failed sensor's reading is not a
/// number).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AirTemperature {
    /// The cell whose board measured it.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// When it was measured, on the master time base as the cell estimates it.
    pub stamp: Time,
    /// Degrees Celsius (not a number: the sensor had no valid reading).
    pub temperature_c: f64,
}

/// `cell/<id>/link` and `robot/<id>/link`: a node's link to its Zenoh
/// router as the node itself sees it, every few seconds. A message of its
/// own, not fields of [`CellStatus`] or
/// [`MsuStatus`](crate::msg::robot::MsuStatus): a central unit that does
/// not know it ignores the key, and one that does shows nothing for a node
/// that does not send it, so nodes and central units of either version
/// still read each other's status.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RouterLink {
    /// The reporting node: the cell's or the robot's id.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub node_id: String,
    /// When the link last came back after a loss, milliseconds since the
    /// Unix epoch on the node's system clock (0: not lost since it started).
    pub back_unix_ms: u64,
    /// Losses of the link since the node started.
    pub losses: u64,
}

/// `cell/<id>/status`: a cell controller's health and sync estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellStatus {
    /// The reporting cell.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub cell_id: String,
    /// When the report was made, on the master time base as the cell estimates it.
    pub stamp: Time,
    /// Estimated offset master minus local clock, nanoseconds.
    pub offset_ns: i64,
    /// Estimated drift of the local clock against the master, parts per billion.
    pub drift_ppb: i64,
    /// One-sigma uncertainty of the offset estimate, nanoseconds.
    pub offset_sigma_ns: i64,
    /// Number of clock samples behind the estimate.
    pub sync_samples: u32,
    /// Last cycle in which the cell fired.
    pub last_cycle_fired: u64,
    /// Cycles fired since start.
    pub cycles_fired: u64,
    /// Slots skipped because their trigger arrived too late.
    pub slots_skipped: u64,
    /// Current faults in plain words (empty when healthy).
    #[serde(deserialize_with = "crate::wire_string::deserialize_vec")]
    pub faults: Vec<String>,
    /// Control messages refused since start (triggers of an old epoch or
    /// off the cycle count, altered or backward schedules, clock answers
    /// of another central unit).
    pub inputs_refused: u64,
    /// The cell's transmitter device in plain words (a board's link and
    /// handshake state, its clock, what it refused); empty for the
    /// simulated driver.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub device: String,
}
