//! The parameters of [`super::ImuFilter`], with the reason for every
//! default.

use super::excess::ExcessParams;
use crate::estimator::InvalidParameter;

/// Parameters of [`super::ImuFilter`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuParams {
    /// Accelerometer white noise, m/s^2/sqrt(Hz).
    pub accel_noise_m_s2_rt_hz: f64,
    /// Gyro white noise, rad/s/sqrt(Hz).
    pub gyro_noise_rad_s_rt_hz: f64,
    /// Accelerometer bias random walk, m/s^3/sqrt(Hz).
    pub accel_bias_walk_m_s3_rt_hz: f64,
    /// Gyro bias random walk, rad/s^2/sqrt(Hz).
    pub gyro_bias_walk_rad_s2_rt_hz: f64,
    /// Start standard deviation of the velocity, m/s.
    pub initial_velocity_sigma_m_s: f64,
    /// Start standard deviation of roll and pitch after levelling, rad.
    pub initial_tilt_sigma_rad: f64,
    /// Yaw at the first placement, rad (counter-clockwise from +x).
    pub initial_yaw_rad: f64,
    /// Its standard deviation, rad.
    pub initial_yaw_sigma_rad: f64,
    /// Start standard deviation of the accelerometer bias, m/s^2.
    pub initial_accel_bias_sigma_m_s2: f64,
    /// Start standard deviation of the gyro bias, rad/s.
    pub initial_gyro_bias_sigma_rad_s: f64,
    /// Innovation gate, standard deviations.
    pub gate_sigma: f64,
    /// The body shadow known before the flight, metres (the prior mean).
    pub shadow_m: f64,
    /// Prior standard deviation of the body shadow, metres; 0 holds it at
    /// `shadow_m`.
    pub shadow_prior_sigma_m: f64,
    /// The antenna in the body frame, metres.
    pub antenna_body_m: [f64; 3],
    /// Gravity, m/s^2.
    pub gravity_m_s2: f64,
    /// IMU samples further apart than this are not integrated across (a
    /// gap in the stream), seconds.
    pub max_imu_gap_s: f64,
    /// Propagate with the specific force along the body z axis only (a
    /// multirotor: its rotors push along body z, the horizontal specific
    /// force is rotor drag, and the accelerometer's horizontal channels
    /// carry vibration and misalignment larger than that in flight). The
    /// accelerometer's x and y are then used only for levelling on the
    /// ground.
    pub thrust_axis_only: bool,
    /// The anchors' excess paths (off by default).
    pub excess: ExcessParams,
}

impl Default for ImuParams {
    /// Noise: a consumer MEMS IMU's datasheet values (about 0.002 m/s^2 and
    /// 0.0003 rad/s per sqrt(Hz)) times 25 for the propellers' vibration,
    /// rounded; bias walks 0.001 m/s^3 and 0.0001 rad/s^2 per sqrt(Hz);
    /// start: 1 m/s, 3 degrees of tilt (levelled from the accelerometer),
    /// yaw 0 within 10 degrees (the vehicle is set down facing +x), biases
    /// within 0.2 m/s^2 and 1 deg/s (the IMU is calibrated at power-up);
    /// 3 sigma; no body shadow; no lever arm; g = 9.81; 0.1 s.
    fn default() -> Self {
        Self {
            accel_noise_m_s2_rt_hz: 0.05,
            gyro_noise_rad_s_rt_hz: 0.0075,
            accel_bias_walk_m_s3_rt_hz: 1e-3,
            gyro_bias_walk_rad_s2_rt_hz: 1e-4,
            initial_velocity_sigma_m_s: 1.0,
            initial_tilt_sigma_rad: 3f64.to_radians(),
            initial_yaw_rad: 0.0,
            initial_yaw_sigma_rad: 10f64.to_radians(),
            initial_accel_bias_sigma_m_s2: 0.2,
            initial_gyro_bias_sigma_rad_s: 1f64.to_radians(),
            gate_sigma: 3.0,
            shadow_m: 0.0,
            shadow_prior_sigma_m: 0.0,
            antenna_body_m: [0.0; 3],
            gravity_m_s2: 9.81,
            max_imu_gap_s: 0.1,
            thrust_axis_only: false,
            excess: ExcessParams::default(),
        }
    }
}

impl ImuParams {
    /// Checks every parameter is in its domain.
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        let positive = [
            ("accel_noise_m_s2_rt_hz", self.accel_noise_m_s2_rt_hz),
            ("gyro_noise_rad_s_rt_hz", self.gyro_noise_rad_s_rt_hz),
            (
                "accel_bias_walk_m_s3_rt_hz",
                self.accel_bias_walk_m_s3_rt_hz,
            ),
            (
                "gyro_bias_walk_rad_s2_rt_hz",
                self.gyro_bias_walk_rad_s2_rt_hz,
            ),
            (
                "initial_velocity_sigma_m_s",
                self.initial_velocity_sigma_m_s,
            ),
            ("initial_tilt_sigma_rad", self.initial_tilt_sigma_rad),
            ("initial_yaw_sigma_rad", self.initial_yaw_sigma_rad),
            (
                "initial_accel_bias_sigma_m_s2",
                self.initial_accel_bias_sigma_m_s2,
            ),
            (
                "initial_gyro_bias_sigma_rad_s",
                self.initial_gyro_bias_sigma_rad_s,
            ),
            ("gate_sigma", self.gate_sigma),
            ("gravity_m_s2", self.gravity_m_s2),
            ("max_imu_gap_s", self.max_imu_gap_s),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(InvalidParameter {
                    estimator: "imu-eskf",
                    field,
                    reason: "must be finite and positive",
                });
            }
        }
        let finite = self.initial_yaw_rad.is_finite()
            && self.antenna_body_m.iter().all(|v| v.is_finite())
            && self.shadow_prior_sigma_m.is_finite()
            && self.shadow_prior_sigma_m >= 0.0
            && self.shadow_m.is_finite()
            && self.shadow_m >= 0.0;
        if !finite {
            return Err(InvalidParameter {
                estimator: "imu-eskf",
                field: "initial_yaw_rad, antenna_body_m, shadow_m or shadow_prior_sigma_m",
                reason: "must be finite (the shadow terms non-negative)",
            });
        }
        self.excess.validate("imu-eskf")
    }
}
