//! `ickon device check ADDRESS`: tries a board of the ICKON device protocol
//! the way a cell controller or an MSU agent would use it, and prints what
//! it saw: the handshake (identity, version, capabilities), clock exchanges
//! (offset, drift, round trip), and for a transmitter board a few bursts
//! armed and reported (how far from their time they fired), for a receiver
//! board the arrival groups it sends. Exit code 0 when the board did
//! everything asked, 1 when it did not, 2 for a bad address.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use ickon_device::message::capability;
use ickon_device::{BoardHost, BoardKind, HostEvent, HostState, Identify};
use ickon_runtime::link::{Backoff, Link, LinkAddress, LinkEvent};
use ickon_runtime::{CommandError, system_now};

/// Which board `ickon device check` expects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExpectedBoard {
    /// A cell's transmitter board.
    Transmitter,
    /// A robot's receiver board.
    Receiver,
}

/// `ickon device check`.
#[derive(Debug, Clone, Args)]
pub struct DeviceCheckArgs {
    /// The board: `serial:PATH[@BAUD]` (115200 baud when not given) or `tcp:HOST:PORT`.
    pub address: String,
    /// The board expected there.
    #[arg(long, value_enum, default_value_t = ExpectedBoard::Transmitter)]
    pub kind: ExpectedBoard,
    /// Bursts to arm on a transmitter board (round robin over its transmitters).
    #[arg(long, default_value_t = 8)]
    pub bursts: u32,
    /// Seconds to listen for a receiver board's arrivals.
    #[arg(long, default_value_t = 5.0)]
    pub listen_s: f64,
}

/// How long the handshake and the first clock exchanges may take.
const READY_WITHIN: Duration = Duration::from_secs(5);
/// Clock exchanges watched before bursts are armed (the fast start's eight
/// and two steady ones: long enough for a drift).
const CLOCK_WATCH: Duration = Duration::from_millis(2_500);
/// How far ahead a burst is armed (as the cell does).
const ARM_AHEAD_NS: i64 = 20_000_000;
/// Spacing of the bursts armed.
const BURST_SPACING: Duration = Duration::from_millis(50);

/// What the check saw.
#[derive(Debug, Default)]
struct Seen {
    identity: Option<Identify>,
    wrong: Option<String>,
    /// Firing error of each reported burst (reported - armed), nanoseconds.
    firing_errors_ns: Vec<i64>,
    arm_refused: u32,
    groups: u32,
    arrivals: u32,
    refused: Vec<String>,
}

/// The session of the check: the link, the protocol, and what came back.
struct Session {
    link: Link,
    rx: mpsc::Receiver<(i64, LinkEvent)>,
    host: BoardHost,
    next_poll: i64,
    seen: Seen,
}

impl Session {
    /// Handles link events and the protocol's timers for `span`.
    fn pump(&mut self, span: Duration) {
        let until = Instant::now() + span;
        loop {
            let now = system_now().as_nanos();
            if now >= self.next_poll {
                let (bytes, next, events) = self.host.poll(now);
                self.send(&bytes);
                self.next_poll = next.max(now + 1_000_000);
                self.absorb(events);
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return;
            }
            let wait = Duration::from_nanos(
                u64::try_from(self.next_poll - system_now().as_nanos()).unwrap_or(0),
            )
            .min(left);
            match self.rx.recv_timeout(wait) {
                Ok((at, LinkEvent::Connected)) => {
                    let hello = self.host.connected(at);
                    self.send(&hello);
                    self.next_poll = at;
                }
                Ok((_, LinkEvent::Disconnected(why))) => {
                    println!("  link lost: {why}");
                    self.host.disconnected();
                }
                Ok((at, LinkEvent::Bytes(b))) => {
                    let events = self.host.on_bytes(at, &b);
                    self.absorb(events);
                }
                Err(_) => {}
            }
        }
    }

    fn send(&mut self, bytes: &[u8]) {
        if !bytes.is_empty()
            && let Err(e) = self.link.send(bytes)
        {
            self.seen.refused.push(format!("send: {e}"));
        }
    }

    fn absorb(&mut self, events: Vec<HostEvent>) {
        for e in events {
            match e {
                HostEvent::Identified(id) => self.seen.identity = Some(id),
                HostEvent::WrongBoard(why) => self.seen.wrong = Some(why),
                HostEvent::Fired {
                    fired_host_ns,
                    armed_host_ns,
                    ..
                } => self
                    .seen
                    .firing_errors_ns
                    .push(fired_host_ns - armed_host_ns),
                HostEvent::ArmRefused { tx_id, reason, .. } => {
                    self.seen.arm_refused += 1;
                    self.seen
                        .refused
                        .push(format!("burst on tx {tx_id} refused: {reason:?}"));
                }
                HostEvent::Arrivals { arrivals: a, .. } => {
                    self.seen.groups += 1;
                    self.seen.arrivals += a.len() as u32;
                }
                HostEvent::Refused(kind, detail) => {
                    if self.seen.refused.len() < 20 {
                        self.seen.refused.push(format!("{kind}: {detail}"));
                    }
                }
                HostEvent::Silent => self.seen.refused.push("the board went silent".into()),
                HostEvent::WheelTicks { .. }
                | HostEvent::Imu { .. }
                | HostEvent::AirTemperature { .. } => {}
            }
        }
    }
}

/// Runs `ickon device check`.
pub fn run(args: &DeviceCheckArgs) -> Result<(), CommandError> {
    let address: LinkAddress = args
        .address
        .parse()
        .map_err(|e: ickon_runtime::link::AddressError| CommandError::bad_input(e.to_string()))?;
    if !(args.listen_s.is_finite() && (0.0..=3600.0).contains(&args.listen_s)) {
        return Err(CommandError::bad_input("--listen-s must be 0-3600 seconds"));
    }
    let expected = match args.kind {
        ExpectedBoard::Transmitter => BoardKind::Transmitter,
        ExpectedBoard::Receiver => BoardKind::Receiver,
    };
    let (tx, rx) = mpsc::channel();
    let link = Link::open(address.clone(), Backoff::default(), move |e| {
        let _ = tx.send((system_now().as_nanos(), e));
    });
    let mut s = Session {
        link,
        rx,
        host: BoardHost::new(expected),
        next_poll: i64::MAX,
        seen: Seen::default(),
    };
    println!("{address}: expecting a {}", expected.name());
    let started = Instant::now();
    while s.host.state() != HostState::Ready
        && s.seen.wrong.is_none()
        && started.elapsed() < READY_WITHIN
    {
        s.pump(Duration::from_millis(50));
    }
    print_identity(&s);
    if let Some(why) = &s.seen.wrong {
        return Err(CommandError::failure(format!("{address}: {why}")));
    }
    if s.host.state() != HostState::Ready {
        let link = s.link.status();
        return Err(CommandError::failure(format!(
            "{address}: no handshake and clock exchange within {READY_WITHIN:?} (link {}{})",
            link.state.name(),
            link.last_error
                .map(|e| format!(": {e}"))
                .unwrap_or_default()
        )));
    }
    s.pump(CLOCK_WATCH);
    print_clock(&s);
    match expected {
        BoardKind::Transmitter => fire_bursts(&mut s, args.bursts),
        BoardKind::Receiver => s.pump(Duration::from_secs_f64(args.listen_s)),
    }
    verdict(&s, expected, args.bursts)
}

fn print_identity(s: &Session) {
    match &s.seen.identity {
        Some(id) => {
            let caps: Vec<&str> = [
                (capability::FIRE, "fire"),
                (capability::ARRIVALS, "arrivals"),
                (capability::WHEEL_TICKS, "wheel ticks"),
                (capability::IMU, "imu"),
                (capability::HEALTH, "health"),
            ]
            .iter()
            .filter(|(bit, _)| id.capabilities & bit != 0)
            .map(|(_, name)| *name)
            .collect();
            println!(
                "  identity: {} v{}, serial {}, firmware {}.{}, capabilities [{}]",
                id.kind.name(),
                id.version,
                id.serial,
                id.firmware >> 8,
                id.firmware & 0xFF,
                caps.join(", ")
            );
            match id.kind {
                BoardKind::Transmitter => println!("  transmitters: {:?}", id.channels),
                BoardKind::Receiver => {
                    let deg: Vec<f64> = id.channels.iter().map(|&c| c as f64 / 100.0).collect();
                    println!("  receivers at (deg): {deg:?}");
                }
            }
        }
        None => println!("  identity: none"),
    }
}

fn print_clock(s: &Session) {
    let r = s.host.report(system_now().as_nanos());
    println!(
        "  clock: {} exchanges, board - host {:.3} ms, drift {:+.2} ppm, best round trip {:.1} us",
        r.counters.exchanges,
        r.clock_offset_ns.unwrap_or(f64::NAN) / 1e6,
        r.clock_drift.unwrap_or(f64::NAN) * 1e6,
        r.clock_bound_ns.unwrap_or(f64::NAN) * 2.0 / 1e3
    );
    if let Some((mv, cdeg, faults)) = r.health {
        println!(
            "  health: supply {:.2} V, {:.1} C, faults {faults:#b}",
            f64::from(mv) / 1e3,
            f64::from(cdeg) / 100.0
        );
    }
}

fn fire_bursts(s: &mut Session, bursts: u32) {
    let txs: Vec<u32> = s
        .seen
        .identity
        .as_ref()
        .map(|i| {
            i.channels
                .iter()
                .filter_map(|&c| u32::try_from(c).ok())
                .collect()
        })
        .unwrap_or_default();
    for i in 0..bursts as usize {
        let Some(&tx) = txs.get(i % txs.len().max(1)) else {
            break;
        };
        let at = system_now().as_nanos() + ARM_AHEAD_NS;
        match s.host.arm(tx, at, i as u64) {
            Ok(bytes) => s.send(&bytes),
            Err(e) => s
                .seen
                .refused
                .push(format!("burst on tx {tx} not armed: {e}")),
        }
        s.pump(BURST_SPACING);
    }
    s.pump(Duration::from_millis(200));
}

fn verdict(s: &Session, kind: BoardKind, bursts: u32) -> Result<(), CommandError> {
    let r = s.host.report(system_now().as_nanos());
    if kind == BoardKind::Transmitter {
        let mut errs: Vec<i64> = s.seen.firing_errors_ns.iter().map(|e| e.abs()).collect();
        errs.sort_unstable();
        let median = errs.get(errs.len() / 2).copied().unwrap_or(0);
        println!(
            "  bursts: {bursts} armed, {} reported fired, {} refused; firing error (reported - armed) median {:.1} us, max {:.1} us",
            s.seen.firing_errors_ns.len(),
            s.seen.arm_refused,
            median as f64 / 1e3,
            errs.last().copied().unwrap_or(0) as f64 / 1e3
        );
    } else {
        println!(
            "  arrivals: {} groups, {} arrivals",
            s.seen.groups, s.seen.arrivals
        );
    }
    println!(
        "  frames refused {}, lost {}, handshakes {}",
        r.counters.refused, r.counters.lost, r.counters.handshakes
    );
    for problem in &s.seen.refused {
        println!("  problem: {problem}");
    }
    let fired_all = kind == BoardKind::Receiver || s.seen.firing_errors_ns.len() == bursts as usize;
    if fired_all && r.counters.refused == 0 && r.counters.lost == 0 {
        println!("ok");
        Ok(())
    } else {
        Err(CommandError::failure(format!(
            "the board did not do everything asked ({} of {bursts} bursts reported, {} frames refused, {} lost)",
            s.seen.firing_errors_ns.len(),
            r.counters.refused,
            r.counters.lost
        )))
    }
}
