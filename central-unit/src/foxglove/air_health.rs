//! The speed of sound and each transmitter's health, for Foxglove: pure
//! functions of the central unit's status and transmitters reports (the
//! documents of `ickon admin status` and `ickon admin transmitters`).
//!
//! - `/site/speed_of_sound` (JSON `ickon.SpeedOfSound`): the speed the
//!   robots solve with and its sigma, the site file's, and the cell
//!   boards' air temperatures' when there are any, to plot;
//! - `/transmitters/scene` (`foxglove.SceneUpdate`): a sphere under each
//!   transmitter coloured by its health (healthy green, unknown grey, weak
//!   orange, moved purple, dead red), labelled when it is not healthy;
//! - `/transmitters/status` (JSON `ickon.TransmitterHealth`): per
//!   transmitter its condition, whether it is left out, the share of fixes
//!   near it that heard it, its residuals' mean and spread, when it was
//!   last heard.
//!
//! Numbers not known yet are left out, never sent as a made-up zero.

use std::sync::Arc;

use foxglove::messages::{Color, SceneEntity, SceneUpdate, SpherePrimitive, Timestamp, Vector3};
use foxglove::{Context, RawChannel};
use ickon_proto::msg::admin::{StatusReport, TransmitterStatus, TransmittersReport};
use ickon_proto::site::Site;
use serde::Serialize;

use super::plots::{json_channel, log_json};
use super::scene::{MAP_FRAME, text, yaw_pose};

/// How far under its transmitter a health sphere hangs, metres (the
/// transmitter itself is drawn by `/site/cells`).
const BELOW_M: f64 = 0.35;
/// Size of a health sphere, metres.
const SIZE_M: f64 = 0.2;

/// `/site/speed_of_sound`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SpeedOfSound {
    /// The speed the robots solve with, m/s (the learnt one, else the site file's).
    pub speed_m_s: f64,
    /// Its one-sigma uncertainty, m/s (absent: the site file's, not learnt).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_m_s: Option<f64>,
    /// Whether it is learnt.
    pub learnt: bool,
    /// The site file's speed, m/s.
    pub site_m_s: f64,
    /// What the cell boards' fresh air temperatures say, m/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub air_sensors_m_s: Option<f64>,
}

impl SpeedOfSound {
    /// The figures of `status`, with the boards' from `transmitters` when
    /// known.
    pub fn new(status: &StatusReport, transmitters: Option<&TransmittersReport>) -> Self {
        let learnt = status.speed_of_sound_m_s > 0.0;
        Self {
            speed_m_s: if learnt {
                status.speed_of_sound_m_s
            } else {
                status.site_speed_of_sound_m_s
            },
            sigma_m_s: learnt.then_some(status.speed_of_sound_sigma_m_s),
            learnt,
            site_m_s: status.site_speed_of_sound_m_s,
            air_sensors_m_s: transmitters
                .map(|t| t.air_sensor_speed_m_s)
                .filter(|v| *v > 0.0),
        }
    }
}

/// One transmitter in `/transmitters/status`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TransmitterHealth<'a> {
    /// Transmitter id.
    pub id: u32,
    /// Its cell.
    pub cell: &'a str,
    /// `unknown`, `healthy`, `dead`, `weak` or `moved`.
    pub condition: &'a str,
    /// 1 when it is left out of the robots' fixes, else 0 (a number, to plot).
    pub left_out: u8,
    /// Share of the recent fixes near it that heard it, percent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heard_pct: Option<f64>,
    /// Mean of its residuals in the fixes that used it, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_mean_mm: Option<f64>,
    /// Their standard deviation, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_std_mm: Option<f64>,
    /// Seconds since a robot last heard it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub last_heard_s_ago: Option<f64>,
}

impl<'a> From<&'a TransmitterStatus> for TransmitterHealth<'a> {
    fn from(t: &'a TransmitterStatus) -> Self {
        let known = |v: f64| (v >= 0.0).then_some(v);
        let mm = |m: f64| (m * 1e4).round() / 10.0;
        Self {
            id: t.tx_id,
            cell: &t.cell_id,
            condition: &t.condition,
            left_out: u8::from(t.left_out),
            heard_pct: known(t.heard_pct),
            residual_mean_mm: t.residuals_known.then(|| mm(t.residual_mean_m)),
            residual_std_mm: t.residuals_known.then(|| mm(t.residual_std_m)),
            last_heard_s_ago: known(t.last_heard_s_ago),
        }
    }
}

/// `/transmitters/status`: every transmitter, in the site's order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TransmittersHealth<'a> {
    /// Transmitters left out of the fixes now.
    pub left_out: usize,
    /// Every transmitter.
    pub transmitters: Vec<TransmitterHealth<'a>>,
}

impl<'a> From<&'a TransmittersReport> for TransmittersHealth<'a> {
    fn from(r: &'a TransmittersReport) -> Self {
        Self {
            left_out: r.transmitters.iter().filter(|t| t.left_out).count(),
            transmitters: r.transmitters.iter().map(TransmitterHealth::from).collect(),
        }
    }
}

/// The colour of a transmitter in `condition`.
pub fn health_color(condition: &str) -> Color {
    let (r, g, b) = match condition {
        "healthy" => (0.18, 0.62, 0.28),
        "weak" => (0.95, 0.55, 0.1),
        "moved" => (0.6, 0.25, 0.75),
        "dead" => (0.86, 0.15, 0.15),
        _ => (0.55, 0.55, 0.55),
    };
    Color { r, g, b, a: 1.0 }
}

/// A sphere under each transmitter of `report` that `site` places,
/// coloured by its health, one entity per transmitter (`tx/<id>`), with a
/// label when it is not healthy.
pub fn transmitters_scene(
    site: &Site,
    report: &TransmittersReport,
    stamp: Timestamp,
) -> SceneUpdate {
    let entities = report
        .transmitters
        .iter()
        .filter_map(|t| {
            let tx = site.transmitters.iter().find(|s| s.id == t.tx_id)?;
            let [x, y, z] = tx.position_m;
            let color = health_color(&t.condition);
            let mut e = SceneEntity {
                timestamp: Some(stamp),
                frame_id: MAP_FRAME.to_string(),
                id: format!("tx/{}", t.tx_id),
                ..Default::default()
            };
            e.spheres.push(SpherePrimitive {
                pose: Some(yaw_pose(x, y, z - BELOW_M, 0.0)),
                size: Some(Vector3 {
                    x: SIZE_M,
                    y: SIZE_M,
                    z: SIZE_M,
                }),
                color: Some(color),
            });
            if t.condition != "healthy" && t.condition != "unknown" {
                let label = if t.left_out {
                    format!("tx {} {} (left out)", t.tx_id, t.condition)
                } else {
                    format!("tx {} {}", t.tx_id, t.condition)
                };
                e.texts.push(text(x, y, z - 2.0 * BELOW_M, &label, color));
            }
            Some(e)
        })
        .collect();
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

const SPEED_SCHEMA: &str = r#"{"type":"object","title":"ickon.SpeedOfSound","properties":{
"speed_m_s":{"type":"number"},"sigma_m_s":{"type":"number"},"learnt":{"type":"boolean"},
"site_m_s":{"type":"number"},"air_sensors_m_s":{"type":"number"}}}"#;

const HEALTH_SCHEMA: &str = r#"{"type":"object","title":"ickon.TransmitterHealth","properties":{
"left_out":{"type":"integer"},"transmitters":{"type":"array","items":{"type":"object","properties":{
"id":{"type":"integer"},"cell":{"type":"string"},"condition":{"type":"string"},
"left_out":{"type":"integer"},"heard_pct":{"type":"number"},
"residual_mean_mm":{"type":"number"},"residual_std_mm":{"type":"number"},
"last_heard_s_ago":{"type":"number"}}}}}}"#;

/// The channel of the speed of sound, on `topic`.
pub fn speed_channel(context: &Arc<Context>, topic: &str) -> Arc<RawChannel> {
    json_channel(context, topic, "ickon.SpeedOfSound", SPEED_SCHEMA)
}

/// The channel of the transmitters' health, on `topic`.
pub fn health_channel(context: &Arc<Context>, topic: &str) -> Arc<RawChannel> {
    json_channel(context, topic, "ickon.TransmitterHealth", HEALTH_SCHEMA)
}

/// Sends the speed of sound.
pub fn log_speed(
    channel: &RawChannel,
    status: &StatusReport,
    transmitters: Option<&TransmittersReport>,
) {
    log_json(channel, &SpeedOfSound::new(status, transmitters));
}

/// Sends the transmitters' health.
pub fn log_health(channel: &RawChannel, report: &TransmittersReport) {
    log_json(channel, &TransmittersHealth::from(report));
}

#[cfg(test)]
#[path = "air_health_tests.rs"]
mod tests;
