//! A Marvelmind hedgehog (mobile beacon) or modem on a serial line or a
//! TCP bridge as the MSU's ranging source (`--receivers
//! marvelmind:serial:PATH[@BAUD]`, `--receivers marvelmind:tcp:HOST:PORT`).
//!
//! The link runs on its own thread and stamps every chunk of bytes with
//! the agent's clock as it is read; a task reads them with a
//! [`HedgehogReader`] and hands each reading of distances (and, when
//! asked, each of the kit's positions) on. The source's state (the link,
//! frames, bad CRCs, garbage, unknown beacons) is logged when it changes
//! and every [`STATUS_EVERY`] while data flows; problems are logged at a
//! bounded rate.

use std::time::Instant;

use ickon_proto::msg::control::TransmitterEntry;
use ickon_proto::time::Time;
use ickon_runtime::link::{Backoff, Link, LinkAddress, LinkEvent};
use ickon_runtime::{LogLimiter, SimulatedClock};
use tokio::sync::mpsc;

use crate::hedgehog::{HedgehogCounters, HedgehogInput, HedgehogReader, MarvelmindSettings};
use crate::receiver_input::SharedSummary;

/// How often the source's counters are logged while it runs.
pub const STATUS_EVERY: std::time::Duration = std::time::Duration::from_secs(30);

/// How long a connected hedgehog may send no frame before it is reported
/// silent: several of its update periods (it streams at 1-16 Hz), and long
/// enough that a radio dropout of a few cycles is not reported.
pub const SILENT_AFTER: std::time::Duration = std::time::Duration::from_secs(3);

/// What the source needs of the site: its speed of sound and its beacons.
#[derive(Debug, Clone)]
pub struct RangingSite {
    /// The site's speed of sound, m/s.
    pub speed_of_sound_m_s: f64,
    /// The site's transmitters (the kit's stationary beacons).
    pub beacons: Vec<TransmitterEntry>,
}

/// The robot's hedgehog; stops when dropped.
pub struct MarvelmindReceivers {
    task: tokio::task::JoinHandle<()>,
    summary: SharedSummary,
}

impl Drop for MarvelmindReceivers {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl MarvelmindReceivers {
    /// Opens the hedgehog at `address` for `robot`, whose clock is `clock`;
    /// every input goes to `sink`.
    pub fn open(
        robot: &str,
        address: LinkAddress,
        clock: SimulatedClock,
        (site, settings): (RangingSite, MarvelmindSettings),
        sink: impl Fn(HedgehogInput) + Send + Sync + 'static,
    ) -> Self {
        let (tx, events) = mpsc::unbounded_channel();
        let link = Link::open(address, Backoff::default(), move |e| {
            let _ = tx.send((clock.now(), e));
        });
        let summary = SharedSummary::default();
        let mut source = Source {
            summary: summary.clone(),
            robot: robot.to_string(),
            reader: HedgehogReader::new(settings, site.speed_of_sound_m_s, &site.beacons),
            link,
            log_limit: LogLimiter::default(),
            last_frame: None,
            silent: false,
            logged: HedgehogCounters::default(),
        };
        let task = tokio::spawn(async move { source.serve(events, sink).await });
        Self { task, summary }
    }

    /// Where the hedgehog's state is described in a line, each second.
    pub fn summary(&self) -> SharedSummary {
        self.summary.clone()
    }
}

struct Source {
    summary: SharedSummary,
    robot: String,
    reader: HedgehogReader,
    link: Link,
    log_limit: LogLimiter<&'static str>,
    /// When the last frame came (wall clock); `None` since (re)connected.
    last_frame: Option<Instant>,
    silent: bool,
    /// The counters last logged.
    logged: HedgehogCounters,
}

impl Source {
    async fn serve(
        &mut self,
        mut events: mpsc::UnboundedReceiver<(Time, LinkEvent)>,
        sink: impl Fn(HedgehogInput),
    ) {
        let mut status = tokio::time::interval(STATUS_EVERY);
        let mut watch = tokio::time::interval(SILENT_AFTER / 3);
        let connected_at = &mut Instant::now();
        loop {
            tokio::select! {
                ev = events.recv() => match ev {
                    Some((_, LinkEvent::Connected)) => {
                        tracing::info!("robot {}: hedgehog on {} connected", self.robot, self.link.address());
                        self.last_frame = None;
                        self.silent = false;
                        *connected_at = Instant::now();
                    }
                    Some((_, LinkEvent::Disconnected(why))) => {
                        tracing::warn!("robot {}: hedgehog lost: {why}; {}", self.robot, self.state());
                    }
                    Some((at, LinkEvent::Bytes(b))) => {
                        let frames_before = self.reader.counters().frames;
                        let (inputs, problems) = self.reader.feed(at, &b);
                        if self.reader.counters().frames > frames_before {
                            self.last_frame = Some(Instant::now());
                            if std::mem::take(&mut self.silent) {
                                tracing::info!("robot {}: hedgehog streams again", self.robot);
                            }
                        }
                        for (kind, detail) in problems {
                            self.log(kind, &detail);
                        }
                        inputs.into_iter().for_each(&sink);
                    }
                    None => return,
                },
                _ = status.tick() => {
                    let now = self.reader.counters();
                    if now != self.logged {
                        tracing::info!("robot {}: hedgehog: {}", self.robot, self.state());
                        self.logged = now;
                    }
                }
                _ = watch.tick() => {
                    let silent = if self.silent { "silent; " } else { "" };
                    self.summary.set(format!("marvelmind hedgehog: {silent}{}", self.state()));
                    let since = self.last_frame.unwrap_or(*connected_at);
                    let up = self.link.status().state == ickon_runtime::link::LinkState::Up;
                    if up && !self.silent && since.elapsed() > SILENT_AFTER {
                        self.silent = true;
                        tracing::warn!(
                            "robot {}: hedgehog silent for {:?} (is the stream of raw distances on?); {}",
                            self.robot, SILENT_AFTER, self.state()
                        );
                    }
                }
            }
        }
    }

    /// The source's state and counters, for a log line.
    fn state(&self) -> String {
        let link = self.link.status();
        let c = self.reader.counters();
        format!(
            "link {} {} ({} connects), frames {}, bad CRC {}, bad length {}, garbage bytes {}, \
             undecodable {}, readings {}, distances {}, unknown beacons {}, absurd distances {}, \
             kit positions {} used / {} not",
            link.address,
            link.state.name(),
            link.connects,
            c.frames,
            c.bad_crc,
            c.bad_length,
            c.garbage_bytes,
            c.undecodable,
            c.readings,
            c.distances,
            c.unknown_beacons,
            c.absurd_distances,
            c.kit_positions,
            c.kit_positions_unused
        )
    }

    fn log(&mut self, kind: &'static str, detail: &str) {
        if let Some(held) = self.log_limit.admit(kind, Instant::now()) {
            tracing::warn!(
                "robot {}: hedgehog: {kind}: {detail} ({held} more since)",
                self.robot
            );
        }
    }
}
