//! Per-robot streams: sensors -> MSU agent -> anyone.

use serde::{Deserialize, Serialize};

use crate::codec::{DecodeError, decode_layouts, decode_older};
use crate::time::Time;

pub mod fix_before_unused;

/// One ultrasonic arrival as the MSU records it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Arrival {
    /// Transmitter id decoded from the burst (may be wrong: decoding errors happen).
    pub tx_id: u32,
    /// Which of the MSU's receivers heard the burst first (0-based, counter-clockwise).
    pub receiver_id: u8,
    /// Time of arrival on the MSU's own clock (the hardware resolves 1 us).
    pub t_arrival: Time,
}

/// `robot/<id>/ultrasound`: the arrivals of one cycle.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct UltrasoundArrivals {
    /// Increases by one per message of this robot, so that a fix and a pose can
    /// name the arrivals they come from (latency measurement).
    pub seq: u64,
    /// Arrivals, in order of arrival.
    pub arrivals: Vec<Arrival>,
}

/// `robot/<id>/odom`: the robot's relative positioning unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Sample time on the robot's clock.
    pub stamp: Time,
    /// Dead-reckoned position in the odometry frame, metres.
    pub x_m: f64,
    /// Dead-reckoned position in the odometry frame, metres.
    pub y_m: f64,
    /// Dead-reckoned heading in the odometry frame, radians (unwrapped).
    pub theta_rad: f64,
    /// Cumulative encoder ticks of the left wheel.
    pub left_ticks: i64,
    /// Cumulative encoder ticks of the right wheel.
    pub right_ticks: i64,
}

/// `robot/<id>/status`: the MSU agent's own report, once a second.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct MsuStatus {
    /// When it was made, on the MSU clock.
    pub stamp: Time,
    /// Where its arrivals or ranges come from, in plain words: a receiver
    /// board's or a ranging kit's link and state, what it refused; empty
    /// for the simulated world's arrivals.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub receivers: String,
}

/// `robot/<id>/imu`: the yaw-rate gyro.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Sample time on the robot's clock.
    pub stamp: Time,
    /// Angular rate about the vertical axis, rad/s, counter-clockwise positive.
    pub gyro_z_rad_s: f64,
}

/// `robot/<id>/range`: obstacle sensors of the CDA paper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ObstacleRanges {
    /// Sample time on the robot's clock.
    pub stamp: Time,
    /// Left ultrasonic range (0.2-7.6 m), metres; meaningful when `left_valid`.
    pub left_m: f64,
    /// Whether the left sensor saw something in range.
    pub left_valid: bool,
    /// Right ultrasonic range (0.2-7.6 m), metres; meaningful when `right_valid`.
    pub right_m: f64,
    /// Whether the right sensor saw something in range.
    pub right_valid: bool,
    /// Left infrared range (0.04-0.3 m), metres; meaningful when `left_ir_valid`.
    pub left_ir_m: f64,
    /// Whether the left infrared sensor saw something in range.
    pub left_ir_valid: bool,
    /// Right infrared range (0.04-0.3 m), metres; meaningful when `right_ir_valid`.
    pub right_ir_m: f64,
    /// Whether the right infrared sensor saw something in range.
    pub right_ir_valid: bool,
}

/// Quality of a fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FixQuality {
    /// Redundant signals, residuals consistent with the timing noise.
    Good,
    /// Just enough signals: no redundancy to check residuals against.
    Minimal,
    /// Solved, but residuals larger than the timing noise explains.
    Suspect,
    /// Two positions fit the signals equally; the one nearer the robot's
    /// estimate was taken.
    Ambiguous,
}

/// `robot/<id>/fix`: the raw MSU solution of one cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fix {
    /// Time of the measurement on the MSU clock (the mean arrival time of the cycle).
    pub stamp: Time,
    /// `seq` of the [`UltrasoundArrivals`] this fix was solved from.
    pub arrivals_seq: u64,
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Height, metres (the known MSU height for a 2D fix).
    pub z_m: f64,
    /// Position covariance, 3x3 row-major, m^2.
    pub covariance: [f64; 9],
    /// Heading from the first receiver (the ICKON paper, eq. 4-6), radians; meaningful when `heading_valid`.
    pub heading_rad: f64,
    /// Whether `heading_rad` holds a value.
    pub heading_valid: bool,
    /// Transmitters used in the solution.
    pub used: Vec<u32>,
    /// Transmitters heard but rejected (reflection, inconsistency, unknown id).
    pub rejected: Vec<u32>,
    /// Range-difference residuals of the used transmitters, metres.
    pub residuals_m: Vec<f64>,
    /// Quality flag.
    pub quality: FixQuality,
    /// The version of the survey calibration the transmitters' positions
    /// were corrected by ([`crate::msg::control::SurveyCalibration`]; 0:
    /// the surveyed positions), so that the central unit reads the
    /// residuals against the table they were solved with.
    pub survey_version: u32,
    /// Transmitters heard and not used whose arrival the MSU measured
    /// against the fix: left out by the survey calibration or rejected by
    /// the fix's gates (unknown or repeated ids are not measured).
    pub unused: Vec<u32>,
    /// The pseudo-range residual of each of `unused` (same order) against
    /// the fix's position and common offset, metres (`rho - |s - p| - b`,
    /// as `residuals_m`; positive: late): what the central unit re-surveys
    /// a moved transmitter from.
    pub unused_residuals_m: Vec<f64>,
}

impl Fix {
    /// Decodes a `robot/<id>/fix` payload: the current layout, or the one
    /// before a fix carried its unused arrivals (read with none). Neither
    /// can be mistaken for the other: the current one is longer by its two
    /// arrays' lengths. A payload of neither fails with the current
    /// layout's error.
    pub fn decode(payload: &[u8]) -> Result<Self, DecodeError> {
        decode_layouts(
            payload,
            &[decode_older::<fix_before_unused::FixWithoutUnused, _>],
        )
    }
}

/// Whether a pose is tracked by the inputs it needs, and if not, which one stalled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum PoseStatus {
    /// Fixes and odometry are coming.
    #[default]
    Tracking,
    /// No fix absorbed for a while: the pose is dead reckoning, its
    /// covariance grows with the time since the last fix.
    NoFixes,
    /// No odometry for a while: the pose moves only with the fixes.
    NoOdometry,
    /// No fix has agreed with the pose since the MSU started: the position
    /// is the configured start pose carried by odometry (an MSU restarted
    /// while its robot drove has the wrong one), a guess to show, not to
    /// steer by. Ends at the first fix the estimator's pose agrees with.
    Localising,
}

/// `robot/<id>/pose`: the fused pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotPose {
    /// Time the pose refers to, on the MSU clock.
    pub stamp: Time,
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians, wrapped to (-pi, pi].
    pub theta_rad: f64,
    /// Covariance of (x, y, theta), 3x3 row-major.
    pub covariance: [f64; 9],
    /// Name of the estimator that made it.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub estimator: String,
    /// `arrivals_seq` of the newest fix the pose has absorbed (0: none yet).
    pub fix_seq: u64,
    /// Whether its inputs are coming (the MSU's own judgement, by the
    /// stamps of its inputs).
    pub status: PoseStatus,
}

/// How often a robot's agent publishes its [`RobotSummary`]: twice a
/// second, whatever its cycle and pose rates. Enough for the central
/// unit's firing plan: a summary is at most this old plus its delivery
/// when a cycle is planned, and a robot whose acceleration stays under
/// 1.5 m/s^2 strays from the course the summary's velocity predicts by
/// under half a metre in that time (a fraction of the 8.5 m a
/// transmitter is fired for), so the plan's regions grow a little and
/// miss nothing. 10,000 robots make 20,000 messages a second.
pub const SUMMARY_PERIOD: crate::time::Duration = crate::time::Duration::from_millis(500);

/// Most fixes one [`RobotSummary`] carries: the newest of those solved
/// since the previous summary. Three: as many as the central unit's survey
/// calibration takes of a robot at once (its share's burst); a site
/// cycling faster than six times a second sends the newest.
pub const MAX_SUMMARY_FIXES: usize = 3;

/// `robot/<id>/summary`: what the central unit needs of a robot, at a
/// bounded rate ([`SUMMARY_PERIOD`]) independent of the cycle and pose
/// rates: where it is and how sure, its velocity, whether its inputs
/// come, and its newest fixes for the fleet's survey calibration. The
/// poses and fixes themselves stay on `robot/<id>/pose` and `fix` for
/// whoever follows one robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotSummary {
    /// Increases by one per summary of this robot.
    pub seq: u64,
    /// Time of the newest pose, on the MSU clock.
    pub stamp: Time,
    /// Position of the newest pose, metres.
    pub x_m: f64,
    /// Position of the newest pose, metres.
    pub y_m: f64,
    /// Heading of the newest pose, radians, wrapped to (-pi, pi].
    pub theta_rad: f64,
    /// Covariance of (x, y, theta) of the newest pose, 3x3 row-major.
    pub covariance: [f64; 9],
    /// Name of the estimator that made the pose.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub estimator: String,
    /// `arrivals_seq` of the newest fix the pose has absorbed (0: none yet).
    pub fix_seq: u64,
    /// Whether the pose's inputs are coming.
    pub status: PoseStatus,
    /// Mean velocity over the last half second of poses, site frame, m/s;
    /// meaningful when `velocity_span_s` > 0.
    pub vx_m_s: f64,
    /// Mean velocity over the last half second of poses, site frame, m/s.
    pub vy_m_s: f64,
    /// The span of pose stamps the velocity is the mean over, seconds (0:
    /// no velocity known).
    pub velocity_span_s: f64,
    /// Fixes solved since the previous summary (more than `fixes` holds
    /// when the cycles are faster than [`MAX_SUMMARY_FIXES`] a summary).
    pub fixes_solved: u32,
    /// The newest fixes solved since the previous summary, oldest first, at
    /// most [`MAX_SUMMARY_FIXES`].
    pub fixes: Vec<Fix>,
}

impl RobotSummary {
    /// Decodes a `robot/<id>/summary` payload: the current layout, or the
    /// one whose fixes carried no unused arrivals (see [`Fix::decode`]).
    pub fn decode(payload: &[u8]) -> Result<Self, DecodeError> {
        decode_layouts(
            payload,
            &[decode_older::<fix_before_unused::SummaryWithoutUnused, _>],
        )
    }

    /// The newest pose it summarises.
    pub fn pose(&self) -> RobotPose {
        RobotPose {
            stamp: self.stamp,
            x_m: self.x_m,
            y_m: self.y_m,
            theta_rad: self.theta_rad,
            covariance: self.covariance,
            estimator: self.estimator.clone(),
            fix_seq: self.fix_seq,
            status: self.status,
        }
    }
}

/// `sim/truth/<id>`: ground truth, simulation only.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// True time of the sample.
    pub stamp: Time,
    /// The same instant on the robot's own clock (which stamps its odometry,
    /// arrivals and poses), so observers can align poses with the truth.
    pub robot_clock: Time,
    /// True position of the MSU reference point, metres.
    pub x_m: f64,
    /// True position of the MSU reference point, metres.
    pub y_m: f64,
    /// True heading, radians, wrapped to (-pi, pi].
    pub theta_rad: f64,
    /// Forward speed, m/s.
    pub v_m_s: f64,
    /// Turn rate, rad/s.
    pub omega_rad_s: f64,
}
