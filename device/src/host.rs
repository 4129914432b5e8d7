//! The host's side of one device link as a sans-IO state machine: the
//! handshake, clock exchanges, armed bursts, arrival groups, health, and
//! everything refused, counted. The adapter feeds it the link's events
//! with the host time they happened at and sends the bytes it returns;
//! [`BoardHost::poll`] says what is due (a `Hello` again, a clock exchange,
//! a health request) and when to call it next.
//!
//! A board that stays silent for [`SILENCE_NS`] is taken to have restarted:
//! its identity and clock are forgotten and the handshake starts again, so
//! a board power-cycled behind a link that stayed up (a serial adapter
//! powered by the host) is found again.

use std::collections::BTreeMap;

use crate::clock::{BoardClock, ClockExchange};
use crate::message::{
    BoardKind, Identify, Message, NO_TEMPERATURE, RefusedReason, VERSION, capability,
};
use crate::stream::{Decoder, Encoder};

/// A `Hello` unanswered this long is sent again, nanoseconds.
pub const HELLO_RETRY_NS: i64 = 1_000_000_000;
/// No valid frame for this long: the board is taken to have restarted.
pub const SILENCE_NS: i64 = 3_000_000_000;
/// Clock exchanges at start (one every [`FAST_EXCHANGE_NS`]) before the
/// steady rate of one per [`EXCHANGE_NS`].
pub const FAST_EXCHANGES: u32 = 8;
/// The interval of the first clock exchanges, nanoseconds.
pub const FAST_EXCHANGE_NS: i64 = 100_000_000;
/// The steady interval of clock exchanges, nanoseconds.
pub const EXCHANGE_NS: i64 = 1_000_000_000;
/// The interval of health requests to a board that answers them, nanoseconds.
pub const HEALTH_NS: i64 = 5_000_000_000;
/// The interval of air temperature requests to a board with a sensor,
/// nanoseconds: the air changes over minutes, a reading a second is plenty.
pub const AIR_TEMPERATURE_NS: i64 = 1_000_000_000;
/// An exchange unanswered this long is forgotten, nanoseconds.
const EXCHANGE_TIMEOUT_NS: i64 = 1_000_000_000;
/// Exchanges awaited at most.
const EXCHANGES_KEPT: usize = 16;
/// Armed bursts remembered at most (a few cycles of a cell's transmitters).
const ARMED_KEPT: usize = 256;
/// An armed burst not reported this long after its time never fired.
const FIRED_TIMEOUT_NS: i64 = 2_000_000_000;
/// A `Fired` time further than this from the armed time is absurd (a board
/// fires on time or refuses), nanoseconds.
pub const MAX_FIRING_ERROR_NS: i64 = 5_000_000;
/// A measurement stamped further than this from the time it arrived is
/// absurd (a board's clock stepped, or nonsense), nanoseconds.
pub const MAX_MEASUREMENT_AGE_NS: i64 = 2_000_000_000;
/// Arrivals one group may collect (a cycle hears a few dozen at most).
const MAX_GROUP: usize = 256;

/// Where the handshake is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HostState {
    /// No link.
    Disconnected,
    /// `Hello` sent, no `Identify` yet.
    AwaitingIdentity,
    /// Identified, clock not known yet.
    Synchronising,
    /// Identified and clock known: in use.
    Ready,
    /// The board is not what this host needs (kind, version, capabilities).
    WrongBoard,
}

impl HostState {
    /// A word for logs and tables.
    pub fn name(self) -> &'static str {
        match self {
            HostState::Disconnected => "disconnected",
            HostState::AwaitingIdentity => "awaiting identity",
            HostState::Synchronising => "synchronising",
            HostState::Ready => "ready",
            HostState::WrongBoard => "wrong board",
        }
    }
}

/// One arrival on the host's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HostArrival {
    /// Transmitter id.
    pub tx_id: u32,
    /// The first receiver to hear it.
    pub receiver: u8,
    /// Time of arrival, host clock, nanoseconds.
    pub host_ns: i64,
    /// Signal quality (0-255).
    pub quality: u8,
}

/// What happened on the link, for the adapter to act on.
#[derive(Debug, Clone, PartialEq)]
pub enum HostEvent {
    /// The board identified itself as what this host needs.
    Identified(Identify),
    /// The board is not what this host needs; the text says why.
    WrongBoard(String),
    /// An armed burst fired.
    Fired {
        /// The tag it was armed with.
        tag: u64,
        /// Transmitter.
        tx_id: u32,
        /// When it fired, host clock, nanoseconds.
        fired_host_ns: i64,
        /// When it was armed to fire, host clock, nanoseconds.
        armed_host_ns: i64,
    },
    /// The board refused an armed burst.
    ArmRefused {
        /// The tag it was armed with.
        tag: u64,
        /// Transmitter.
        tx_id: u32,
        /// Why.
        reason: RefusedReason,
    },
    /// A complete group of arrivals.
    Arrivals {
        /// The board's number of the group (16 bits, wrapping; see
        /// [`crate::GroupSequence`]).
        group: u16,
        /// Its arrivals.
        arrivals: Vec<HostArrival>,
    },
    /// Wheel encoder ticks.
    WheelTicks {
        /// Sample time, host clock, nanoseconds.
        host_ns: i64,
        /// Left wheel, cumulative.
        left: i64,
        /// Right wheel, cumulative.
        right: i64,
    },
    /// A gyro sample.
    Imu {
        /// Sample time, host clock, nanoseconds.
        host_ns: i64,
        /// Yaw rate, rad/s.
        gyro_z_rad_s: f64,
    },
    /// An air temperature reading of the board's sensor, as the board sent
    /// it: whether it is plausible is for its user to judge.
    AirTemperature {
        /// When it was measured, host clock, nanoseconds.
        host_ns: i64,
        /// Degrees Celsius; not a number when the sensor had no valid reading.
        temperature_c: f64,
    },
    /// Something from the board was refused: a short kind (for a
    /// rate-limited log) and the detail.
    Refused(&'static str, String),
    /// The board was silent for [`SILENCE_NS`]: handshake again.
    Silent,
}

/// Counts of one link's life.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct HostCounters {
    /// Bursts armed.
    pub armed: u64,
    /// Bursts reported fired.
    pub fired: u64,
    /// Bursts the board refused.
    pub arm_refused: u64,
    /// Bursts armed but never reported.
    pub never_fired: u64,
    /// Arrival groups handed on.
    pub groups: u64,
    /// Clock exchanges taken.
    pub exchanges: u64,
    /// Frames or messages refused (protocol errors, absurd or unexpected content).
    pub refused: u64,
    /// Frames lost (gaps in the board's sequence numbers).
    pub lost: u64,
    /// Handshakes started.
    pub handshakes: u64,
}

/// The state of a link's board, for `ickon admin` and the map.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceReport {
    /// Handshake state.
    pub state: HostState,
    /// The board's identity, when known.
    pub identity: Option<Identify>,
    /// `board - host`, nanoseconds, when known.
    pub clock_offset_ns: Option<f64>,
    /// The board clock's drift against the host's, when known.
    pub clock_drift: Option<f64>,
    /// Half the quickest clock exchange's round trip, nanoseconds.
    pub clock_bound_ns: Option<f64>,
    /// The last `Health`: supply mV, temperature 0.01 C, fault bits.
    pub health: Option<(u16, i16, u32)>,
    /// The last air temperature reading, degrees Celsius (not a number:
    /// the sensor had no valid reading), when the board has a sensor.
    pub air_temperature_c: Option<f64>,
    /// Counters.
    pub counters: HostCounters,
}

impl DeviceReport {
    /// The board's state in a line for an operator: its handshake state,
    /// what it is, how well its clock is known, and what was refused or lost.
    pub fn summary(&self) -> String {
        let mut out = self.state.name().to_string();
        if let Some(id) = &self.identity {
            out.push_str(&format!(
                ", serial {} firmware {}.{}",
                id.serial,
                id.firmware >> 8,
                id.firmware & 0xFF
            ));
        }
        if let Some(bound_ns) = self.clock_bound_ns {
            out.push_str(&format!(", clock within {:.0} us", bound_ns / 1e3));
        }
        if let Some(drift) = self.clock_drift {
            out.push_str(&format!(", drift {:.1} ppm", drift * 1e6));
        }
        if let Some((mv, cdeg, faults)) = self.health {
            out.push_str(&format!(
                ", supply {:.2} V, {:.1} C",
                f64::from(mv) / 1e3,
                f64::from(cdeg) / 100.0
            ));
            if faults != 0 {
                out.push_str(&format!(", faults {faults:#b}"));
            }
        }
        if let Some(t) = self.air_temperature_c {
            out.push_str(&format!(", air {t:.1} C"));
        }
        let c = &self.counters;
        if c.refused + c.lost + c.arm_refused + c.never_fired > 0 {
            out.push_str(&format!(
                ", refused {} frames, lost {}, bursts refused {}, never fired {}",
                c.refused, c.lost, c.arm_refused, c.never_fired
            ));
        }
        out
    }
}

/// Why a burst could not be armed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ArmError {
    /// The board is not ready (not identified, or its clock unknown).
    #[error("board not ready ({0})")]
    NotReady(&'static str),
    /// The board does not drive this transmitter.
    #[error("transmitter {0} is not on the board")]
    UnknownTransmitter(u32),
    /// The time does not map onto the board's clock.
    #[error("time outside the board's clock")]
    OutOfRange,
}

#[derive(Debug, Clone, Copy)]
struct Armed {
    tag: u64,
    /// The sequence number of the `Arm` frame (a `Refused` names it).
    seq: u8,
    tx_id: u32,
    host_ns: i64,
}

#[derive(Debug)]
struct Group {
    id: u16,
    arrivals: Vec<HostArrival>,
}

/// The host's side of one link to a board of kind `expected`.
#[derive(Debug)]
pub struct BoardHost {
    expected: BoardKind,
    state: HostState,
    encoder: Encoder,
    decoder: Decoder,
    clock: BoardClock,
    identity: Option<Identify>,
    health: Option<(u16, i16, u32)>,
    air_temperature_c: Option<f64>,
    hello_at: i64,
    last_heard: i64,
    next_exchange: i64,
    next_health: i64,
    next_air: i64,
    exchanges_sent: u32,
    exchange_id: u32,
    awaiting: BTreeMap<u32, i64>,
    burst_id: u16,
    armed: BTreeMap<u16, Armed>,
    group: Option<Group>,
    counters: HostCounters,
}

impl BoardHost {
    /// A host for a board of kind `expected`, not connected.
    pub fn new(expected: BoardKind) -> Self {
        Self {
            expected,
            state: HostState::Disconnected,
            encoder: Encoder::new(),
            decoder: Decoder::new(),
            clock: BoardClock::new(),
            identity: None,
            health: None,
            air_temperature_c: None,
            hello_at: 0,
            last_heard: 0,
            next_exchange: 0,
            next_health: 0,
            next_air: 0,
            exchanges_sent: 0,
            exchange_id: 0,
            awaiting: BTreeMap::new(),
            burst_id: 0,
            armed: BTreeMap::new(),
            group: None,
            counters: HostCounters::default(),
        }
    }

    /// The link opened at `now_ns`: the bytes to send (a flush and `Hello`).
    pub fn connected(&mut self, now_ns: i64) -> Vec<u8> {
        self.decoder = Decoder::new();
        self.restart(now_ns)
    }

    /// The link was lost: everything learnt of the board is forgotten.
    pub fn disconnected(&mut self) {
        self.forget();
        self.state = HostState::Disconnected;
    }

    fn forget(&mut self) {
        self.counters.never_fired += self.armed.len() as u64;
        self.armed.clear();
        self.awaiting.clear();
        self.group = None;
        self.identity = None;
        self.air_temperature_c = None;
        self.clock = BoardClock::new();
        self.exchanges_sent = 0;
    }

    fn restart(&mut self, now_ns: i64) -> Vec<u8> {
        self.forget();
        self.state = HostState::AwaitingIdentity;
        self.hello_at = now_ns;
        self.last_heard = now_ns;
        self.counters.handshakes += 1;
        let mut out = vec![crate::frame::DELIMITER];
        out.extend(self.encoder.frame(&Message::Hello {
            min_version: VERSION,
            max_version: VERSION,
        }));
        out
    }

    /// The handshake's state.
    pub fn state(&self) -> HostState {
        self.state
    }

    /// The board's clock as known.
    pub fn clock(&self) -> &BoardClock {
        &self.clock
    }

    /// The state of the board, for reports.
    pub fn report(&self, now_ns: i64) -> DeviceReport {
        let mut counters = self.counters;
        let d = self.decoder.counters();
        counters.lost = d.lost;
        DeviceReport {
            state: self.state,
            identity: self.identity.clone(),
            clock_offset_ns: self.clock.offset_ns(now_ns),
            clock_drift: self.clock.drift(),
            clock_bound_ns: self.clock.bound_ns(),
            health: self.health,
            air_temperature_c: self.air_temperature_c,
            counters,
        }
    }

    /// What is due at `now_ns`: bytes to send (possibly none), and when to
    /// call again at the latest, nanoseconds.
    pub fn poll(&mut self, now_ns: i64) -> (Vec<u8>, i64, Vec<HostEvent>) {
        let mut out = Vec::new();
        let mut events = Vec::new();
        match self.state {
            HostState::Disconnected | HostState::WrongBoard => {
                return (out, now_ns + EXCHANGE_NS, events);
            }
            HostState::AwaitingIdentity => {
                if now_ns - self.hello_at >= HELLO_RETRY_NS {
                    out = self.restart(now_ns);
                }
                return (out, self.hello_at + HELLO_RETRY_NS, events);
            }
            HostState::Synchronising | HostState::Ready => {}
        }
        if now_ns - self.last_heard >= SILENCE_NS {
            events.push(HostEvent::Silent);
            out = self.restart(now_ns);
            return (out, now_ns + HELLO_RETRY_NS, events);
        }
        self.expire(now_ns);
        if now_ns >= self.next_exchange {
            self.exchange_id = self.exchange_id.wrapping_add(1);
            if self.awaiting.len() == EXCHANGES_KEPT {
                self.awaiting.pop_first();
            }
            self.awaiting.insert(self.exchange_id, now_ns);
            out.extend(self.encoder.frame(&Message::ClockRequest {
                exchange: self.exchange_id,
            }));
            self.exchanges_sent += 1;
            let step = if self.exchanges_sent < FAST_EXCHANGES {
                FAST_EXCHANGE_NS
            } else {
                EXCHANGE_NS
            };
            self.next_exchange = now_ns + step;
        }
        let answers_health = self
            .identity
            .as_ref()
            .is_some_and(|i| i.capabilities & capability::HEALTH != 0);
        if answers_health && now_ns >= self.next_health {
            out.extend(self.encoder.frame(&Message::HealthRequest));
            self.next_health = now_ns + HEALTH_NS;
        }
        let has_air_sensor = self
            .identity
            .as_ref()
            .is_some_and(|i| i.capabilities & capability::AIR_TEMPERATURE != 0);
        if has_air_sensor && now_ns >= self.next_air {
            out.extend(self.encoder.frame(&Message::AirTemperatureRequest));
            self.next_air = now_ns + AIR_TEMPERATURE_NS;
        }
        let mut next = self.next_exchange;
        if answers_health {
            next = next.min(self.next_health);
        }
        if has_air_sensor {
            next = next.min(self.next_air);
        }
        (out, next.min(self.last_heard + SILENCE_NS), events)
    }

    /// Forgets exchanges and armed bursts that will not be answered.
    fn expire(&mut self, now_ns: i64) {
        self.awaiting
            .retain(|_, t1| now_ns - *t1 < EXCHANGE_TIMEOUT_NS);
        let before = self.armed.len();
        self.armed
            .retain(|_, a| now_ns.saturating_sub(a.host_ns) < FIRED_TIMEOUT_NS);
        self.counters.never_fired += (before - self.armed.len()) as u64;
    }

    /// Arms transmitter `tx_id` to fire at host time `fire_host_ns`,
    /// remembered as `tag`: the bytes to send.
    pub fn arm(&mut self, tx_id: u32, fire_host_ns: i64, tag: u64) -> Result<Vec<u8>, ArmError> {
        match self.state {
            HostState::Ready => {}
            other => return Err(ArmError::NotReady(other.name())),
        }
        let drives = self
            .identity
            .as_ref()
            .is_some_and(|i| i.channels.contains(&i64::from(tx_id)));
        if !drives {
            return Err(ArmError::UnknownTransmitter(tx_id));
        }
        let fire_at_board_ns = self
            .clock
            .to_board(fire_host_ns)
            .ok_or(ArmError::OutOfRange)?;
        self.burst_id = self.burst_id.wrapping_add(1);
        if self.armed.len() == ARMED_KEPT {
            self.armed.pop_first();
            self.counters.never_fired += 1;
        }
        self.armed.insert(
            self.burst_id,
            Armed {
                tag,
                seq: self.encoder.next_seq(),
                tx_id,
                host_ns: fire_host_ns,
            },
        );
        self.counters.armed += 1;
        Ok(self.encoder.frame(&Message::Arm {
            burst: self.burst_id,
            tx_id,
            fire_at_board_ns,
        }))
    }

    /// Bytes read from the link, received at host time `now_ns`.
    pub fn on_bytes(&mut self, now_ns: i64, bytes: &[u8]) -> Vec<HostEvent> {
        let mut events = Vec::new();
        for decoded in self.decoder.feed(bytes) {
            match decoded {
                Ok((_, message)) => {
                    self.last_heard = now_ns;
                    self.on_message(now_ns, message, &mut events);
                }
                Err(e) => {
                    self.counters.refused += 1;
                    events.push(HostEvent::Refused(e.kind(), e.to_string()));
                }
            }
        }
        events
    }

    fn refuse(&mut self, events: &mut Vec<HostEvent>, kind: &'static str, detail: String) {
        self.counters.refused += 1;
        events.push(HostEvent::Refused(kind, detail));
    }

    fn on_message(&mut self, now_ns: i64, message: Message, events: &mut Vec<HostEvent>) {
        if matches!(self.state, HostState::WrongBoard | HostState::Disconnected) {
            return;
        }
        match message {
            Message::Identify(id) => self.on_identify(now_ns, id, events),
            _ if self.state == HostState::AwaitingIdentity => {
                self.refuse(events, "before identity", format!("{message:?}"));
            }
            Message::ClockReply {
                exchange,
                t2_board_ns,
                t3_board_ns,
            } => {
                let Some(t1) = self.awaiting.remove(&exchange) else {
                    return self.refuse(events, "unknown exchange", format!("exchange {exchange}"));
                };
                let x = ClockExchange {
                    t1_host_ns: t1,
                    t2_board_ns,
                    t3_board_ns,
                    t4_host_ns: now_ns,
                };
                match self.clock.add(x) {
                    Ok(()) => {
                        self.counters.exchanges += 1;
                        self.state = HostState::Ready;
                    }
                    Err(e) => self.refuse(events, "clock reply", e.to_string()),
                }
            }
            Message::Fired {
                burst,
                tx_id,
                fired_board_ns,
            } => self.on_fired(burst, tx_id, fired_board_ns, events),
            Message::Refused {
                msg_type,
                seq,
                reason,
            } => self.on_refused(msg_type, seq, reason, events),
            Message::Health {
                supply_mv,
                temperature_cdeg_c,
                faults,
            } => self.health = Some((supply_mv, temperature_cdeg_c, faults)),
            Message::Arrivals {
                group,
                last,
                arrivals,
            } => self.on_arrivals(now_ns, group, last, &arrivals, events),
            Message::WheelTicks {
                board_ns,
                left,
                right,
            } => {
                if let Some(host_ns) = self.measured(now_ns, board_ns, events) {
                    events.push(HostEvent::WheelTicks {
                        host_ns,
                        left,
                        right,
                    });
                }
            }
            Message::ImuSample {
                board_ns,
                gyro_z_urad_s,
            } => {
                if let Some(host_ns) = self.measured(now_ns, board_ns, events) {
                    events.push(HostEvent::Imu {
                        host_ns,
                        gyro_z_rad_s: f64::from(gyro_z_urad_s) * 1e-6,
                    });
                }
            }
            Message::AirTemperature {
                board_ns,
                temperature_cdeg_c,
            } => self.on_air_temperature(now_ns, board_ns, temperature_cdeg_c, events),
            Message::Hello { .. }
            | Message::ClockRequest { .. }
            | Message::Arm { .. }
            | Message::HealthRequest
            | Message::AirTemperatureRequest => {
                self.refuse(
                    events,
                    "host message from the board",
                    format!("{message:?}"),
                );
            }
        }
    }

    fn on_identify(&mut self, now_ns: i64, id: Identify, events: &mut Vec<HostEvent>) {
        let needs = match self.expected {
            BoardKind::Transmitter => capability::FIRE,
            BoardKind::Receiver => capability::ARRIVALS,
        };
        let problem = if id.kind != self.expected {
            Some(format!(
                "a {} answered where a {} was expected",
                id.kind.name(),
                self.expected.name()
            ))
        } else if id.version != VERSION {
            Some(format!(
                "the board speaks protocol version {}, not {VERSION}",
                id.version
            ))
        } else if id.capabilities & needs != needs {
            Some(format!(
                "the {} lacks the capability this host needs (bits {:#06x} of {needs:#06x})",
                id.kind.name(),
                id.capabilities
            ))
        } else {
            None
        };
        if let Some(why) = problem {
            self.forget();
            self.state = HostState::WrongBoard;
            events.push(HostEvent::WrongBoard(why));
            return;
        }
        if self.state == HostState::AwaitingIdentity {
            self.state = HostState::Synchronising;
            self.next_exchange = now_ns;
            self.next_health = now_ns;
            self.next_air = now_ns;
        }
        self.identity = Some(id.clone());
        events.push(HostEvent::Identified(id));
    }

    fn on_fired(
        &mut self,
        burst: u16,
        tx_id: u32,
        fired_board_ns: u64,
        events: &mut Vec<HostEvent>,
    ) {
        let Some(armed) = self.armed.remove(&burst) else {
            return self.refuse(
                events,
                "unarmed burst",
                format!("burst {burst}, tx {tx_id}"),
            );
        };
        if armed.tx_id != tx_id {
            return self.refuse(
                events,
                "wrong transmitter",
                format!(
                    "burst {burst} armed for tx {}, reported for tx {tx_id}",
                    armed.tx_id
                ),
            );
        }
        let Some(fired_host_ns) = self.clock.to_host(fired_board_ns) else {
            return self.refuse(
                events,
                "absurd time",
                format!("fired at board time {fired_board_ns}"),
            );
        };
        let error = fired_host_ns.saturating_sub(armed.host_ns);
        if error.saturating_abs() > MAX_FIRING_ERROR_NS {
            return self.refuse(
                events,
                "absurd time",
                format!("tx {tx_id} reported fired {error} ns from its armed time"),
            );
        }
        self.counters.fired += 1;
        events.push(HostEvent::Fired {
            tag: armed.tag,
            tx_id,
            fired_host_ns,
            armed_host_ns: armed.host_ns,
        });
    }

    fn on_refused(
        &mut self,
        msg_type: u8,
        seq: u8,
        reason: RefusedReason,
        events: &mut Vec<HostEvent>,
    ) {
        // Only an `Arm` names something to undo: the armed burst whose
        // frame had that sequence number (the newest, if it wrapped).
        let armed = (msg_type == 0x03)
            .then(|| self.armed.iter().rev().find(|(_, a)| a.seq == seq))
            .flatten()
            .map(|(&burst, _)| burst);
        if let Some(a) = armed.and_then(|b| self.armed.remove(&b)) {
            self.counters.arm_refused += 1;
            events.push(HostEvent::ArmRefused {
                tag: a.tag,
                tx_id: a.tx_id,
                reason,
            });
            return;
        }
        self.refuse(
            events,
            "refused by the board",
            format!("message type {msg_type:#04x} (seq {seq}): {reason:?}"),
        );
    }

    fn on_arrivals(
        &mut self,
        now_ns: i64,
        group: u16,
        last: bool,
        arrivals: &[crate::message::BoardArrival],
        events: &mut Vec<HostEvent>,
    ) {
        let receivers = self.identity.as_ref().map_or(0, |i| i.channels.len());
        let mut g = match self.group.take() {
            Some(g) if g.id == group => g,
            Some(g) => {
                self.refuse(
                    events,
                    "unfinished group",
                    format!("group {} dropped", g.id),
                );
                Group {
                    id: group,
                    arrivals: Vec::new(),
                }
            }
            None => Group {
                id: group,
                arrivals: Vec::new(),
            },
        };
        for a in arrivals {
            if usize::from(a.receiver) >= receivers {
                self.refuse(
                    events,
                    "unknown receiver",
                    format!("receiver {} of {receivers}", a.receiver),
                );
                continue;
            }
            let Some(host_ns) = self.measured(now_ns, a.board_ns, events) else {
                continue;
            };
            if g.arrivals.len() < MAX_GROUP {
                g.arrivals.push(HostArrival {
                    tx_id: a.tx_id,
                    receiver: a.receiver,
                    host_ns,
                    quality: a.quality,
                });
            }
        }
        if last {
            self.counters.groups += 1;
            events.push(HostEvent::Arrivals {
                group: g.id,
                arrivals: g.arrivals,
            });
        } else {
            self.group = Some(g);
        }
    }

    /// An `AirTemperature` of the board: handed on with its host time
    /// (asked of a board without a sensor or not, a reading is a reading;
    /// one stamped at an absurd time is refused).
    fn on_air_temperature(
        &mut self,
        now_ns: i64,
        board_ns: u64,
        temperature_cdeg_c: i16,
        events: &mut Vec<HostEvent>,
    ) {
        let Some(host_ns) = self.measured(now_ns, board_ns, events) else {
            return;
        };
        let temperature_c = if temperature_cdeg_c == NO_TEMPERATURE {
            f64::NAN
        } else {
            f64::from(temperature_cdeg_c) / 100.0
        };
        self.air_temperature_c = Some(temperature_c);
        events.push(HostEvent::AirTemperature {
            host_ns,
            temperature_c,
        });
    }

    /// A board time of a measurement received at `now_ns`, on the host's
    /// clock, or `None` (refused) when absurd.
    fn measured(&mut self, now_ns: i64, board_ns: u64, events: &mut Vec<HostEvent>) -> Option<i64> {
        match self.clock.to_host(board_ns) {
            Some(t) if now_ns.saturating_sub(t).saturating_abs() <= MAX_MEASUREMENT_AGE_NS => {
                Some(t)
            }
            _ => {
                self.refuse(events, "absurd time", format!("board time {board_ns}"));
                None
            }
        }
    }
}
