//! The site file as written: serde structs that keep the byte span of every
//! field, so that validation can name the line of each problem.

use serde::Deserialize;
use toml::Spanned;

/// `[msu]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMsu {
    pub receivers: Spanned<i64>,
    pub receiver_angles_deg: Option<Spanned<Vec<f64>>>,
    pub height_m: Spanned<f64>,
    /// Carrier channels the MSU can hear (default 1).
    pub channels: Option<Spanned<i64>>,
}

/// `[[cells]]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCell {
    pub id: Spanned<String>,
    pub polygon: Spanned<Vec<[f64; 2]>>,
}

/// `[[transmitters]]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTransmitter {
    pub id: Spanned<i64>,
    pub cell: Spanned<String>,
    pub position: Spanned<[f64; 3]>,
    /// Carrier channel, from 0 (default 0).
    pub channel: Option<Spanned<i64>>,
}

/// `[[walls]]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawWall {
    pub from: Spanned<[f64; 2]>,
    pub to: Spanned<[f64; 2]>,
    pub height_m: Option<Spanned<f64>>,
}

/// `[[columns]]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawColumn {
    pub polygon: Spanned<Vec<[f64; 2]>>,
    pub height_m: Option<Spanned<f64>>,
}

/// `[[routes]]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRoute {
    pub name: Spanned<String>,
    pub points: Spanned<Vec<[f64; 2]>>,
    #[serde(default)]
    pub closed: bool,
    pub reference_points: Option<Spanned<i64>>,
    pub speed_m_s: Option<Spanned<f64>>,
}

/// `[[robots]]`
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRobot {
    pub id: Spanned<String>,
    /// The route a simulation drives it along; a real site's robots have none.
    pub route: Option<Spanned<String>>,
    /// `[x_m, y_m, heading_deg]`
    pub start: Option<Spanned<[f64; 3]>>,
}

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSite {
    pub name: Spanned<String>,
    pub speed_of_sound_m_s: Option<Spanned<f64>>,
    pub temperature_c: Option<Spanned<f64>>,
    pub guard_time_ms: Option<Spanned<f64>>,
    pub burst_length_ms: Option<Spanned<f64>>,
    pub decoder_window_ms: Option<Spanned<f64>>,
    pub ceiling_height_m: Option<Spanned<f64>>,
    pub msu: Spanned<RawMsu>,
    #[serde(default)]
    pub cells: Vec<RawCell>,
    #[serde(default)]
    pub transmitters: Vec<RawTransmitter>,
    #[serde(default)]
    pub walls: Vec<RawWall>,
    #[serde(default)]
    pub columns: Vec<RawColumn>,
    #[serde(default)]
    pub routes: Vec<RawRoute>,
    #[serde(default)]
    pub robots: Vec<RawRobot>,
}
