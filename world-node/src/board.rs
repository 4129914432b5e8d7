//! An emulated board of the ICKON device protocol (`docs/device-protocol.md`)
//! as a sans-IO state machine: it answers the host as a board would, keeps
//! its own clock (an offset, a drift and a timing jitter against the time
//! it is fed), fires armed bursts when its clock says so, frames arrivals
//! the world heard, and misbehaves on request (garbage on the line, frames
//! dropped, a board that stops answering). `ickon emulate` drives it over
//! a pseudo-terminal or TCP; the tests drive it directly.
//!
//! Times fed in are nanoseconds on the emulation's reference clock (the
//! true time of a simulation); the board's clock starts at
//! [`BoardSpec::clock_offset_ns`] when the board starts and runs
//! [`BoardSpec::drift_ppm`] fast.

use ickon_device::message::{MAX_ARRIVALS_PER_FRAME, capability};
use ickon_device::{
    BoardArrival, BoardKind, Decoder, Encoder, Identify, Message, NO_TEMPERATURE, RefusedReason,
    VERSION,
};
use rand_chacha::ChaCha8Rng;

use ickon_sim::air::AirField;
use ickon_sim::air_sensor::AirSensor;
use ickon_sim::rng::{chance, normal, stream};

/// An `Arm` closer than this to its time is refused as too late, nanoseconds
/// (a board needs a moment to load its timer).
pub const ARM_LEAD_NS: i64 = 200_000;
/// Armed bursts a board holds.
pub const ARMED_SLOTS: usize = 32;

/// How an emulated board misbehaves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BoardFaults {
    /// Chance that a frame sent is preceded by a burst of random bytes.
    pub garbage: f64,
    /// Chance that a frame is not sent at all.
    pub drop: f64,
    /// The board stops answering (and firing) this long after it starts, nanoseconds.
    pub mute_after_ns: Option<i64>,
}

/// What an emulated board is.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardSpec {
    /// Its identity (kind, channels, ...).
    pub identity: Identify,
    /// Its clock at start, nanoseconds.
    pub clock_offset_ns: i64,
    /// How fast its clock runs against the reference, ppm.
    pub drift_ppm: f64,
    /// Standard deviation of its timing (when a burst leaves, when an
    /// arrival is stamped), nanoseconds.
    pub jitter_ns: f64,
    /// Faults.
    pub faults: BoardFaults,
    /// Seed of its random draws.
    pub seed: u64,
    /// Its air temperature sensor, if it has one.
    pub air: Option<BoardAir>,
}

/// The air temperature sensor of an emulated board and the air it reads.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardAir {
    /// The sensor.
    pub sensor: AirSensor,
    /// The air.
    pub field: AirField,
    /// The reference time at which the air's run starts, nanoseconds.
    pub start_ns: i64,
}

impl BoardAir {
    /// A reading at reference time `t_ns`, in the protocol's 0.01 degree
    /// ([`NO_TEMPERATURE`] when the sensor has none).
    fn read_cdeg_c(&mut self, t_ns: i64) -> i16 {
        let t_s = (t_ns - self.start_ns) as f64 * 1e-9;
        let c = self.sensor.read(&self.field, t_s);
        if c.is_nan() {
            NO_TEMPERATURE
        } else {
            // Beyond the field's width the sensor saturates.
            (c * 100.0).round().clamp(-32_767.0, 32_767.0) as i16
        }
    }
}

impl BoardSpec {
    /// A transmitter board driving `tx_ids`.
    pub fn transmitter(tx_ids: &[u32], seed: u64) -> Self {
        Self::new(
            BoardKind::Transmitter,
            capability::FIRE | capability::HEALTH,
            tx_ids.iter().map(|&t| i64::from(t)).collect(),
            seed,
        )
    }

    /// A receiver board with `receivers` receivers evenly spaced from 0
    /// degrees, angles in (-180, 180] degrees.
    pub fn receiver(receivers: u8, seed: u64) -> Self {
        let n = i64::from(receivers.max(1));
        Self::new(
            BoardKind::Receiver,
            capability::ARRIVALS | capability::HEALTH,
            (0..n)
                .map(|i| i * 36_000 / n)
                .map(|a| if a > 18_000 { a - 36_000 } else { a })
                .collect(),
            seed,
        )
    }

    /// The same board with an air temperature sensor.
    pub fn with_air_sensor(mut self, air: BoardAir) -> Self {
        self.identity.capabilities |= capability::AIR_TEMPERATURE;
        self.air = Some(air);
        self
    }

    /// The same board reporting the robot's wheel ticks and gyro too.
    pub fn with_motion(mut self) -> Self {
        self.identity.capabilities |= capability::WHEEL_TICKS | capability::IMU;
        self
    }

    fn new(kind: BoardKind, capabilities: u16, channels: Vec<i64>, seed: u64) -> Self {
        Self {
            identity: Identify {
                version: VERSION,
                kind,
                capabilities,
                serial: (seed & 0xFFFF_FFFF) as u32,
                firmware: 0x0100,
                channels,
            },
            clock_offset_ns: 1_000_000_000,
            drift_ppm: 0.0,
            jitter_ns: 0.0,
            faults: BoardFaults::default(),
            seed,
            air: None,
        }
    }
}

/// A burst the board fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emission {
    /// Transmitter.
    pub tx_id: u32,
    /// When it left the transducer, reference clock, nanoseconds.
    pub reference_ns: i64,
}

#[derive(Debug, Clone, Copy)]
struct ArmedBurst {
    burst: u16,
    tx_id: u32,
    fire_at_board_ns: u64,
}

/// An emulated board.
#[derive(Debug)]
pub struct EmulatedBoard {
    spec: BoardSpec,
    start_ns: i64,
    rng: ChaCha8Rng,
    encoder: Encoder,
    decoder: Decoder,
    armed: Vec<ArmedBurst>,
    group: u16,
    /// Frames received that it could not read.
    pub refused: u64,
}

impl EmulatedBoard {
    /// A board that starts (its clock at its offset) at reference time `start_ns`.
    pub fn new(spec: BoardSpec, start_ns: i64) -> Self {
        let rng = stream(spec.seed, "emulated-board");
        Self {
            spec,
            start_ns,
            rng,
            encoder: Encoder::new(),
            decoder: Decoder::new(),
            armed: Vec::new(),
            group: 0,
            refused: 0,
        }
    }

    /// What the board is.
    pub fn spec(&self) -> &BoardSpec {
        &self.spec
    }

    /// The board's clock at reference time `t_ns` (never below 0).
    pub fn board_ns(&self, t_ns: i64) -> u64 {
        let since = (t_ns - self.start_ns) as f64;
        let b = self.spec.clock_offset_ns as f64 + since * (1.0 + self.spec.drift_ppm * 1e-6);
        b.max(0.0) as u64
    }

    /// The reference time at which the board's clock reads `board_ns`.
    pub fn reference_ns(&self, board_ns: u64) -> i64 {
        let since = (board_ns as f64 - self.spec.clock_offset_ns as f64)
            / (1.0 + self.spec.drift_ppm * 1e-6);
        self.start_ns.saturating_add(since as i64)
    }

    fn muted(&self, t_ns: i64) -> bool {
        self.spec
            .faults
            .mute_after_ns
            .is_some_and(|m| t_ns - self.start_ns >= m)
    }

    fn jitter(&mut self) -> i64 {
        normal(&mut self.rng, self.spec.jitter_ns) as i64
    }

    /// One frame as sent, with the faults applied.
    fn send(&mut self, message: &Message, out: &mut Vec<u8>) {
        let frame = self.encoder.frame(message);
        if chance(&mut self.rng, self.spec.faults.drop) {
            return;
        }
        if chance(&mut self.rng, self.spec.faults.garbage) {
            let n = 1 + (rand::Rng::random::<u8>(&mut self.rng) % 40) as usize;
            out.extend((0..n).map(|_| rand::Rng::random::<u8>(&mut self.rng)));
        }
        out.extend(frame);
    }

    /// Bytes from the host at reference time `t_ns`: the board's answers.
    pub fn on_bytes(&mut self, t_ns: i64, bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        if self.muted(t_ns) {
            return out;
        }
        for decoded in self.decoder.feed(bytes) {
            let Ok((seq, message)) = decoded else {
                self.refused += 1;
                continue;
            };
            self.on_message(t_ns, seq, message, &mut out);
        }
        out
    }

    fn on_message(&mut self, t_ns: i64, seq: u8, message: Message, out: &mut Vec<u8>) {
        let refuse = |msg_type: u8, reason| Message::Refused {
            msg_type,
            seq,
            reason,
        };
        match message {
            Message::Hello {
                min_version,
                max_version,
            } => {
                let reply = if (min_version..=max_version).contains(&VERSION) {
                    Message::Identify(self.spec.identity.clone())
                } else {
                    refuse(0x01, RefusedReason::UnsupportedVersion)
                };
                self.send(&reply, out);
            }
            Message::ClockRequest { exchange } => {
                let t2_board_ns = self.board_ns(t_ns);
                let reply = Message::ClockReply {
                    exchange,
                    t2_board_ns,
                    // The emulation answers at once: a real board's
                    // turnaround shows up as t3 - t2.
                    t3_board_ns: t2_board_ns,
                };
                self.send(&reply, out);
            }
            Message::Arm {
                burst,
                tx_id,
                fire_at_board_ns,
            } => {
                let reason = if self.spec.identity.kind != BoardKind::Transmitter {
                    Some(RefusedReason::UnknownType)
                } else if !self.spec.identity.channels.contains(&i64::from(tx_id)) {
                    Some(RefusedReason::UnknownTransmitter)
                } else if fire_at_board_ns < self.board_ns(t_ns + ARM_LEAD_NS) {
                    Some(RefusedReason::TooLate)
                } else if self.armed.len() >= ARMED_SLOTS {
                    Some(RefusedReason::Busy)
                } else {
                    None
                };
                match reason {
                    Some(r) => self.send(&refuse(0x03, r), out),
                    None => self.armed.push(ArmedBurst {
                        burst,
                        tx_id,
                        fire_at_board_ns,
                    }),
                }
            }
            Message::HealthRequest => {
                let health = Message::Health {
                    supply_mv: 12_000,
                    temperature_cdeg_c: 3_150,
                    faults: 0,
                };
                self.send(&health, out);
            }
            Message::AirTemperatureRequest => {
                let board_ns = self.board_ns(t_ns);
                let reply = match self.spec.air.as_mut() {
                    Some(air) => Message::AirTemperature {
                        board_ns,
                        temperature_cdeg_c: air.read_cdeg_c(t_ns),
                    },
                    None => refuse(0x05, RefusedReason::UnknownType),
                };
                self.send(&reply, out);
            }
            other => {
                // A board message sent to a board.
                self.send(&refuse(other.type_byte(), RefusedReason::UnknownType), out);
            }
        }
    }

    /// The reference time of the next armed burst, if any.
    pub fn next_fire_ns(&self) -> Option<i64> {
        self.armed
            .iter()
            .map(|a| self.reference_ns(a.fire_at_board_ns))
            .min()
    }

    /// Fires every burst due by reference time `t_ns`: the `Fired` frames
    /// and the emissions (at the reference time they really left, jitter
    /// included).
    pub fn fire_due(&mut self, t_ns: i64) -> (Vec<u8>, Vec<Emission>) {
        let mut out = Vec::new();
        let mut emissions = Vec::new();
        let now_board = self.board_ns(t_ns);
        let (due, later): (Vec<_>, Vec<_>) = self
            .armed
            .iter()
            .partition(|a| a.fire_at_board_ns <= now_board);
        self.armed = later;
        if self.muted(t_ns) {
            return (out, emissions);
        }
        for a in due {
            let left_ns = self.reference_ns(a.fire_at_board_ns) + self.jitter();
            emissions.push(Emission {
                tx_id: a.tx_id,
                reference_ns: left_ns,
            });
            let fired = Message::Fired {
                burst: a.burst,
                tx_id: a.tx_id,
                fired_board_ns: self.board_ns(left_ns),
            };
            self.send(&fired, &mut out);
        }
        (out, emissions)
    }

    /// Frames cumulative wheel encoder counts sampled at reference time
    /// `t_ns` (a board with [`capability::WHEEL_TICKS`]).
    pub fn wheel_ticks(&mut self, t_ns: i64, left: i64, right: i64) -> Vec<u8> {
        let mut out = Vec::new();
        if !self.muted(t_ns) {
            let jitter_ns = self.jitter();
            let board_ns = self.board_ns(t_ns + jitter_ns);
            self.send(
                &Message::WheelTicks {
                    board_ns,
                    left,
                    right,
                },
                &mut out,
            );
        }
        out
    }

    /// Frames a yaw-rate sample taken at reference time `t_ns` (a board
    /// with [`capability::IMU`]); rates beyond the message's range are
    /// clipped to it, as a saturated gyro reads.
    pub fn imu(&mut self, t_ns: i64, gyro_z_rad_s: f64) -> Vec<u8> {
        let mut out = Vec::new();
        if !self.muted(t_ns) {
            let jitter_ns = self.jitter();
            let board_ns = self.board_ns(t_ns + jitter_ns);
            let urad_s = (gyro_z_rad_s * 1e6).round();
            let gyro_z_urad_s = urad_s.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
            self.send(
                &Message::ImuSample {
                    board_ns,
                    gyro_z_urad_s,
                },
                &mut out,
            );
        }
        out
    }

    /// Frames the arrivals of one cycle heard at reference times
    /// `(tx_id, receiver, t_ns)`, stamped on the board's clock with its
    /// jitter, as one group.
    pub fn arrivals(&mut self, t_ns: i64, heard: &[(u32, u8, i64)]) -> Vec<u8> {
        let mut out = Vec::new();
        if self.muted(t_ns) {
            return out;
        }
        self.group = self.group.wrapping_add(1);
        let stamped: Vec<BoardArrival> = heard
            .iter()
            .map(|&(tx_id, receiver, at)| {
                let j = self.jitter();
                BoardArrival {
                    tx_id,
                    receiver,
                    board_ns: self.board_ns(at + j),
                    quality: 200,
                }
            })
            .collect();
        let chunks: Vec<&[BoardArrival]> = if stamped.is_empty() {
            vec![&[]]
        } else {
            stamped.chunks(MAX_ARRIVALS_PER_FRAME).collect()
        };
        let n = chunks.len();
        for (i, chunk) in chunks.into_iter().enumerate() {
            let m = Message::Arrivals {
                group: self.group,
                last: i + 1 == n,
                arrivals: chunk.to_vec(),
            };
            self.send(&m, &mut out);
        }
        out
    }
}
