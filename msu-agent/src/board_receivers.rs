//! A receiver board on a serial line or a TCP connection, speaking the
//! ICKON device protocol (`docs/device-protocol.md`): the MSU's arrivals
//! for real hardware (`--receivers serial:PATH[@BAUD]`, `--receivers
//! tcp:HOST:PORT`).
//!
//! The link runs on its own thread and stamps every chunk of bytes with
//! the agent's clock as it is read; the protocol ([`BoardHost`]) runs in a
//! task of its own, which turns each complete group of arrivals into the
//! [`UltrasoundArrivals`] of one cycle on the agent's clock, numbered by
//! the board's group counter (so that whoever framed the groups can name
//! the cycle a pose comes from); a board that reports the robot's wheel
//! ticks and gyro feeds them as the robot's odometry and IMU, on the same
//! clock. The board's
//! clock is learnt by clock exchanges (one a second); arrivals it stamps
//! with absurd times, receivers it does not have, frames that do not
//! decode are refused, counted and logged at a bounded rate.

use std::time::Instant;

use ickon_device::{BoardHost, BoardKind, GroupSequence, HostEvent};
use ickon_fusion::estimator::{WheelGeometry, arc_step};
use ickon_proto::msg::robot::{Arrival, Imu, Odometry, UltrasoundArrivals};
use ickon_proto::time::{Duration, Time};
use ickon_runtime::link::{Backoff, Link, LinkAddress, LinkEvent};
use ickon_runtime::{LogLimiter, SimulatedClock};
use tokio::sync::mpsc;

use crate::receiver_input::{ReceiverInput, SharedSummary};

/// How often the board's line in the agent's status is refreshed.
const SUMMARY_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// The robot's receiver board; stops when dropped.
pub struct BoardReceivers {
    task: tokio::task::JoinHandle<()>,
    summary: SharedSummary,
}

impl Drop for BoardReceivers {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl BoardReceivers {
    /// Opens the board at `address` for `robot`, whose clock is `clock`
    /// and whose wheels are `wheels`; each group of arrivals, each wheel
    /// tick and gyro sample goes to `sink`.
    pub fn open(
        robot: &str,
        address: LinkAddress,
        clock: SimulatedClock,
        wheels: WheelGeometry,
        sink: impl Fn(ReceiverInput) + Send + Sync + 'static,
    ) -> Self {
        let (tx, events) = mpsc::unbounded_channel();
        let link = Link::open(address, Backoff::default(), move |e| {
            let _ = tx.send((clock.now(), e));
        });
        let summary = SharedSummary::default();
        let mut board = Board {
            summary: summary.clone(),
            summarised: None,
            robot: robot.to_string(),
            clock,
            host: BoardHost::new(BoardKind::Receiver),
            link,
            seq: GroupSequence::default(),
            odometry: DeadReckoning::new(wheels),
            log_limit: LogLimiter::default(),
        };
        let task = tokio::spawn(async move { board.serve(events, sink).await });
        Self { task, summary }
    }

    /// Where the board and its link are described in a line, each second.
    pub fn summary(&self) -> SharedSummary {
        self.summary.clone()
    }
}

struct Board {
    summary: SharedSummary,
    /// When the summary was last written.
    summarised: Option<Instant>,
    robot: String,
    clock: SimulatedClock,
    host: BoardHost,
    link: Link,
    seq: GroupSequence,
    odometry: DeadReckoning,
    log_limit: LogLimiter<&'static str>,
}

/// The odometry frame's pose from a board's cumulative wheel ticks, as a
/// robot's own odometry would publish it (the filters use the ticks; the
/// pose is for those who read the odometry: a recording, ROS 2's `odom`).
struct DeadReckoning {
    wheels: WheelGeometry,
    last: Option<(i64, i64)>,
    pose: (f64, f64, f64),
}

impl DeadReckoning {
    fn new(wheels: WheelGeometry) -> Self {
        Self {
            wheels,
            last: None,
            pose: (0.0, 0.0, 0.0),
        }
    }

    /// The robot's odometry at `stamp` with the cumulative counts.
    fn at(&mut self, stamp: Time, left: i64, right: i64) -> Odometry {
        if let Some((l0, r0)) = self.last {
            let dl = left.wrapping_sub(l0) as f64 * self.wheels.left_m_per_tick;
            let dr = right.wrapping_sub(r0) as f64 * self.wheels.right_m_per_tick;
            let base = self.wheels.wheel_base_m;
            if base > 0.0 && dl.is_finite() && dr.is_finite() {
                let (x, y, theta) = self.pose;
                self.pose = arc_step(x, y, theta, (dl + dr) / 2.0, (dr - dl) / base);
            }
        }
        self.last = Some((left, right));
        let (x_m, y_m, theta_rad) = self.pose;
        Odometry {
            stamp,
            x_m,
            y_m,
            theta_rad,
            left_ticks: left,
            right_ticks: right,
        }
    }
}

impl Board {
    async fn serve(
        &mut self,
        mut events: mpsc::UnboundedReceiver<(Time, LinkEvent)>,
        sink: impl Fn(ReceiverInput),
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
                if let Some(input) = self.on_host(e) {
                    sink(input);
                }
            }
            if self.summarised.is_none_or(|t| t.elapsed() >= SUMMARY_EVERY) {
                self.summarised = Some(Instant::now());
                self.summary.set(self.describe());
            }
        }
    }

    /// The board and its link in a line for an operator.
    fn describe(&self) -> String {
        let report = self.host.report(self.clock.now().as_nanos());
        format!(
            "receiver board {}, {}",
            self.link.status().describe(),
            report.summary()
        )
    }

    fn send(&mut self, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        if let Err(e) = self.link.send(bytes) {
            self.log("send failed", &e.to_string());
        }
    }

    fn on_host(&mut self, event: HostEvent) -> Option<ReceiverInput> {
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
            HostEvent::Arrivals {
                group,
                arrivals: mut heard,
            } => {
                heard.sort_by_key(|a| a.host_ns);
                return Some(ReceiverInput::Arrivals(Ok(UltrasoundArrivals {
                    seq: self.seq.next(group),
                    arrivals: heard
                        .into_iter()
                        .map(|a| Arrival {
                            tx_id: a.tx_id,
                            receiver_id: a.receiver,
                            t_arrival: Time::from_nanos(a.host_ns),
                        })
                        .collect(),
                })));
            }
            HostEvent::Refused(kind, detail) => self.log(kind, &detail),
            HostEvent::Silent => {
                tracing::warn!("robot {robot}: receiver board silent; greeting it again");
            }
            HostEvent::Fired { .. } | HostEvent::ArmRefused { .. } => {
                self.log("transmitter data", "from a receiver board");
            }
            // A robot's air is not the hall's: the MSU solves with the
            // central unit's speed of sound.
            HostEvent::AirTemperature { .. } => {}
            HostEvent::WheelTicks {
                host_ns,
                left,
                right,
            } => {
                let odometry = self.odometry.at(Time::from_nanos(host_ns), left, right);
                return Some(ReceiverInput::Odometry(odometry));
            }
            HostEvent::Imu {
                host_ns,
                gyro_z_rad_s,
            } => {
                return Some(ReceiverInput::Imu(Imu {
                    stamp: Time::from_nanos(host_ns),
                    gyro_z_rad_s,
                }));
            }
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
