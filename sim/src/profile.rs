//! Named noise profiles: every parameter of every sensor model in one serde
//! struct per sensor, so a profile can be printed, stored and compared.
//!
//! - `ideal`: no noise at all; the robot moves during the cycle as it does
//!   everywhere else, and the MSU's solver relates each arrival to the
//!   robot's position at its own time (from the wheels), so fixes are exact
//!   once its odometry is aligned (the world can still freeze the robot
//!   during a cycle: [`UltrasoundNoise::motion_during_cycle`]).
//! - `paper`: calibrated against the ICKON paper (see [`NoiseProfile::paper`] for the
//!   values and how they were chosen).
//! - `building`: `paper` in the air of a real hall ([`crate::air`]).
//! - `harsh`: the same air, more reflections, blockage, slip and gyro drift, and a more
//!   reverberant room.
//!
//! Every profile models collisions between bursts on one carrier channel
//! and reverberation tails ([`CollisionModel`]).

use serde::{Deserialize, Serialize};

use crate::air::Air;
use crate::air_sensor::AirSensors;

/// The ultrasonic channel and the MSU's receivers (docs/simulation.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UltrasoundNoise {
    /// Whether the robot moves while the sound flies and between the
    /// emissions of a cycle; `false` freezes it at the cycle's mean arrival time.
    pub motion_during_cycle: bool,
    /// Standard deviation of the detection time of each arrival, microseconds.
    pub timing_jitter_us: f64,
    /// Resolution of the MSU's time stamps, microseconds (0: none).
    pub quantisation_us: f64,
    /// Standard deviation of the bearing seen by the receiver ring before the
    /// first receiver is picked, degrees (receivers overlap near their borders).
    pub bearing_sigma_deg: f64,
    /// Probability that an arrival in line of sight is lost.
    pub drop_probability: f64,
    /// Probability that a blocked transmitter is heard by a reflection instead of not at all.
    pub blocked_reflection_probability: f64,
    /// Probability that a transmitter in line of sight is heard first by a
    /// reflection (direct path too weak to trigger the detector).
    pub los_reflection_probability: f64,
    /// Extra path of a reflection, metres: uniform in `[min, max]`.
    pub reflection_extra_m: [f64; 2],
    /// Probability that the transmitter id is decoded wrongly.
    pub id_error_probability: f64,
    /// Farthest distance at which a burst is still detected, metres.
    pub max_range_m: f64,
    /// Standard deviation of the survey error of each transmitter coordinate,
    /// metres: the lookup table the MSU uses differs from where the
    /// transmitters really hang (the ICKON paper measured them with a laser plumb).
    pub survey_sigma_m: f64,
    /// Error of the temperature the MSU assumes, degrees Celsius (the true
    /// speed of sound differs from the site's by this much).
    pub temperature_error_c: f64,
    /// Collisions and reverberation between bursts on one carrier channel.
    pub collisions: CollisionModel,
    /// The hall's air around the mean set by `temperature_error_c`: its
    /// swing over the run, gradient, spots, drafts and steps (still and
    /// even when absent).
    #[serde(default, skip_serializing_if = "Air::is_calm")]
    pub air: Air,
}

/// How bursts on one carrier channel spoil each other at a receiver
/// ([`crate::collision`]). The burst length and the decoder's window are
/// the site's (`burst_length_ms`, `decoder_window_ms`: the hardware's);
/// what the air and the room do is here.
///
/// Levels are in dB relative to the burst's level at 1 m: a burst that
/// travelled `d` metres arrives at `-20 log10(d) - absorption_db_per_m d`.
/// Each burst that reaches a receiver directly leaves a reverberation tail
/// that starts `reverb_tail_db` below the burst's own level when the burst
/// ends and falls by `reverb_decay_db_per_ms`; a later burst is masked when
/// the tail is less than `detection_snr_db` below it. Two bursts whose
/// onsets are closer than the burst length plus the decoder window collide:
/// both are lost, except that with `misdecode_probability` the detector
/// reports the earlier onset with the stronger burst's id (a wrong time for
/// that id when the stronger came later).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionModel {
    /// Air absorption at the carrier, dB per metre (40 kHz at 20 degC and
    /// 50 % humidity: about 1.3 dB/m).
    pub absorption_db_per_m: f64,
    /// Extra loss of a reflected path at the reflecting surface, dB.
    pub reflection_loss_db: f64,
    /// Level of a burst's reverberation tail when the burst ends, relative
    /// to the burst's direct level at the receiver, dB (negative).
    pub reverb_tail_db: f64,
    /// How fast the tail dies away, dB per millisecond (60 dB in
    /// `60 / decay` ms: the room's reverberation time at the carrier).
    pub reverb_decay_db_per_ms: f64,
    /// A burst is detected only this far above the tail it arrives in, dB.
    pub detection_snr_db: f64,
    /// Probability that a collision yields a detection (the earlier onset,
    /// the stronger burst's id) instead of nothing.
    pub misdecode_probability: f64,
}

impl CollisionModel {
    /// The room and air of `paper`: 1.3 dB/m absorption, 6 dB lost at a
    /// reflection, a tail 10 dB under the burst dying at 3 dB/ms (a
    /// reverberation time of 20 ms at 40 kHz, where air and soft surfaces
    /// absorb much more than at audible frequencies), detection 10 dB
    /// above the tail, and one collision in five decoded as the stronger
    /// burst at the earlier onset.
    pub fn paper() -> Self {
        Self {
            absorption_db_per_m: 1.3,
            reflection_loss_db: 6.0,
            reverb_tail_db: -10.0,
            reverb_decay_db_per_ms: 3.0,
            detection_snr_db: 10.0,
            misdecode_probability: 0.2,
        }
    }
}

/// Wheel encoders of the differential drive.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncoderNoise {
    /// True left wheel radius relative to nominal, minus one.
    pub left_radius_error: f64,
    /// True right wheel radius relative to nominal, minus one.
    pub right_radius_error: f64,
    /// True wheel base relative to nominal, minus one.
    pub wheel_base_error: f64,
    /// Standard deviation of the slip of each wheel on straight lines, a fraction of its travel.
    pub slip_sigma: f64,
    /// Extra slip standard deviation per rad/s of turn rate.
    pub slip_per_rad_s: f64,
}

/// Yaw-rate gyro.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroNoise {
    /// Standard deviation of the constant bias drawn at power-up, deg/s.
    pub bias_sigma_deg_s: f64,
    /// Bias random walk, deg/s per sqrt(s).
    pub bias_walk_deg_s_sqrt_s: f64,
    /// White noise of each sample, deg/s.
    pub white_sigma_deg_s: f64,
    /// Scale factor error (fraction).
    pub scale_error: f64,
    /// Sampling rate, Hz.
    pub rate_hz: f64,
}

/// Obstacle sensors of the CDA paper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleNoise {
    /// Standard deviation of the ultrasonic ranges, metres (1 cm resolution on top).
    pub ultrasonic_sigma_m: f64,
    /// Standard deviation of the infrared ranges, metres.
    pub ir_sigma_m: f64,
    /// Probability that a reading is missing.
    pub dropout_probability: f64,
}

/// Device clocks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClockNoise {
    /// Standard deviation of a cell clock's offset from the master at
    /// power-up, milliseconds (the cell's synchronisation removes it).
    pub cell_offset_sigma_ms: f64,
    /// Standard deviation of a cell clock's drift, parts per million.
    pub cell_drift_sigma_ppm: f64,
    /// Smallest one-way delay of a message between two nodes, microseconds.
    pub net_delay_us: f64,
    /// Mean of the queueing delay added to every message, microseconds
    /// (exponentially distributed: most messages are fast, a few are late).
    pub net_jitter_us: f64,
    /// Standard deviation of each cell's path asymmetry (outward minus
    /// return delay, constant per cell), microseconds. No clock exchange can
    /// see it: a cell's residual synchronisation error is half of it.
    pub net_asymmetry_sigma_us: f64,
    /// Standard deviation of the MSU clock's offset from true time, milliseconds.
    pub msu_offset_sigma_ms: f64,
    /// Standard deviation of the MSU clock's drift, parts per million.
    pub msu_drift_sigma_ppm: f64,
}

/// One named noise profile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseProfile {
    /// Profile name.
    pub name: String,
    /// Ultrasound channel.
    pub ultrasound: UltrasoundNoise,
    /// Wheel encoders.
    pub encoders: EncoderNoise,
    /// Gyro.
    pub gyro: GyroNoise,
    /// Obstacle sensors.
    pub obstacles: ObstacleNoise,
    /// Clocks.
    pub clocks: ClockNoise,
    /// The air temperature sensors on the cells' boards (absent: none).
    #[serde(default, skip_serializing_if = "AirSensors::is_absent")]
    pub air_sensors: AirSensors,
}

/// A profile name that is not one of [`NoiseProfile::names`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown noise profile `{0}` (known: ideal, paper, building, harsh, or a TOML file such as deploy/profiles/paper.toml)"
)]
pub struct UnknownProfile(pub String);

impl NoiseProfile {
    /// The profile names, mildest first.
    pub fn names() -> &'static [&'static str] {
        &["ideal", "paper", "building", "harsh"]
    }

    /// The profile called `name`.
    pub fn by_name(name: &str) -> Result<Self, UnknownProfile> {
        match name {
            "ideal" => Ok(Self::ideal()),
            "paper" => Ok(Self::paper()),
            "building" => Ok(Self::building()),
            "harsh" => Ok(Self::harsh()),
            _ => Err(UnknownProfile(name.to_owned())),
        }
    }

    /// No noise anywhere. The robot moves during each cycle's sound: a
    /// frozen robot is data no moving robot produces, and a filter that
    /// relates each arrival to its own time (`tdoa-ekf`, the MSU's motion
    /// compensated solver) would see the freeze as a 6 cm error.
    pub fn ideal() -> Self {
        Self {
            name: "ideal".into(),
            ultrasound: UltrasoundNoise {
                motion_during_cycle: true,
                timing_jitter_us: 0.0,
                quantisation_us: 0.0,
                bearing_sigma_deg: 0.0,
                drop_probability: 0.0,
                blocked_reflection_probability: 0.0,
                los_reflection_probability: 0.0,
                reflection_extra_m: [0.0, 0.0],
                id_error_probability: 0.0,
                max_range_m: 12.0,
                survey_sigma_m: 0.0,
                temperature_error_c: 0.0,
                // Collisions are physics, not noise: the same room, but a
                // collision never yields a wrong detection.
                collisions: CollisionModel {
                    misdecode_probability: 0.0,
                    ..CollisionModel::paper()
                },
                air: Air::default(),
            },
            encoders: EncoderNoise {
                left_radius_error: 0.0,
                right_radius_error: 0.0,
                wheel_base_error: 0.0,
                slip_sigma: 0.0,
                slip_per_rad_s: 0.0,
            },
            gyro: GyroNoise {
                bias_sigma_deg_s: 0.0,
                bias_walk_deg_s_sqrt_s: 0.0,
                white_sigma_deg_s: 0.0,
                scale_error: 0.0,
                rate_hz: 100.0,
            },
            obstacles: ObstacleNoise {
                ultrasonic_sigma_m: 0.0,
                ir_sigma_m: 0.0,
                dropout_probability: 0.0,
            },
            clocks: ClockNoise {
                cell_offset_sigma_ms: 0.0,
                cell_drift_sigma_ppm: 0.0,
                net_delay_us: 0.0,
                net_jitter_us: 0.0,
                net_asymmetry_sigma_us: 0.0,
                msu_offset_sigma_ms: 0.0,
                msu_drift_sigma_ppm: 0.0,
            },
            air_sensors: AirSensors::default(),
        }
    }

    /// Calibrated against the ICKON paper's Tables 1-2 (`ickon-akf`, 10 tours of
    /// `route-1` and `route-2`: mean error 78 / 63 mm, 81 / 86 % under 100 mm).
    ///
    /// Physical values first, from data sheets and the papers' hardware: 1 us
    /// time stamps; a Pioneer 3-DX with a 0.5 % left/right wheel mismatch and
    /// a 1.5 % wheel-base error, 1 % slip plus 2 % per rad/s of turn rate; a
    /// low-cost MEMS gyro (0.5 deg/s bias, 0.01 deg/s/sqrt(s) walk, 0.1 deg/s
    /// white noise at 100 Hz, 0.5 % scale error); 20 ppm crystals in the MSU
    /// and the cells, whose clocks start up to 50 ms off; an Ethernet site
    /// network of 100 us one way plus 50 us mean queueing, with a path
    /// asymmetry of 40 us per cell (so the cells' own synchronisation, run
    /// in the engine, leaves the 20 us residual the calibration below was
    /// made with); the air 1 degC off the site's
    /// temperature; obstacle rangers with 1 cm / 5 mm noise.
    ///
    /// The free parameters were then set by running `ickon eval --profile
    /// paper --estimator ickon-akf --route route-1|route-2` for seeds 1-4
    /// and moving them until every seed's mean rows fell inside the paper's
    /// range with a margin (50-110 mm, 75-95 % under 100 mm): detection
    /// jitter 70 us (between one and three 25 us carrier periods; first set
    /// to 60 us with a one-slot-per-transmitter schedule, raised when the
    /// central unit's colouring scheduler made cycles 30 % shorter and the
    /// means fell under 50 mm on two seeds), transmitter
    /// survey error 1 cm per axis (2 cm made the result depend too much on
    /// one seed's draw), 2 % of direct paths replaced by a reflection, 30 %
    /// of blocked transmitters heard by a reflection 5-150 cm longer, 5 %
    /// drops, 1 % id errors, and a 15 deg blur on the bearing that picks the
    /// first receiver (its beams overlap; 8 deg left the receiver-id heading
    /// too systematic along straight corridors). The measured table is in
    /// the crate README.
    pub fn paper() -> Self {
        Self {
            name: "paper".into(),
            ultrasound: UltrasoundNoise {
                motion_during_cycle: true,
                timing_jitter_us: 70.0,
                quantisation_us: 1.0,
                bearing_sigma_deg: 15.0,
                drop_probability: 0.05,
                blocked_reflection_probability: 0.3,
                los_reflection_probability: 0.02,
                reflection_extra_m: [0.05, 1.5],
                id_error_probability: 0.01,
                max_range_m: 10.0,
                survey_sigma_m: 0.01,
                temperature_error_c: 1.0,
                collisions: CollisionModel::paper(),
                air: Air::default(),
            },
            encoders: EncoderNoise {
                left_radius_error: 0.0025,
                right_radius_error: -0.0025,
                wheel_base_error: 0.015,
                slip_sigma: 0.01,
                slip_per_rad_s: 0.02,
            },
            gyro: GyroNoise {
                bias_sigma_deg_s: 0.5,
                bias_walk_deg_s_sqrt_s: 0.01,
                white_sigma_deg_s: 0.1,
                scale_error: 0.005,
                rate_hz: 100.0,
            },
            obstacles: ObstacleNoise {
                ultrasonic_sigma_m: 0.01,
                ir_sigma_m: 0.005,
                dropout_probability: 0.02,
            },
            clocks: ClockNoise {
                cell_offset_sigma_ms: 50.0,
                cell_drift_sigma_ppm: 20.0,
                net_delay_us: 100.0,
                net_jitter_us: 50.0,
                net_asymmetry_sigma_us: 40.0,
                msu_offset_sigma_ms: 50.0,
                msu_drift_sigma_ppm: 20.0,
            },
            air_sensors: AirSensors::default(),
        }
    }

    /// `paper`'s sensors in the air of a real hall ([`Air::building`]):
    /// the temperature swinging by 10 degrees over the run, a degree
    /// warmer per metre of height, a heater and a cold gate, drafts of
    /// 1 m/s and a gate opened at 240 s. The mean is `paper`'s, a degree
    /// off the site's nominal temperature.
    pub fn building() -> Self {
        let mut p = Self::paper();
        p.name = "building".into();
        p.ultrasound.air = Air::building();
        p
    }

    /// Like `building`, with more reflections, blockage, drops, slip and drift.
    pub fn harsh() -> Self {
        let mut p = Self::paper();
        p.name = "harsh".into();
        p.ultrasound.air = Air::building();
        p.ultrasound.timing_jitter_us = 80.0;
        p.ultrasound.drop_probability = 0.15;
        p.ultrasound.blocked_reflection_probability = 0.7;
        p.ultrasound.los_reflection_probability = 0.1;
        p.ultrasound.reflection_extra_m = [0.05, 3.0];
        p.ultrasound.id_error_probability = 0.03;
        p.ultrasound.temperature_error_c = 3.0;
        p.ultrasound.survey_sigma_m = 0.04;
        // A harder, emptier room: the tail starts higher and dies at half the rate.
        p.ultrasound.collisions.reverb_tail_db = -6.0;
        p.ultrasound.collisions.reverb_decay_db_per_ms = 1.5;
        p.ultrasound.collisions.misdecode_probability = 0.5;
        p.encoders.wheel_base_error = 0.03;
        p.encoders.slip_sigma = 0.03;
        p.encoders.slip_per_rad_s = 0.06;
        p.gyro.bias_walk_deg_s_sqrt_s = 0.05;
        p.gyro.white_sigma_deg_s = 0.3;
        p.obstacles.dropout_probability = 0.1;
        p.clocks.net_asymmetry_sigma_us = 200.0;
        p.clocks.net_jitter_us = 300.0;
        p.clocks.cell_drift_sigma_ppm = 50.0;
        p.clocks.msu_drift_sigma_ppm = 50.0;
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_name_builds_a_profile_of_that_name() {
        for name in NoiseProfile::names() {
            assert_eq!(NoiseProfile::by_name(name).unwrap().name, *name);
        }
        assert!(NoiseProfile::by_name("nice").is_err());
    }
}
