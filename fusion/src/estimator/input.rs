//! The measurements an estimator consumes, and their validation.

use super::EstimatorError;
use crate::tdoa::Fix;

/// Pose reported by the robot's relative positioning unit (the ICKON paper:
/// `x_b, y_b, gamma_b`), in the robot's own odometry frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometrySample {
    /// Time of the pose, in seconds.
    pub t_s: f64,
    /// `x_b` in metres.
    pub x_m: f64,
    /// `y_b` in metres.
    pub y_m: f64,
    /// `gamma_b` in radians (may be wrapped or continuous).
    pub theta_rad: f64,
}

/// Geometry of a differential drive, carried with the ticks so that the
/// estimator and the robot never disagree on it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WheelGeometry {
    /// Distance between the wheel contact points (the CDA paper: `W`), in metres.
    pub wheel_base_m: f64,
    /// Distance travelled by the left wheel per encoder tick, in metres.
    pub left_m_per_tick: f64,
    /// Distance travelled by the right wheel per encoder tick, in metres.
    pub right_m_per_tick: f64,
}

/// Cumulative wheel encoder counts (the CDA paper: `l, r`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderSample {
    /// Time of the reading, in seconds.
    pub t_s: f64,
    /// Cumulative left ticks since power-up (wrapping is the caller's job).
    pub left_ticks: i64,
    /// Cumulative right ticks since power-up.
    pub right_ticks: i64,
    /// The drive geometry converting ticks to distances.
    pub geometry: WheelGeometry,
}

/// A rate-gyro reading about the vertical axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroSample {
    /// Time of the reading, in seconds.
    pub t_s: f64,
    /// Yaw rate, counter-clockwise positive, in rad/s (raw: bias included).
    pub rate_rad_s: f64,
}

/// Obstacle-sensor readings (the CDA paper, section 3.3). A range is `None` when the
/// sensor sees nothing within its reach.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RangeSample {
    /// Time of the readings, in seconds.
    pub t_s: f64,
    /// Left ultrasonic range `d_lu`, in metres.
    pub left_ultrasonic_m: Option<f64>,
    /// Right ultrasonic range `d_ru`, in metres.
    pub right_ultrasonic_m: Option<f64>,
    /// Left infrared range `d_li`, in metres.
    pub left_ir_m: Option<f64>,
    /// Right infrared range `d_ri`, in metres.
    pub right_ir_m: Option<f64>,
    /// Heading planned by the obstacle-avoidance system, in the world frame,
    /// in radians, when the planner publishes it; used instead of eq. 12-15.
    pub planned_heading_rad: Option<f64>,
}

/// One time difference of arrival, already turned into a difference of
/// distances: `|p - b| - |p - a| = d_m` where `p` is the receiver and `a`,
/// `b` the two transmitters (B minus A). A tightly-coupled filter fuses
/// each one on its own, so no complete set of signals is needed for a fix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeDifferenceSample {
    /// Time of the measurement (arrival of the later signal), in seconds.
    pub t_s: f64,
    /// Arrival time of the earlier signal (transmitter A), in seconds, when
    /// the source knows it (the MSU does). A filter relating each arrival to
    /// the robot's position at its own time needs it for the first arrival
    /// of a cycle; without it, that time is guessed from the usual spacing.
    pub a_t_s: Option<f64>,
    /// Position of transmitter A in the world frame, metres.
    pub a_m: [f64; 3],
    /// Position of transmitter B in the world frame, metres.
    pub b_m: [f64; 3],
    /// `|p - b| - |p - a|`, in metres.
    pub d_m: f64,
    /// Standard deviation of `d_m`, in metres.
    pub sigma_m: f64,
    /// The clocks transmitters A and B fire by (for ultrasound: their
    /// cells), when the source knows them. Arrivals of one clock share its
    /// residual synchronisation error, which `tdoa-ekf` estimates per clock;
    /// `None` when not known (or not applicable: radio anchors).
    pub clocks: Option<[TransmitterClock; 2]>,
    /// One-sigma relative uncertainty of the propagation speed `d_m` was
    /// computed with, when the source knows it: for ultrasound, that of the
    /// speed of sound the MSU solves with (the fleet's published one, or
    /// the site file's). Every range of a cycle is off by that same share,
    /// which no number of cycles averages away.
    pub speed_rel_sigma: Option<f64>,
}

/// One distance from a beacon to the receiver, measured by the time of
/// flight of a signal whose emission time the receiver knows (a Marvelmind
/// hedgehog's raw distances; a radio ranging radio). Unlike a
/// [`RangeDifferenceSample`] it carries no unknown emission offset, so each
/// one constrains the position on its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeaconRangeSample {
    /// Time of the measurement, in seconds.
    pub t_s: f64,
    /// Position of the beacon in the world frame, metres.
    pub beacon_m: [f64; 3],
    /// Distance from the beacon to the receiver, metres.
    pub range_m: f64,
    /// Standard deviation of `range_m`, metres.
    pub sigma_m: f64,
}

/// The clock a transmitter fires by, and how well that clock is said to be
/// synchronised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransmitterClock {
    /// Names the clock (transmitters with the same id share it).
    pub id: u32,
    /// One-sigma sync error the clock's owner reports, as metres of path
    /// (its time error times the propagation speed); 0 when not reported.
    pub sync_sigma_m: f64,
}

impl RangeDifferenceSample {
    /// From a time difference `dt_s = t_b - t_a` (emission offsets already
    /// removed) and its standard deviation, at the propagation speed
    /// `speed_m_s` (speed of sound for ultrasound, of light for radio).
    pub fn from_time_difference(
        t_s: f64,
        a_m: [f64; 3],
        b_m: [f64; 3],
        dt_s: f64,
        sigma_s: f64,
        speed_m_s: f64,
    ) -> Self {
        Self {
            t_s,
            a_t_s: None,
            a_m,
            b_m,
            d_m: dt_s * speed_m_s,
            sigma_m: sigma_s * speed_m_s,
            clocks: None,
            speed_rel_sigma: None,
        }
    }

    /// The distance between the two transmitters, in metres: no receiver
    /// can measure a larger `|d_m|`.
    pub fn baseline_m(&self) -> f64 {
        let d: [f64; 3] = std::array::from_fn(|k| self.b_m[k] - self.a_m[k]);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }
}

/// One timestamped measurement.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Robot odometry pose.
    Odometry(OdometrySample),
    /// Wheel encoder ticks.
    Encoders(EncoderSample),
    /// Yaw rate.
    Gyro(GyroSample),
    /// MSU fix (the solver's own result, with the receiver-id heading).
    Fix(Fix),
    /// Obstacle ranges.
    Range(RangeSample),
    /// One range difference between two transmitters (tightly coupled).
    RangeDifference(RangeDifferenceSample),
    /// One distance to a beacon (tightly coupled).
    BeaconRange(BeaconRangeSample),
}

impl Input {
    /// The time of the measurement, in seconds.
    pub fn t_s(&self) -> f64 {
        match self {
            Input::Odometry(s) => s.t_s,
            Input::Encoders(s) => s.t_s,
            Input::Gyro(s) => s.t_s,
            Input::Fix(s) => s.t_s,
            Input::Range(s) => s.t_s,
            Input::RangeDifference(s) => s.t_s,
            Input::BeaconRange(s) => s.t_s,
        }
    }

    /// Checks every field is finite and in its domain.
    pub fn validate(&self) -> Result<(), EstimatorError> {
        match self {
            Input::Odometry(s) => {
                finite("t_s", s.t_s)?;
                finite("x_m", s.x_m)?;
                finite("y_m", s.y_m)?;
                finite("theta_rad", s.theta_rad)
            }
            Input::Encoders(s) => {
                finite("t_s", s.t_s)?;
                let g = &s.geometry;
                positive("wheel_base_m", g.wheel_base_m)?;
                positive("left_m_per_tick", g.left_m_per_tick)?;
                positive("right_m_per_tick", g.right_m_per_tick)
            }
            Input::Gyro(s) => {
                finite("t_s", s.t_s)?;
                finite("rate_rad_s", s.rate_rad_s)
            }
            Input::Fix(s) => {
                finite("t_s", s.t_s)?;
                if !s.position_m.iter().all(|v| v.is_finite()) {
                    return Err(EstimatorError::NonFinite {
                        field: "position_m",
                    });
                }
                if !s.covariance_m2.iter().all(|v| v.is_finite()) {
                    return Err(EstimatorError::NonFinite {
                        field: "covariance",
                    });
                }
                if let Some(h) = s.heading_rad {
                    finite("heading_rad", h)?;
                }
                Ok(())
            }
            Input::Range(s) => {
                finite("t_s", s.t_s)?;
                for (field, v) in [
                    ("left_ultrasonic_m", s.left_ultrasonic_m),
                    ("right_ultrasonic_m", s.right_ultrasonic_m),
                    ("left_ir_m", s.left_ir_m),
                    ("right_ir_m", s.right_ir_m),
                ] {
                    if let Some(d) = v {
                        positive(field, d)?;
                    }
                }
                if let Some(h) = s.planned_heading_rad {
                    finite("planned_heading_rad", h)?;
                }
                Ok(())
            }
            Input::RangeDifference(s) => {
                finite("t_s", s.t_s)?;
                for v in s.a_m {
                    finite("a_m", v)?;
                }
                for v in s.b_m {
                    finite("b_m", v)?;
                }
                finite("d_m", s.d_m)?;
                if let Some(v) = s.speed_rel_sigma {
                    non_negative("speed_rel_sigma", v)?;
                }
                positive("sigma_m", s.sigma_m)
            }
            Input::BeaconRange(s) => {
                finite("t_s", s.t_s)?;
                for v in s.beacon_m {
                    finite("beacon_m", v)?;
                }
                positive("range_m", s.range_m)?;
                positive("sigma_m", s.sigma_m)
            }
        }
    }
}

fn finite(field: &'static str, v: f64) -> Result<(), EstimatorError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(EstimatorError::NonFinite { field })
    }
}

fn non_negative(field: &'static str, v: f64) -> Result<(), EstimatorError> {
    finite(field, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(EstimatorError::OutOfRange {
            field,
            reason: "must not be negative",
        })
    }
}

fn positive(field: &'static str, v: f64) -> Result<(), EstimatorError> {
    finite(field, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(EstimatorError::OutOfRange {
            field,
            reason: "must be positive",
        })
    }
}
