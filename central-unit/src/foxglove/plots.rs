//! The figures Foxglove plots: one small JSON message per robot
//! (`ickon.RobotState`) and per cell (`ickon.CellSync`) each tick, and the
//! site's status (`ickon.SiteStatus`), each with its JSON schema so that
//! the app lists the fields to plot. Numbers not known yet are left out,
//! never sent as a made-up zero.

use std::sync::Arc;

use foxglove::{Context, RawChannel, Schema};
use serde::Serialize;

use super::scene::{cell_state, fired_this_cycle, robot_state};
use crate::http::view::{CellSnapshot, RobotSnapshot, Snapshot};

/// `/robot/<id>/state`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobotState<'a> {
    /// `tracking`, `localising`, `dead_reckoning`, `stale`, `down` or `unknown`.
    pub state: &'static str,
    /// Why it is stale, when it is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stale: Option<&'a str>,
    /// One sigma of the fused position along its worst axis, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_major_mm: Option<f64>,
    /// One sigma of the fused position along its best axis, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_minor_mm: Option<f64>,
    /// One sigma of the fused heading, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_heading_deg: Option<f64>,
    /// Distance of the fused pose from the truth (simulation only), mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub err_mm: Option<f64>,
    /// Fixes per second lately.
    pub fixes_per_s: f64,
    /// Transmitters used by the latest fix.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_used: Option<usize>,
    /// Transmitters rejected by the latest fix.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_rejected: Option<usize>,
    /// Since its last pose arrived, ms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub staleness_ms: Option<f64>,
}

impl<'a> From<&'a RobotSnapshot> for RobotState<'a> {
    fn from(r: &'a RobotSnapshot) -> Self {
        // The ellipse is 2 sigma; half of it is one.
        let sigma = |two_sigma_m: f64| (two_sigma_m * 500.0 * 10.0).round() / 10.0;
        Self {
            state: robot_state(r),
            stale: r.health.stale.as_deref(),
            sigma_major_mm: r.fused_ellipse.map(|e| sigma(e.a_m)),
            sigma_minor_mm: r.fused_ellipse.map(|e| sigma(e.b_m)),
            sigma_heading_deg: r
                .fused_heading_sigma_rad
                .map(|s| (s.to_degrees() * 100.0).round() / 100.0),
            err_mm: r.err_mm,
            fixes_per_s: r.health.fixes_per_s,
            fix_used: r.fix.as_ref().map(|f| f.used),
            fix_rejected: r.fix.as_ref().map(|f| f.rejected),
            staleness_ms: r.staleness_ms,
        }
    }
}

/// `/cell/<id>/sync`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellSync {
    /// `up`, `idle` or `down`.
    pub state: &'static str,
    /// 1 when it fired in the current cycle, else 0 (a number, to plot).
    pub firing: u8,
    /// Transmitter of its latest burst.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub last_tx: Option<u32>,
    /// Largest |actual - scheduled| emission time of its recent bursts, us.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sync_error_us: Option<f64>,
    /// RMS of the same, us.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sync_error_rms_us: Option<f64>,
    /// The cell's own one-sigma sync estimate, us.
    pub sync_sigma_us: f64,
    /// Offset master minus cell clock, us.
    pub offset_us: f64,
    /// Drift of the cell clock, ppm.
    pub drift_ppm: f64,
    /// Cycles fired since the central unit started.
    pub cycles_fired: u64,
    /// Scheduled cycles it did not fire.
    pub cycles_missed: u64,
}

impl CellSync {
    /// The figures of `c`; `cycle_period_ms` tells whether it is firing.
    pub fn new(c: &CellSnapshot, cycle_period_ms: f64) -> Self {
        Self {
            state: cell_state(c),
            firing: u8::from(fired_this_cycle(c, cycle_period_ms)),
            last_tx: c.last_tx,
            sync_error_us: c.health.sync_error_us,
            sync_error_rms_us: c.health.sync_error_rms_us,
            sync_sigma_us: c.health.sync_sigma_us,
            offset_us: c.health.offset_us,
            drift_ppm: c.health.drift_ppm,
            cycles_fired: c.health.cycles_fired,
            cycles_missed: c.health.cycles_missed,
        }
    }
}

/// `/site/status`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SiteStatus<'a> {
    /// Site name.
    pub site: &'a str,
    /// Last cycle triggered.
    pub cycle: u64,
    /// Cycles per second of the schedule in force.
    pub update_rate_hz: f64,
    /// Version of the schedule in force.
    pub schedule_version: u32,
    /// Whether cycle triggers are paused.
    pub paused: bool,
    /// Messages the live view ignored (unknown robot or cell, bad numbers).
    pub ignored_messages: u64,
}

const ROBOT_SCHEMA: &str = r#"{"type":"object","title":"ickon.RobotState","properties":{
"state":{"type":"string"},"stale":{"type":"string"},
"sigma_major_mm":{"type":"number"},"sigma_minor_mm":{"type":"number"},
"sigma_heading_deg":{"type":"number"},"err_mm":{"type":"number"},
"fixes_per_s":{"type":"number"},"fix_used":{"type":"integer"},
"fix_rejected":{"type":"integer"},"staleness_ms":{"type":"number"}}}"#;

const CELL_SCHEMA: &str = r#"{"type":"object","title":"ickon.CellSync","properties":{
"state":{"type":"string"},"firing":{"type":"integer"},"last_tx":{"type":"integer"},
"sync_error_us":{"type":"number"},"sync_error_rms_us":{"type":"number"},
"sync_sigma_us":{"type":"number"},"offset_us":{"type":"number"},
"drift_ppm":{"type":"number"},"cycles_fired":{"type":"integer"},
"cycles_missed":{"type":"integer"}}}"#;

const STATUS_SCHEMA: &str = r#"{"type":"object","title":"ickon.SiteStatus","properties":{
"site":{"type":"string"},"cycle":{"type":"integer"},"update_rate_hz":{"type":"number"},
"schedule_version":{"type":"integer"},"paused":{"type":"boolean"},
"ignored_messages":{"type":"integer"}}}"#;

/// A JSON channel with the JSON schema `schema` called `name`.
pub(super) fn json_channel(
    context: &Arc<Context>,
    topic: &str,
    name: &str,
    schema: &str,
) -> Arc<RawChannel> {
    let schema = Schema::new(name, "jsonschema", schema.as_bytes().to_vec());
    context
        .channel_builder(topic)
        .message_encoding("json")
        .schema(schema)
        .build_raw()
        // It fails only without a message encoding, which is set above
        // (as the SDK's own typed channels do).
        .expect("a channel with a message encoding")
}

/// The channel of a robot's figures.
pub fn robot_channel(context: &Arc<Context>, topic: &str) -> Arc<RawChannel> {
    json_channel(context, topic, "ickon.RobotState", ROBOT_SCHEMA)
}

/// The channel of a cell's figures.
pub fn cell_channel(context: &Arc<Context>, topic: &str) -> Arc<RawChannel> {
    json_channel(context, topic, "ickon.CellSync", CELL_SCHEMA)
}

/// The channel of the site's status, on `topic` (`topics::SITE_STATUS`).
pub fn status_channel(context: &Arc<Context>, topic: &str) -> Arc<RawChannel> {
    json_channel(context, topic, "ickon.SiteStatus", STATUS_SCHEMA)
}

/// Sends `value` as JSON on `channel`, when anyone listens.
pub(super) fn log_json<T: Serialize>(channel: &RawChannel, value: &T) {
    if !channel.has_sinks() {
        return;
    }
    match serde_json::to_vec(value) {
        Ok(bytes) => channel.log(&bytes),
        Err(e) => tracing::warn!("{} not serialised: {e}", channel.topic()),
    }
}

/// Sends a robot's figures.
pub fn log_robot(channel: &RawChannel, r: &RobotSnapshot) {
    log_json(channel, &RobotState::from(r));
}

/// Sends a cell's figures.
pub fn log_cell(channel: &RawChannel, c: &CellSnapshot, cycle_period_ms: f64) {
    log_json(channel, &CellSync::new(c, cycle_period_ms));
}

/// Sends the site's status.
pub fn log_status(channel: &RawChannel, s: &Snapshot) {
    log_json(
        channel,
        &SiteStatus {
            site: &s.site,
            cycle: s.cycle,
            update_rate_hz: s.update_rate_hz,
            schedule_version: s.schedule_version,
            paused: s.paused,
            ignored_messages: s.ignored_messages,
        },
    );
}
