//! The MSU configuration file as written: serde structs that keep the byte
//! span of every value, so that validation can name its line and column.

use serde::Deserialize;
use toml::Spanned;

/// A number with where it was written.
pub(super) type Num = Spanned<f64>;

/// `[filter]`: which estimator, and the tuning that is not one input's.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFilter {
    pub estimator: Spanned<String>,
    pub history_s: Option<Num>,
    /// `[x_m, y_m, heading_deg]`; the site file's start when absent.
    pub start: Option<Spanned<[f64; 3]>>,
    /// The estimator's own remaining parameters, as its documentation names them.
    pub params: Option<Spanned<toml::Table>>,
}

/// `[robot]`: the drive geometry that turns encoder ticks into metres.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRobot {
    pub wheel_base_m: Option<Num>,
    pub m_per_tick: Option<Num>,
}

/// `[fix]`: the position solved from one cycle.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFix {
    pub timing_sigma_us: Option<Num>,
    pub residual_gate_m: Option<Num>,
    pub max_sigma_m: Option<Num>,
    pub sigma_floor_mm: Option<Num>,
}

/// `[range_differences]`: arrivals fused one pair at a time.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRangeDifferences {
    pub gate_sigma: Option<Num>,
    pub late_soft_sigma: Option<Num>,
}

/// `[odometry]`: the wheel encoders.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOdometry {
    pub distance_sigma_fraction: Option<Num>,
    pub heading_sigma_deg_per_m: Option<Num>,
    pub heading_sigma_per_turn: Option<Num>,
}

/// `[gyro]`: the z-axis rate gyro.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawGyro {
    #[serde(rename = "use")]
    pub use_gyro: Option<Spanned<bool>>,
    pub white_noise_deg_s: Option<Num>,
    pub rate_hz: Option<Num>,
    pub bias_sigma_deg_s: Option<Num>,
    pub bias_walk_deg_s_sqrt_s: Option<Num>,
    pub scale_error: Option<Num>,
    pub max_gap_s: Option<Num>,
}

/// `[receiver_heading]`: the heading from which receiver heard first.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawReceiverHeading {
    pub sigma_deg: Option<Num>,
}

/// `[marvelmind]`: a Marvelmind kit as the ranging source.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMarvelmind {
    pub speed_of_sound_m_s: Option<Num>,
    pub range_sigma_m: Option<Num>,
    pub use_kit_positions: Option<Spanned<bool>>,
    pub kit_position_sigma_m: Option<Num>,
    pub gyro_rad_s_per_count: Option<Num>,
}

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMsuFile {
    pub filter: Spanned<RawFilter>,
    pub robot: Option<Spanned<RawRobot>>,
    pub fix: Option<Spanned<RawFix>>,
    pub range_differences: Option<Spanned<RawRangeDifferences>>,
    pub odometry: Option<Spanned<RawOdometry>>,
    pub gyro: Option<Spanned<RawGyro>>,
    pub receiver_heading: Option<Spanned<RawReceiverHeading>>,
    pub marvelmind: Option<Spanned<RawMarvelmind>>,
    /// `[ros2]`: the ROS 2 side, the fields of the `--ros2-*` flags (checked
    /// when the agent starts, like the flags).
    #[cfg(feature = "zenoh")]
    pub ros2: Option<crate::ros2::Ros2Options>,
}
