//! The arrival-time log format (`docs/log-format.md`): what each file
//! holds once read, and the names of its columns.

use std::collections::HashMap;

/// The format and version a measurements file declares on its first line.
pub const FORMAT: &str = "ickon-tdoa-log/1";

/// Columns of the anchors file (`z_m` only in 3D).
pub mod anchor_columns {
    /// Anchor id: any text without commas.
    pub const ID: &str = "id";
    /// Position, metres.
    pub const X: &str = "x_m";
    /// Position, metres.
    pub const Y: &str = "y_m";
    /// Position, metres (3D files only).
    pub const Z: &str = "z_m";
    /// `transmitter` or `receiver`.
    pub const ROLE: &str = "role";
}

/// Columns of the measurements file.
pub mod measurement_columns {
    /// Epoch id: a non-negative integer, non-decreasing down the file.
    pub const EPOCH: &str = "epoch";
    /// Time of the row on the measurements' clock, seconds.
    pub const TIME: &str = "time_s";
    /// The anchor the value concerns.
    pub const ANCHOR: &str = "anchor";
    /// The other anchor of a time difference (blank otherwise).
    pub const REFERENCE: &str = "reference";
    /// What `value` is, with its unit (see [`super::Kind`]).
    pub const KIND: &str = "kind";
    /// The measured value, in the unit the kind names.
    pub const VALUE: &str = "value";
    /// Optional standard deviation of `value`, same unit.
    pub const SIGMA: &str = "sigma";
}

/// Columns of the truth file (`z_m` only in 3D, `heading_rad` optional).
pub mod truth_columns {
    /// Time on the truth's clock, seconds.
    pub const TIME: &str = "time_s";
    /// Position, metres.
    pub const X: &str = "x_m";
    /// Position, metres.
    pub const Y: &str = "y_m";
    /// Position, metres (3D files only).
    pub const Z: &str = "z_m";
    /// Heading, radians counter-clockwise from +x (optional).
    pub const HEADING: &str = "heading_rad";
}

/// Which side of the link the anchors are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Fixed emitters heard by a mobile receiver (ICKON, GPS-like).
    Transmitter,
    /// Fixed listeners hearing a mobile emitter (microphone networks,
    /// UWB TDoA anchors hearing a tag).
    Receiver,
}

impl Role {
    /// The role spelled as in the file.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Transmitter => "transmitter",
            Self::Receiver => "receiver",
        }
    }
}

/// What a measurement row's `value` is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `toa_s`: an arrival time, seconds, with an unknown offset common to
    /// its epoch (the emission time, or the receiver's clock offset).
    ToaS,
    /// `tdoa_s`: arrival at `anchor` minus arrival at `reference`, seconds.
    TdoaS,
    /// `tdoa_m`: the same as a range difference, metres.
    TdoaM,
    /// `range_m`: a range (or pseudo-range), metres.
    RangeM,
}

impl Kind {
    /// Every kind as spelled in the file.
    pub const ALL: [(&'static str, Kind); 4] = [
        ("toa_s", Kind::ToaS),
        ("tdoa_s", Kind::TdoaS),
        ("tdoa_m", Kind::TdoaM),
        ("range_m", Kind::RangeM),
    ];

    /// The kind called `s`.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == s).map(|&(_, k)| k)
    }

    /// The value is a time (needs the propagation speed).
    pub fn is_time(self) -> bool {
        matches!(self, Self::ToaS | Self::TdoaS)
    }

    /// The value is a difference against a named reference.
    pub fn is_difference(self) -> bool {
        matches!(self, Self::TdoaS | Self::TdoaM)
    }
}

/// One anchor.
#[derive(Debug, Clone, PartialEq)]
pub struct Anchor {
    /// Its id in the files.
    pub id: String,
    /// Position, metres (`z` = 0 in 2D).
    pub position_m: [f64; 3],
}

/// The anchors file, read.
#[derive(Debug, Clone)]
pub struct Anchors {
    /// Every anchor, in file order.
    pub list: Vec<Anchor>,
    /// Index into `list` by id.
    pub by_id: HashMap<String, usize>,
    /// 2 or 3.
    pub dim: usize,
    /// The role every anchor has.
    pub role: Role,
    /// In 2D, the height of the plane the mobile moves in, metres (0
    /// unless the anchors file gives `mobile_height_m`).
    pub plane_z_m: f64,
}

impl Anchors {
    /// Positions, in file order.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.list.iter().map(|a| a.position_m).collect()
    }

    /// The anchors' centroid.
    pub fn centroid(&self) -> [f64; 3] {
        let n = self.list.len().max(1) as f64;
        std::array::from_fn(|k| self.list.iter().map(|a| a.position_m[k]).sum::<f64>() / n)
    }
}

/// One row of the measurements file, its ids looked up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrival {
    /// Line in the file.
    pub line: u64,
    /// Epoch id.
    pub epoch: u64,
    /// Time on the measurements' clock, seconds.
    pub t_s: f64,
    /// Index of the anchor.
    pub anchor: usize,
    /// Index of the reference anchor (differences only).
    pub reference: Option<usize>,
    /// What `value` is.
    pub kind: Kind,
    /// The value, in the kind's unit.
    pub value: f64,
    /// Its standard deviation, same unit, when the row gives one.
    pub sigma: Option<f64>,
}

/// One truth row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRow {
    /// Time on the truth's clock, seconds.
    pub t_s: f64,
    /// Position, metres (`z` = 0 in 2D).
    pub position_m: [f64; 3],
    /// Heading, radians, when given.
    pub heading_rad: Option<f64>,
}

/// The `# key: value` lines at the top of a file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Meta {
    /// `format`.
    pub format: Option<String>,
    /// `clock`: the name of the clock the file's times are on.
    pub clock: Option<String>,
    /// `propagation_speed_m_s`.
    pub propagation_speed_m_s: Option<f64>,
    /// `mobile_height_m` (anchors file): the log is 2D, the mobile moving
    /// in the horizontal plane at this height among anchors with heights.
    pub mobile_height_m: Option<f64>,
}

/// Columns of the odometry file: body-frame increments since the previous
/// row (x forward, y left).
pub mod odometry_columns {
    /// Time at the end of the increment, on the measurements' clock, seconds.
    pub const TIME: &str = "time_s";
    /// Forward increment, metres.
    pub const DX: &str = "dx_m";
    /// Leftward increment, metres.
    pub const DY: &str = "dy_m";
    /// Heading change, radians counter-clockwise.
    pub const DTHETA: &str = "dtheta_rad";
}

/// Columns of the IMU file: specific force and angular rate in the body
/// frame.
pub mod imu_columns {
    /// Time of the sample, on the measurements' clock, seconds.
    pub const TIME: &str = "time_s";
    /// Specific force, m/s^2, body x, y, z.
    pub const ACCEL: [&str; 3] = ["ax_m_s2", "ay_m_s2", "az_m_s2"];
    /// Angular rate, rad/s, about body x, y, z.
    pub const GYRO: [&str; 3] = ["gx_rad_s", "gy_rad_s", "gz_rad_s"];
}

/// One odometry row as the ground filter takes it: the distance along
/// the arc of the increment and its turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryRow {
    /// Time at the end of the increment, seconds.
    pub t_s: f64,
    /// Distance along the arc, metres (negative: driving backwards).
    pub distance_m: f64,
    /// Heading change, radians.
    pub dtheta_rad: f64,
}

impl OdometryRow {
    /// The row of an increment `(dx, dy)` in the body frame with the turn
    /// `dtheta`: the arc whose chord it is (the chord of an arc of length
    /// `d` turning by `dtheta` is `2 d sin(dtheta/2) / dtheta` long, at
    /// `dtheta/2` from the start heading). A lateral slip beyond the arc
    /// is not modelled by the filter; the chord's length keeps it.
    pub fn from_increment(t_s: f64, dx_m: f64, dy_m: f64, dtheta_rad: f64) -> Self {
        let chord = dx_m.hypot(dy_m);
        let half = 0.5 * dtheta_rad;
        let arc_per_chord = if half.abs() < 1e-9 {
            1.0
        } else {
            half / half.sin()
        };
        Self {
            t_s,
            distance_m: chord.copysign(dx_m) * arc_per_chord,
            dtheta_rad,
        }
    }

    /// The body-frame increment `(dx, dy)` of an arc of `distance_m`
    /// turning by `dtheta_rad` (the inverse of [`Self::from_increment`]).
    pub fn increment_m(distance_m: f64, dtheta_rad: f64) -> [f64; 2] {
        let half = 0.5 * dtheta_rad;
        let chord = if half.abs() < 1e-9 {
            distance_m
        } else {
            distance_m * half.sin() / half
        };
        [chord * half.cos(), chord * half.sin()]
    }
}
