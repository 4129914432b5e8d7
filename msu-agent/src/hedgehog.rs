//! A Marvelmind hedgehog's stream turned into the MSU's inputs, without
//! I/O: bytes as read (stamped with the agent's clock) in, distances to the
//! site's beacons and optionally the kit's own positions out, every
//! problem counted.
//!
//! The kit measures a distance as time of flight times the speed of sound
//! it was set to; [`HedgehogReader`] rescales it to the site's speed of
//! sound (the site file's temperature), so that the kit's setting and the
//! site's need not agree. Only the raw distances (`0x0004`, `0x0084`) and,
//! with `use_kit_positions`, the positions (`0x0001`, `0x0011`, `0x0081`)
//! become inputs. The raw IMU's gyro becomes the robot's gyro only when
//! the configuration states its scale (`gyro_rad_s_per_count`):
//! Marvelmind's open-source parsers (`marvelmind.c`, `marvelmind.py`,
//! `marvelmind_nav`) pass it through as raw counts and state none, so its
//! rate in rad/s is known only to whoever calibrated their hedgehog.

use std::collections::BTreeMap;

use ickon_marvelmind::{Deframer, FrameError, Packet, Position, RawDistances};
use ickon_proto::msg::control::TransmitterEntry;
use ickon_proto::msg::robot::Imu;
use ickon_proto::time::{Duration, Time};

use crate::beacons::{BeaconDistance, BeaconDistances, KitPosition};

/// The `[marvelmind]` block of the MSU configuration file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarvelmindSettings {
    /// The speed of sound the kit was set to, m/s: its distances are
    /// rescaled from it to the site's.
    pub speed_of_sound_m_s: f64,
    /// One-sigma noise of one distance, metres.
    pub range_sigma_m: f64,
    /// Whether the kit's own positions are fused too (as position fixes).
    pub use_kit_positions: bool,
    /// One-sigma noise of one of the kit's positions per axis, metres.
    pub kit_position_sigma_m: f64,
    /// The raw gyro's scale, rad/s per count, as the user measured it for
    /// their hedgehog; `None` (the default): the kit's gyro is not used.
    pub gyro_rad_s_per_count: Option<f64>,
}

/// Speed of sound in dry air at 20 °C, m/s (331.3 m/s at 0 °C times
/// `sqrt(293.15 / 273.15)`): a kit's when its dashboard was left at room
/// temperature.
pub const DEFAULT_KIT_SPEED_OF_SOUND_M_S: f64 = 343.0;

/// Marvelmind's stated accuracy of its distances and positions, ±2 cm,
/// taken as one sigma, metres.
pub const DEFAULT_KIT_SIGMA_M: f64 = 0.02;

impl Default for MarvelmindSettings {
    fn default() -> Self {
        Self {
            speed_of_sound_m_s: DEFAULT_KIT_SPEED_OF_SOUND_M_S,
            range_sigma_m: DEFAULT_KIT_SIGMA_M,
            use_kit_positions: false,
            kit_position_sigma_m: DEFAULT_KIT_SIGMA_M,
            gyro_rad_s_per_count: None,
        }
    }
}

/// Where the kit's beacon positions may differ from the site file's
/// before a warning, metres: five of the kit's stated sigmas, beyond what
/// its own survey noise explains; a difference that large is a wrong
/// address or a wrong coordinate in one of the two.
pub const BEACON_DISAGREEMENT_M: f64 = 0.1;

/// Longest time shift a distance may carry, milliseconds: the kit reports
/// distances within its update period (at most a few hundred ms); older
/// than a second is not a measurement of now.
pub const MAX_TIME_SHIFT_MS: u16 = 1000;

/// What the reader has seen since it was made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HedgehogCounters {
    /// Frames whose CRC held.
    pub frames: u64,
    /// Frames refused for their CRC.
    pub bad_crc: u64,
    /// Frames refused for a length their code does not allow.
    pub bad_length: u64,
    /// Bytes skipped as garbage.
    pub garbage_bytes: u64,
    /// Frames that decode to nothing usable (a beacon count that does not
    /// match the length).
    pub undecodable: u64,
    /// Frames of codes that are not read (skipped by their length).
    pub skipped: u64,
    /// Readings of distances handed on.
    pub readings: u64,
    /// Distances handed on.
    pub distances: u64,
    /// Distances to addresses that are not transmitters of the site.
    pub unknown_beacons: u64,
    /// Distances of zero or with an absurd time shift.
    pub absurd_distances: u64,
    /// The kit's positions handed on (with `use_kit_positions`).
    pub kit_positions: u64,
    /// The kit's positions not used (not wanted, or marked unavailable).
    pub kit_positions_unused: u64,
    /// Gyro samples handed on (with `gyro_rad_s_per_count`).
    pub gyro_samples: u64,
}

/// An input for the MSU core.
#[derive(Debug, Clone, PartialEq)]
pub enum HedgehogInput {
    /// Distances to the site's beacons.
    Distances(BeaconDistances),
    /// The kit's own position.
    KitPosition(KitPosition),
    /// The hedgehog's yaw rate (its raw gyro's z axis, scaled as the
    /// configuration states), on the agent's clock.
    Gyro(Imu),
}

/// Something to log (at a bounded rate): its kind and what it was.
pub type HedgehogProblem = (&'static str, String);

/// The hedgehog's stream, read.
#[derive(Debug)]
pub struct HedgehogReader {
    deframer: Deframer,
    settings: MarvelmindSettings,
    /// Kit distance to site distance.
    scale: f64,
    beacons: BTreeMap<u32, [f64; 3]>,
    counters: HedgehogCounters,
}

impl HedgehogReader {
    /// A reader for a site whose speed of sound is `site_speed_of_sound_m_s`
    /// and whose transmitters (the kit's stationary beacons, by address)
    /// are `beacons`.
    pub fn new(
        settings: MarvelmindSettings,
        site_speed_of_sound_m_s: f64,
        beacons: &[TransmitterEntry],
    ) -> Self {
        Self {
            deframer: Deframer::new(),
            settings,
            scale: site_speed_of_sound_m_s / settings.speed_of_sound_m_s,
            beacons: beacons
                .iter()
                .map(|b| (b.tx_id, [b.x_m, b.y_m, b.z_m]))
                .collect(),
            counters: HedgehogCounters::default(),
        }
    }

    /// What it has seen so far.
    pub fn counters(&self) -> HedgehogCounters {
        let d = self.deframer.stats();
        HedgehogCounters {
            frames: d.frames,
            bad_crc: d.bad_crc,
            bad_length: d.bad_length,
            garbage_bytes: d.garbage_bytes,
            ..self.counters
        }
    }

    /// Reads `bytes`, read at `now` on the agent's clock: the inputs they
    /// complete, and the problems met (already counted).
    pub fn feed(&mut self, now: Time, bytes: &[u8]) -> (Vec<HedgehogInput>, Vec<HedgehogProblem>) {
        let mut frames = Vec::new();
        let mut problems = Vec::new();
        self.deframer.feed(bytes, |f| match f {
            Ok(frame) => frames.push(frame),
            Err(e) => problems.push((frame_problem(&e), e.to_string())),
        });
        let mut inputs = Vec::new();
        for frame in frames {
            match Packet::decode(&frame) {
                Ok(Some(packet)) => self.on_packet(now, packet, &mut inputs, &mut problems),
                Ok(None) => self.counters.skipped += 1,
                Err(e) => {
                    self.counters.undecodable += 1;
                    problems.push(("undecodable frame", e.to_string()));
                }
            }
        }
        (inputs, problems)
    }

    fn on_packet(
        &mut self,
        now: Time,
        packet: Packet,
        inputs: &mut Vec<HedgehogInput>,
        problems: &mut Vec<HedgehogProblem>,
    ) {
        match packet {
            Packet::RawDistances(d) => {
                if let Some(reading) = self.distances(now, &d, problems) {
                    self.counters.readings += 1;
                    self.counters.distances += reading.distances.len() as u64;
                    inputs.push(HedgehogInput::Distances(reading));
                }
            }
            Packet::Position(p) => match self.kit_position(now, &p) {
                Some(k) => {
                    self.counters.kit_positions += 1;
                    inputs.push(HedgehogInput::KitPosition(k));
                }
                None => self.counters.kit_positions_unused += 1,
            },
            Packet::BeaconPositions(list) => {
                for b in list {
                    let kit_m = [b.x_mm, b.y_mm, b.z_mm].map(|v| f64::from(v) / 1000.0);
                    let Some(site_m) = self.beacons.get(&u32::from(b.address)) else {
                        problems.push((
                            "beacon position",
                            format!("the kit has beacon {}, which the site has not", b.address),
                        ));
                        continue;
                    };
                    let off_m = (0..3)
                        .map(|k| (kit_m[k] - site_m[k]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    if off_m > BEACON_DISAGREEMENT_M {
                        problems.push((
                            "beacon position",
                            format!(
                                "beacon {} is at {kit_m:?} m for the kit but {site_m:?} m in the site file ({off_m:.2} m apart; the site file is used)",
                                b.address
                            ),
                        ));
                    }
                }
            }
            // The raw gyro with a stated scale (see the module's doc). The
            // hedgehog lies flat on the robot: its z axis is the robot's
            // vertical, counter-clockwise positive as the robot's gyro.
            Packet::RawImu(imu) => match self.settings.gyro_rad_s_per_count {
                Some(scale) => {
                    self.counters.gyro_samples += 1;
                    inputs.push(HedgehogInput::Gyro(Imu {
                        stamp: now,
                        gyro_z_rad_s: f64::from(imu.gyro[2]) * scale,
                    }));
                }
                None => self.counters.skipped += 1,
            },
            // The kit's IMU fusion, quality and telemetry: not inputs.
            Packet::FusedImu(_) | Packet::Quality(_) | Packet::Telemetry(_) => {
                self.counters.skipped += 1;
            }
        }
    }

    /// The reading of `d`: each slot with a beacon address, checked, in
    /// metres at the site's speed of sound.
    fn distances(
        &mut self,
        now: Time,
        d: &RawDistances,
        problems: &mut Vec<HedgehogProblem>,
    ) -> Option<BeaconDistances> {
        if d.time_shift_ms > MAX_TIME_SHIFT_MS {
            let n = d.distances.iter().filter(|s| s.beacon != 0).count();
            self.counters.absurd_distances += n as u64;
            problems.push((
                "absurd distance",
                format!("time shift of {} ms", d.time_shift_ms),
            ));
            return None;
        }
        let mut distances = Vec::new();
        for slot in d.distances.iter().filter(|s| s.beacon != 0) {
            let tx_id = u32::from(slot.beacon);
            if !self.beacons.contains_key(&tx_id) {
                self.counters.unknown_beacons += 1;
                problems.push((
                    "unknown beacon",
                    format!("beacon {tx_id} is not a transmitter of the site"),
                ));
            } else if slot.distance_mm == 0 {
                self.counters.absurd_distances += 1;
                problems.push(("absurd distance", format!("beacon {tx_id}: 0 mm")));
            } else {
                distances.push(BeaconDistance {
                    tx_id,
                    distance_m: f64::from(slot.distance_mm) / 1000.0 * self.scale,
                    sigma_m: self.settings.range_sigma_m,
                });
            }
        }
        (!distances.is_empty()).then(|| BeaconDistances {
            stamp: now - Duration::from_millis(i64::from(d.time_shift_ms)),
            distances,
        })
    }

    /// The kit's position `p` as an input, when wanted and available.
    fn kit_position(&self, now: Time, p: &Position) -> Option<KitPosition> {
        if !(self.settings.use_kit_positions && p.available()) {
            return None;
        }
        // The position's own time is the hedgehog's, on a clock the agent
        // does not know; the kit writes it as soon as it is computed.
        Some(KitPosition {
            stamp: now,
            x_m: f64::from(p.x_mm) / 1000.0,
            y_m: f64::from(p.y_mm) / 1000.0,
            sigma_m: self.settings.kit_position_sigma_m,
        })
    }
}

fn frame_problem(e: &FrameError) -> &'static str {
    match e {
        FrameError::Garbage { .. } => "garbage",
        FrameError::BadLength { .. } => "bad length",
        FrameError::BadCrc { .. } => "bad CRC",
    }
}

#[cfg(test)]
mod tests;
