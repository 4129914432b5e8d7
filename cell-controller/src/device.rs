//! A transmitter board on a serial line or a TCP connection, speaking the
//! ICKON device protocol (`docs/device-protocol.md`): the cell's
//! [`TransmitterDriver`] for real hardware (`--driver serial:PATH[@BAUD]`,
//! `--driver tcp:HOST:PORT`).
//!
//! The link runs on its own thread ([`ickon_runtime::link`]) and stamps
//! every chunk of bytes with the cell's clock as it is read; the protocol
//! ([`BoardHost`]) runs in the cell's loop, through [`BoardTransmitters::next`].
//! Bursts are armed on the board's clock (known from clock exchanges); each
//! `Fired` report becomes the burst's emission report, its `actual` time the
//! scheduled time moved by how far from its armed time the board fired.

use std::collections::BTreeMap;
use std::time::Instant;

use ickon_device::host::DeviceReport;
use ickon_device::{BoardHost, BoardKind, HostEvent};
use ickon_proto::msg::control::Burst;
use ickon_proto::time::{Duration, Time};
use ickon_runtime::link::{Backoff, Link, LinkAddress, LinkEvent, LinkStatus};
use ickon_runtime::{LogLimiter, SimulatedClock};
use tokio::sync::mpsc;

use crate::driver::{DriverError, TransmitterDriver};
use crate::timer::PlannedBurst;

/// Bursts awaiting their report at most (a few cycles of a cell).
const PENDING_KEPT: usize = 512;
/// Air temperature readings held for the node at most (it takes them at
/// once; a reading a second).
const AIR_KEPT: usize = 16;

/// The cell's transmitter board.
pub struct BoardTransmitters {
    cell_id: String,
    clock: SimulatedClock,
    host: BoardHost,
    link: Link,
    events: mpsc::UnboundedReceiver<(Time, LinkEvent)>,
    pending: BTreeMap<u64, PlannedBurst>,
    next_tag: u64,
    next_poll: Time,
    log_limit: LogLimiter<&'static str>,
    /// Air temperature readings of the board's sensor not yet taken:
    /// (local time measured, degrees Celsius).
    air: Vec<(Time, f64)>,
}

impl BoardTransmitters {
    /// Opens the board at `address` for cell `cell_id`, whose clock is `clock`.
    pub fn open(cell_id: &str, address: LinkAddress, clock: SimulatedClock) -> Self {
        let (tx, events) = mpsc::unbounded_channel();
        let link = Link::open(address, Backoff::default(), move |e| {
            let _ = tx.send((clock.now(), e));
        });
        Self {
            cell_id: cell_id.to_string(),
            clock,
            host: BoardHost::new(BoardKind::Transmitter),
            link,
            events,
            pending: BTreeMap::new(),
            next_tag: 0,
            next_poll: clock.now(),
            log_limit: LogLimiter::default(),
            air: Vec::new(),
        }
    }

    /// The board's and the link's state now.
    pub fn report(&self) -> (DeviceReport, LinkStatus) {
        (
            self.host.report(self.clock.now().as_nanos()),
            self.link.status(),
        )
    }

    /// The board and its link in a line for an operator (the cell's
    /// status carries it to `ickon admin` and the map).
    pub fn summary(&self) -> String {
        let (report, link) = self.report();
        format!(
            "transmitter board {}, {}",
            link.describe(),
            report.summary()
        )
    }

    /// The air temperature readings of the board's sensor since the last
    /// call: (local time measured, degrees Celsius, not a number when the
    /// sensor had none). Judged by the central unit, not here.
    pub fn take_air(&mut self) -> Vec<(Time, f64)> {
        std::mem::take(&mut self.air)
    }

    /// Waits for the link's next event or the protocol's next due time and
    /// handles it; returns the emission reports of bursts fired. Safe to
    /// cancel (inside a `select!`): nothing is lost while it waits.
    pub async fn next(&mut self) -> Vec<Burst> {
        let wait = self.next_poll.since(self.clock.now()).to_std();
        tokio::select! {
            ev = self.events.recv() => match ev {
                Some((at, ev)) => self.on_link(at, ev),
                None => std::future::pending().await,
            },
            _ = tokio::time::sleep(wait) => {
                self.poll();
                Vec::new()
            }
        }
    }

    fn send(&mut self, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        if let Err(e) = self.link.send(bytes) {
            self.log("send failed", &e.to_string());
        }
    }

    fn poll(&mut self) {
        let now = self.clock.now();
        let (bytes, next_ns, events) = self.host.poll(now.as_nanos());
        self.send(&bytes);
        self.next_poll = Time::from_nanos(next_ns).max(now + Duration::from_millis(1));
        for e in events {
            self.on_host(e);
        }
    }

    fn on_link(&mut self, at: Time, event: LinkEvent) -> Vec<Burst> {
        match event {
            LinkEvent::Connected => {
                let hello = self.host.connected(at.as_nanos());
                self.send(&hello);
                self.next_poll = self.clock.now();
                Vec::new()
            }
            LinkEvent::Disconnected(why) => {
                tracing::warn!("cell {}: transmitter board lost: {why}", self.cell_id);
                self.host.disconnected();
                self.pending.clear();
                Vec::new()
            }
            LinkEvent::Bytes(bytes) => {
                let events = self.host.on_bytes(at.as_nanos(), &bytes);
                events.into_iter().filter_map(|e| self.on_host(e)).collect()
            }
        }
    }

    /// Acts on one protocol event; a fired burst's emission report.
    fn on_host(&mut self, event: HostEvent) -> Option<Burst> {
        let cell = &self.cell_id;
        match event {
            HostEvent::Identified(id) => {
                tracing::info!(
                    "cell {cell}: transmitter board serial {} firmware {}.{} drives {:?}",
                    id.serial,
                    id.firmware >> 8,
                    id.firmware & 0xFF,
                    id.channels
                );
            }
            HostEvent::WrongBoard(why) => {
                tracing::error!(
                    "cell {cell}: board on {} refused: {why}",
                    self.link.address()
                );
            }
            HostEvent::Fired {
                tag,
                fired_host_ns,
                armed_host_ns,
                ..
            } => {
                let b = self.pending.remove(&tag)?;
                let late = Duration::from_nanos(fired_host_ns.saturating_sub(armed_host_ns));
                return Some(Burst {
                    cell_id: cell.clone(),
                    tx_id: b.tx_id,
                    cycle: b.cycle,
                    scheduled: b.master,
                    actual: b.master + late,
                    epoch: b.epoch,
                });
            }
            HostEvent::ArmRefused { tag, tx_id, reason } => {
                self.pending.remove(&tag);
                self.log("burst refused", &format!("tx {tx_id}: {reason:?}"));
            }
            HostEvent::Refused(kind, detail) => self.log(kind, &detail),
            HostEvent::Silent => {
                tracing::warn!("cell {cell}: transmitter board silent; greeting it again");
            }
            HostEvent::AirTemperature {
                host_ns,
                temperature_c,
            } => {
                if self.air.len() == AIR_KEPT {
                    self.air.remove(0);
                }
                self.air.push((Time::from_nanos(host_ns), temperature_c));
            }
            HostEvent::Arrivals { .. } | HostEvent::WheelTicks { .. } | HostEvent::Imu { .. } => {
                self.log("receiver data", "from a transmitter board");
            }
        }
        None
    }

    fn log(&mut self, kind: &'static str, detail: &str) {
        if let Some(held) = self.log_limit.admit(kind, Instant::now()) {
            tracing::warn!(
                "cell {}: transmitter board: {kind}: {detail} ({held} more since)",
                self.cell_id
            );
        }
    }
}

impl TransmitterDriver for BoardTransmitters {
    fn program(&mut self, b: &PlannedBurst) -> Result<Option<Burst>, DriverError> {
        self.next_tag += 1;
        let bytes = self
            .host
            .arm(b.tx_id, b.local.as_nanos(), self.next_tag)
            .map_err(|e| match e {
                ickon_device::host::ArmError::UnknownTransmitter(t) => {
                    DriverError::UnknownTransmitter(t)
                }
                e => DriverError::Hardware(e.to_string()),
            })?;
        if self.pending.len() == PENDING_KEPT {
            self.pending.pop_first();
        }
        self.pending.insert(self.next_tag, *b);
        self.link
            .send(&bytes)
            .map_err(|e| DriverError::Hardware(e.to_string()))?;
        Ok(None)
    }
}
