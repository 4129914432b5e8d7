//! A receiver board on a serial line or a TCP connection, speaking the
//! ICKON device protocol (`docs/device-protocol.md`): the MSU's arrivals
//! for real hardware (`--receivers serial:PATH[@BAUD]`, `--receivers
//! tcp:HOST:PORT`).
//!
//! The link runs on its own thread and stamps every chunk of bytes with
//! the agent's clock as it is read; the protocol ([`BoardHost`]) runs in a
//! task of its own, which turns each complete group of arrivals into the
//! [`UltrasoundArrivals`] of one cycle on the agent's clock. The board's
//! clock is learnt by clock exchanges (one a second); arrivals it stamps
//! with absurd times, receivers it does not have, frames that do not
//! decode are refused, counted and logged at a bounded rate.

use std::time::Instant;

use ickon_device::{BoardHost, BoardKind, HostEvent};
use ickon_proto::DecodeError;
use ickon_proto::msg::robot::{Arrival, UltrasoundArrivals};
use ickon_proto::time::{Duration, Time};
use ickon_runtime::link::{Backoff, Link, LinkAddress, LinkEvent};
use ickon_runtime::{LogLimiter, SimulatedClock};
use tokio::sync::mpsc;

/// The robot's receiver board; stops when dropped.
pub struct BoardReceivers {
    task: tokio::task::JoinHandle<()>,
}

impl Drop for BoardReceivers {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl BoardReceivers {
    /// Opens the board at `address` for `robot`, whose clock is `clock`;
    /// each group of arrivals goes to `sink`.
    pub fn open(
        robot: &str,
        address: LinkAddress,
        clock: SimulatedClock,
        sink: impl Fn(Result<UltrasoundArrivals, DecodeError>) + Send + Sync + 'static,
    ) -> Self {
        let (tx, events) = mpsc::unbounded_channel();
        let link = Link::open(address, Backoff::default(), move |e| {
            let _ = tx.send((clock.now(), e));
        });
        let mut board = Board {
            robot: robot.to_string(),
            clock,
            host: BoardHost::new(BoardKind::Receiver),
            link,
            seq: 0,
            log_limit: LogLimiter::default(),
        };
        let task = tokio::spawn(async move { board.serve(events, sink).await });
        Self { task }
    }
}

struct Board {
    robot: String,
    clock: SimulatedClock,
    host: BoardHost,
    link: Link,
    seq: u64,
    log_limit: LogLimiter<&'static str>,
}

impl Board {
    async fn serve(
        &mut self,
        mut events: mpsc::UnboundedReceiver<(Time, LinkEvent)>,
        sink: impl Fn(Result<UltrasoundArrivals, DecodeError>),
    ) {
        let mut next_poll = self.clock.now();
        loop {
            let wait = next_poll.since(self.clock.now()).to_std();
            let host_events = tokio::select! {
                ev = events.recv() => match ev {
                    Some((at, LinkEvent::Connected)) => {
                        let hello = self.host.connected(at.as_nanos());
                        self.send(&hello);
                        next_poll = self.clock.now();
                        Vec::new()
                    }
                    Some((_, LinkEvent::Disconnected(why))) => {
                        tracing::warn!("robot {}: receiver board lost: {why}", self.robot);
                        self.host.disconnected();
                        Vec::new()
                    }
                    Some((at, LinkEvent::Bytes(b))) => self.host.on_bytes(at.as_nanos(), &b),
                    None => return,
                },
                _ = tokio::time::sleep(wait) => {
                    let now = self.clock.now();
                    let (bytes, next, events) = self.host.poll(now.as_nanos());
                    self.send(&bytes);
                    next_poll = Time::from_nanos(next).max(now + Duration::from_millis(1));
                    events
                }
            };
            for e in host_events {
                if let Some(arrivals) = self.on_host(e) {
                    sink(Ok(arrivals));
                }
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

    fn on_host(&mut self, event: HostEvent) -> Option<UltrasoundArrivals> {
        let robot = &self.robot;
        match event {
            HostEvent::Identified(id) => {
                let angles: Vec<f64> = id.channels.iter().map(|&c| c as f64 / 100.0).collect();
                tracing::info!(
                    "robot {robot}: receiver board serial {} firmware {}.{}, receivers at {angles:?} deg",
                    id.serial,
                    id.firmware >> 8,
                    id.firmware & 0xFF
                );
            }
            HostEvent::WrongBoard(why) => {
                tracing::error!(
                    "robot {robot}: board on {} refused: {why}",
                    self.link.address()
                );
            }
            HostEvent::Arrivals(mut group) => {
                group.sort_by_key(|a| a.host_ns);
                self.seq += 1;
                return Some(UltrasoundArrivals {
                    seq: self.seq,
                    arrivals: group
                        .into_iter()
                        .map(|a| Arrival {
                            tx_id: a.tx_id,
                            receiver_id: a.receiver,
                            t_arrival: Time::from_nanos(a.host_ns),
                        })
                        .collect(),
                });
            }
            HostEvent::Refused(kind, detail) => self.log(kind, &detail),
            HostEvent::Silent => {
                tracing::warn!("robot {robot}: receiver board silent; greeting it again");
            }
            HostEvent::Fired { .. } | HostEvent::ArmRefused { .. } => {
                self.log("transmitter data", "from a receiver board");
            }
            // Wheel ticks and gyro samples of a receiver board are not
            // used: the robot's own odometry and IMU come over Zenoh.
            HostEvent::WheelTicks { .. } | HostEvent::Imu { .. } => {}
        }
        None
    }

    fn log(&mut self, kind: &'static str, detail: &str) {
        if let Some(held) = self.log_limit.admit(kind, Instant::now()) {
            tracing::warn!(
                "robot {}: receiver board: {kind}: {detail} ({held} more since)",
                self.robot
            );
        }
    }
}
