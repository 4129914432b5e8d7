//! The messages of protocol version 1 and their bodies (the optional
//! ones behind a capability bit).
//!
//! A body is a 3-byte header, `version` (1), `type`, `seq` (the sender's
//! frame counter, wrapping, so that the other side can count lost frames),
//! then the type's fields, little-endian, packed, nothing after them. Types
//! under 0x80 go from the host to a board, from 0x80 up from a board to the
//! host. A body with trailing bytes, a short one, an unknown type or
//! another version is refused, never guessed at.

/// The protocol version this crate speaks.
pub const VERSION: u8 = 1;

/// Bytes of the header: version, type, sequence number.
pub const HEADER_LEN: usize = 3;

/// Arrivals one frame can carry (a group may span frames).
pub const MAX_ARRIVALS_PER_FRAME: usize = 17;

/// Channels an identity can list (transmitters or receivers).
pub const MAX_CHANNELS: usize = 59;

/// What a board is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardKind {
    /// Fires the transmitters of a cell (kind byte 1).
    Transmitter,
    /// A robot's receiver ring (kind byte 2).
    Receiver,
}

impl BoardKind {
    fn byte(self) -> u8 {
        match self {
            BoardKind::Transmitter => 1,
            BoardKind::Receiver => 2,
        }
    }

    /// The name used in logs and the docs.
    pub fn name(self) -> &'static str {
        match self {
            BoardKind::Transmitter => "transmitter board",
            BoardKind::Receiver => "receiver board",
        }
    }
}

/// Capability bits of [`Identify::capabilities`].
pub mod capability {
    /// Fires bursts on `Arm` and reports `Fired`.
    pub const FIRE: u16 = 1 << 0;
    /// Reports `Arrivals`.
    pub const ARRIVALS: u16 = 1 << 1;
    /// Reports `WheelTicks`.
    pub const WHEEL_TICKS: u16 = 1 << 2;
    /// Reports `ImuSample`.
    pub const IMU: u16 = 1 << 3;
    /// Answers `HealthRequest`.
    pub const HEALTH: u16 = 1 << 4;
    /// Has an air temperature sensor: answers `AirTemperatureRequest`.
    /// Optional: a board without a sensor leaves the bit clear and is never
    /// asked, a host that does not know the bit never asks.
    pub const AIR_TEMPERATURE: u16 = 1 << 5;
}

/// [`Message::AirTemperature::temperature_cdeg_c`] of a sensor that has no
/// valid reading (failed, not yet settled): the host takes it as not a
/// number.
pub const NO_TEMPERATURE: i16 = i16::MIN;

/// A board's answer to `Hello`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identify {
    /// The protocol version the board will speak (within the host's range).
    pub version: u8,
    /// What the board is.
    pub kind: BoardKind,
    /// [`capability`] bits.
    pub capabilities: u16,
    /// The board's serial number.
    pub serial: u32,
    /// Firmware version, major in the high byte.
    pub firmware: u16,
    /// Transmitter board: the transmitter ids it drives, in channel order.
    /// Receiver board: each receiver's angle, 0.01 degree counter-clockwise
    /// from the robot's forward axis, in receiver order. At most
    /// [`MAX_CHANNELS`].
    pub channels: Vec<i64>,
}

/// One arrival as a receiver board reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardArrival {
    /// Transmitter id decoded from the burst.
    pub tx_id: u32,
    /// The receiver that heard it first (index into the identity's channels).
    pub receiver: u8,
    /// Time of arrival on the board's clock, nanoseconds.
    pub board_ns: u64,
    /// Signal quality, 0 (barely detected) to 255 (clean).
    pub quality: u8,
}

/// Why a board refused a message ([`Message::Refused`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefusedReason {
    /// Unknown message type (1).
    UnknownType,
    /// Wrong length for the type (2).
    BadLength,
    /// The burst's time has passed or is too close (3).
    TooLate,
    /// The transmitter is not on this board (4).
    UnknownTransmitter,
    /// No room for another armed burst (5).
    Busy,
    /// No protocol version in the host's range (6).
    UnsupportedVersion,
    /// A reason this version does not know (kept as sent).
    Other(u8),
}

impl RefusedReason {
    fn byte(self) -> u8 {
        match self {
            RefusedReason::UnknownType => 1,
            RefusedReason::BadLength => 2,
            RefusedReason::TooLate => 3,
            RefusedReason::UnknownTransmitter => 4,
            RefusedReason::Busy => 5,
            RefusedReason::UnsupportedVersion => 6,
            RefusedReason::Other(b) => b,
        }
    }

    fn from_byte(b: u8) -> Self {
        match b {
            1 => RefusedReason::UnknownType,
            2 => RefusedReason::BadLength,
            3 => RefusedReason::TooLate,
            4 => RefusedReason::UnknownTransmitter,
            5 => RefusedReason::Busy,
            6 => RefusedReason::UnsupportedVersion,
            b => RefusedReason::Other(b),
        }
    }
}

/// Every message of protocol version 1.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// Host -> board 0x01: the host's version range; answered by `Identify`.
    Hello {
        /// Oldest version the host speaks.
        min_version: u8,
        /// Newest version the host speaks.
        max_version: u8,
    },
    /// Host -> board 0x02: a clock exchange; answered by `ClockReply`.
    ClockRequest {
        /// Chosen by the host, echoed.
        exchange: u32,
    },
    /// Host -> board 0x03: fire transmitter `tx_id` when the board's clock reads `fire_at_board_ns`.
    Arm {
        /// Chosen by the host, echoed in `Fired`.
        burst: u16,
        /// Transmitter.
        tx_id: u32,
        /// When, on the board's clock, nanoseconds.
        fire_at_board_ns: u64,
    },
    /// Host -> board 0x04: asks for `Health`.
    HealthRequest,
    /// Host -> board 0x05: asks for `AirTemperature` (only of a board with
    /// [`capability::AIR_TEMPERATURE`]).
    AirTemperatureRequest,
    /// Board -> host 0x81: who the board is.
    Identify(Identify),
    /// Board -> host 0x82: the board's side of a clock exchange.
    ClockReply {
        /// The request's exchange number.
        exchange: u32,
        /// Request received, board clock, nanoseconds.
        t2_board_ns: u64,
        /// Reply sent, board clock, nanoseconds.
        t3_board_ns: u64,
    },
    /// Board -> host 0x83: a burst was fired.
    Fired {
        /// The `Arm`'s burst number.
        burst: u16,
        /// Transmitter.
        tx_id: u32,
        /// When it fired, board clock, nanoseconds.
        fired_board_ns: u64,
    },
    /// Board -> host 0x84: supply, temperature and faults.
    Health {
        /// Supply voltage, millivolts.
        supply_mv: u16,
        /// Board temperature, 0.01 degree Celsius.
        temperature_cdeg_c: i16,
        /// Bit `i`: channel `i` (transducer or receiver) is faulty.
        faults: u32,
    },
    /// Board -> host 0x85: a message was refused.
    Refused {
        /// Its type.
        msg_type: u8,
        /// Its sequence number.
        seq: u8,
        /// Why.
        reason: RefusedReason,
    },
    /// Board -> host 0x86: arrivals of one listening group (a group may span frames).
    Arrivals {
        /// The board's group counter (wrapping).
        group: u16,
        /// This frame ends the group.
        last: bool,
        /// At most [`MAX_ARRIVALS_PER_FRAME`].
        arrivals: Vec<BoardArrival>,
    },
    /// Board -> host 0x87: cumulative wheel encoder ticks.
    WheelTicks {
        /// Sample time, board clock, nanoseconds.
        board_ns: u64,
        /// Left wheel, cumulative.
        left: i64,
        /// Right wheel, cumulative.
        right: i64,
    },
    /// Board -> host 0x88: a yaw-rate gyro sample.
    ImuSample {
        /// Sample time, board clock, nanoseconds.
        board_ns: u64,
        /// Rate about the vertical axis, micro-radians per second, counter-clockwise positive.
        gyro_z_urad_s: i32,
    },
    /// Board -> host 0x89: the air temperature at the board, measured when
    /// asked.
    AirTemperature {
        /// When it was measured, board clock, nanoseconds.
        board_ns: u64,
        /// The air's temperature, 0.01 degree Celsius; [`NO_TEMPERATURE`]
        /// when the sensor has no valid reading.
        temperature_cdeg_c: i16,
    },
}

/// Why a frame's body is not a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum MessageError {
    /// A body shorter than the header.
    #[error("body of {0} bytes is shorter than the header")]
    Truncated(usize),
    /// Another protocol version.
    #[error("protocol version {0} (this host speaks {VERSION})")]
    UnsupportedVersion(u8),
    /// A type this version does not define.
    #[error("unknown message type {0:#04x}")]
    UnknownType(u8),
    /// The type's fields do not fill the body exactly.
    #[error("message type {msg_type:#04x}: {got} payload bytes, expected {want}")]
    BadLength {
        /// The type.
        msg_type: u8,
        /// Payload bytes received.
        got: usize,
        /// Payload bytes the type (and its counts) need.
        want: usize,
    },
    /// A field holds a value the type does not allow.
    #[error("message type {msg_type:#04x}: {what}")]
    BadField {
        /// The type.
        msg_type: u8,
        /// What is wrong.
        what: &'static str,
    },
}

impl Message {
    /// The type byte.
    pub fn type_byte(&self) -> u8 {
        match self {
            Message::Hello { .. } => 0x01,
            Message::ClockRequest { .. } => 0x02,
            Message::Arm { .. } => 0x03,
            Message::HealthRequest => 0x04,
            Message::AirTemperatureRequest => 0x05,
            Message::Identify(_) => 0x81,
            Message::ClockReply { .. } => 0x82,
            Message::Fired { .. } => 0x83,
            Message::Health { .. } => 0x84,
            Message::Refused { .. } => 0x85,
            Message::Arrivals { .. } => 0x86,
            Message::WheelTicks { .. } => 0x87,
            Message::ImuSample { .. } => 0x88,
            Message::AirTemperature { .. } => 0x89,
        }
    }

    /// The body of this message with sequence number `seq`. Lists longer
    /// than a frame holds ([`MAX_CHANNELS`], [`MAX_ARRIVALS_PER_FRAME`])
    /// are cut to it; channel values are cut to their field's width.
    pub fn encode(&self, seq: u8) -> Vec<u8> {
        let mut b = vec![VERSION, self.type_byte(), seq];
        match self {
            Message::Hello {
                min_version,
                max_version,
            } => b.extend([*min_version, *max_version]),
            Message::ClockRequest { exchange } => b.extend(exchange.to_le_bytes()),
            Message::Arm {
                burst,
                tx_id,
                fire_at_board_ns,
            } => {
                b.extend(burst.to_le_bytes());
                b.extend(tx_id.to_le_bytes());
                b.extend(fire_at_board_ns.to_le_bytes());
            }
            Message::HealthRequest | Message::AirTemperatureRequest => {}
            Message::Identify(id) => encode_identify(&mut b, id),
            Message::ClockReply {
                exchange,
                t2_board_ns,
                t3_board_ns,
            } => {
                b.extend(exchange.to_le_bytes());
                b.extend(t2_board_ns.to_le_bytes());
                b.extend(t3_board_ns.to_le_bytes());
            }
            Message::Fired {
                burst,
                tx_id,
                fired_board_ns,
            } => {
                b.extend(burst.to_le_bytes());
                b.extend(tx_id.to_le_bytes());
                b.extend(fired_board_ns.to_le_bytes());
            }
            Message::Health {
                supply_mv,
                temperature_cdeg_c,
                faults,
            } => {
                b.extend(supply_mv.to_le_bytes());
                b.extend(temperature_cdeg_c.to_le_bytes());
                b.extend(faults.to_le_bytes());
            }
            Message::Refused {
                msg_type,
                seq,
                reason,
            } => b.extend([*msg_type, *seq, reason.byte()]),
            Message::Arrivals {
                group,
                last,
                arrivals,
            } => {
                let n = arrivals.len().min(MAX_ARRIVALS_PER_FRAME);
                b.extend(group.to_le_bytes());
                b.push(u8::from(*last));
                b.push(n as u8);
                for a in &arrivals[..n] {
                    b.extend(a.tx_id.to_le_bytes());
                    b.push(a.receiver);
                    b.extend(a.board_ns.to_le_bytes());
                    b.push(a.quality);
                }
            }
            Message::WheelTicks {
                board_ns,
                left,
                right,
            } => {
                b.extend(board_ns.to_le_bytes());
                b.extend(left.to_le_bytes());
                b.extend(right.to_le_bytes());
            }
            Message::ImuSample {
                board_ns,
                gyro_z_urad_s,
            } => {
                b.extend(board_ns.to_le_bytes());
                b.extend(gyro_z_urad_s.to_le_bytes());
            }
            Message::AirTemperature {
                board_ns,
                temperature_cdeg_c,
            } => {
                b.extend(board_ns.to_le_bytes());
                b.extend(temperature_cdeg_c.to_le_bytes());
            }
        }
        b
    }

    /// Decodes a body: its sequence number and message.
    pub fn decode(body: &[u8]) -> Result<(u8, Message), MessageError> {
        let [version, msg_type, seq, payload @ ..] = body else {
            return Err(MessageError::Truncated(body.len()));
        };
        if *version != VERSION {
            return Err(MessageError::UnsupportedVersion(*version));
        }
        let t = *msg_type;
        let fixed = |want: usize| -> Result<Fields<'_>, MessageError> {
            if payload.len() == want {
                Ok(Fields(payload))
            } else {
                Err(MessageError::BadLength {
                    msg_type: t,
                    got: payload.len(),
                    want,
                })
            }
        };
        let m = match t {
            0x01 => {
                let mut f = fixed(2)?;
                Message::Hello {
                    min_version: f.u8(),
                    max_version: f.u8(),
                }
            }
            0x02 => Message::ClockRequest {
                exchange: fixed(4)?.u32(),
            },
            0x03 => {
                let mut f = fixed(14)?;
                Message::Arm {
                    burst: f.u16(),
                    tx_id: f.u32(),
                    fire_at_board_ns: f.u64(),
                }
            }
            0x04 => {
                fixed(0)?;
                Message::HealthRequest
            }
            0x05 => {
                fixed(0)?;
                Message::AirTemperatureRequest
            }
            0x81 => Message::Identify(decode_identify(payload)?),
            0x82 => {
                let mut f = fixed(20)?;
                Message::ClockReply {
                    exchange: f.u32(),
                    t2_board_ns: f.u64(),
                    t3_board_ns: f.u64(),
                }
            }
            0x83 => {
                let mut f = fixed(14)?;
                Message::Fired {
                    burst: f.u16(),
                    tx_id: f.u32(),
                    fired_board_ns: f.u64(),
                }
            }
            0x84 => {
                let mut f = fixed(8)?;
                Message::Health {
                    supply_mv: f.u16(),
                    temperature_cdeg_c: f.u16() as i16,
                    faults: f.u32(),
                }
            }
            0x85 => {
                let mut f = fixed(3)?;
                Message::Refused {
                    msg_type: f.u8(),
                    seq: f.u8(),
                    reason: RefusedReason::from_byte(f.u8()),
                }
            }
            0x86 => decode_arrivals(payload)?,
            0x87 => {
                let mut f = fixed(24)?;
                Message::WheelTicks {
                    board_ns: f.u64(),
                    left: f.u64() as i64,
                    right: f.u64() as i64,
                }
            }
            0x88 => {
                let mut f = fixed(12)?;
                Message::ImuSample {
                    board_ns: f.u64(),
                    gyro_z_urad_s: f.u32() as i32,
                }
            }
            0x89 => {
                let mut f = fixed(10)?;
                Message::AirTemperature {
                    board_ns: f.u64(),
                    temperature_cdeg_c: f.u16() as i16,
                }
            }
            other => return Err(MessageError::UnknownType(other)),
        };
        Ok((*seq, m))
    }
}

fn encode_identify(b: &mut Vec<u8>, id: &Identify) {
    let n = id.channels.len().min(MAX_CHANNELS);
    b.extend([id.version, id.kind.byte()]);
    b.extend(id.capabilities.to_le_bytes());
    b.extend(id.serial.to_le_bytes());
    b.extend(id.firmware.to_le_bytes());
    b.push(n as u8);
    for &c in &id.channels[..n] {
        match id.kind {
            BoardKind::Transmitter => b.extend((c as u32).to_le_bytes()),
            BoardKind::Receiver => b.extend((c as i16).to_le_bytes()),
        }
    }
}

/// Fixed part of `Identify`: version, kind, capabilities, serial, firmware, count.
const IDENTIFY_FIXED: usize = 11;

fn decode_identify(payload: &[u8]) -> Result<Identify, MessageError> {
    let short = MessageError::BadLength {
        msg_type: 0x81,
        got: payload.len(),
        want: IDENTIFY_FIXED,
    };
    let (head, rest) = payload.split_at_checked(IDENTIFY_FIXED).ok_or(short)?;
    let mut f = Fields(head);
    let version = f.u8();
    let kind = match f.u8() {
        1 => BoardKind::Transmitter,
        2 => BoardKind::Receiver,
        _ => {
            return Err(MessageError::BadField {
                msg_type: 0x81,
                what: "unknown board kind",
            });
        }
    };
    let (capabilities, serial, firmware, count) = (f.u16(), f.u32(), f.u16(), f.u8());
    let width = match kind {
        BoardKind::Transmitter => 4,
        BoardKind::Receiver => 2,
    };
    let want = usize::from(count) * width;
    if rest.len() != want {
        return Err(MessageError::BadLength {
            msg_type: 0x81,
            got: payload.len(),
            want: IDENTIFY_FIXED + want,
        });
    }
    let channels = rest
        .chunks_exact(width)
        .map(|c| match kind {
            BoardKind::Transmitter => i64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
            BoardKind::Receiver => i64::from(i16::from_le_bytes([c[0], c[1]])),
        })
        .collect();
    Ok(Identify {
        version,
        kind,
        capabilities,
        serial,
        firmware,
        channels,
    })
}

/// Bytes of one arrival: tx id, receiver, time, quality.
const ARRIVAL_LEN: usize = 14;

fn decode_arrivals(payload: &[u8]) -> Result<Message, MessageError> {
    let bad_length = |want| MessageError::BadLength {
        msg_type: 0x86,
        got: payload.len(),
        want,
    };
    let [g0, g1, flags, count, rest @ ..] = payload else {
        return Err(bad_length(4));
    };
    let want = usize::from(*count) * ARRIVAL_LEN;
    if rest.len() != want {
        return Err(bad_length(4 + want));
    }
    if *flags > 1 {
        return Err(MessageError::BadField {
            msg_type: 0x86,
            what: "flags other than 'last' set",
        });
    }
    let arrivals = rest
        .chunks_exact(ARRIVAL_LEN)
        .map(|c| {
            let mut f = Fields(c);
            BoardArrival {
                tx_id: f.u32(),
                receiver: f.u8(),
                board_ns: f.u64(),
                quality: f.u8(),
            }
        })
        .collect();
    Ok(Message::Arrivals {
        group: u16::from_le_bytes([*g0, *g1]),
        last: *flags == 1,
        arrivals,
    })
}

/// Reads little-endian fields off a payload whose length was checked.
struct Fields<'a>(&'a [u8]);

impl Fields<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0; N];
        // The length was checked before reading: a short read leaves zeros
        // instead of panicking, and cannot happen.
        let n = N.min(self.0.len());
        out[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        out
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
}
