//! The Foxglove live server of the central unit (`--foxglove [ADDR]`): the
//! site, the fleet and every fix, live in the Foxglove app's standard
//! panels, over Foxglove's WebSocket protocol (subprotocol
//! `foxglove.sdk.v1`, served by Foxglove's own SDK, or its older name
//! `foxglove.websocket.v1` through [`front_door`]) with Foxglove's own
//! schemas.
//!
//! It is fed as the web map is: the central unit's loop hands its
//! [`LiveView`] the robots' summaries, the bursts and the truth
//! ([`FoxgloveLive::sink`]) and the status ([`FoxgloveLive::publish`], a
//! non-blocking replace); a ticker turns both into messages
//! [`TICK_PERIOD`] apart. A recorder drawing the same channels
//! ([`FoxgloveLive::into_sink`]) fills the view from subscribers of its
//! own ([`crate::http::feed::Feed`]). The
//! topics are listed in [`topics`] and in `docs/foxglove.md`.
//!
//! Read-only: the server advertises no capability (no client publishing,
//! no parameters, no services), so a client can subscribe to what is
//! listed and do nothing else. It binds to loopback unless told otherwise.

pub mod air_health;
pub mod front_door;
pub mod layout;
pub mod plots;
pub mod scene;
pub mod site_log;
pub mod topics;

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use foxglove::messages::{FrameTransform, FrameTransforms, Timestamp, Vector3};
use foxglove::{Channel, Context, RawChannel, WebSocketServerHandle};
use ickon_proto::keys::Keys;
use ickon_proto::msg::admin::{StatusReport, TransmittersReport};
use ickon_proto::site::Site;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use zenoh::Session;

use crate::http::feed::{Feed, SharedView, Stopwatch, ViewSink};
use crate::http::view::{LiveView, Snapshot};
use topics::{CellChannels, RobotChannels};

/// The address `--foxglove` binds with no value: loopback, Foxglove's
/// usual port.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// How often the fleet, the cells and the plots are sent: 10 Hz, the rate
/// a site's poses come at, so a pose is rarely held back more than one tick.
pub const TICK_PERIOD: Duration = Duration::from_millis(100);

/// The site's fixed scene is sent again every this many ticks (1 s), for
/// clients that join later: a scene entity stays until it is replaced.
const SITE_SCENE_EVERY_TICKS: u64 = 10;

/// The Foxglove flag of the central unit.
#[derive(Debug, Clone, Default, Args)]
pub struct FoxgloveArgs {
    /// Serve the site, the fleet and every fix live to the Foxglove app on
    /// ADDR (with no ADDR: 127.0.0.1:8765), read-only and without
    /// authentication: whoever reaches the port sees them (docs/foxglove.md).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub foxglove: Option<SocketAddr>,
}

/// Why the Foxglove server could not start.
#[derive(Debug, thiserror::Error)]
pub enum FoxgloveError {
    /// The server could not start on the address.
    #[error("cannot serve Foxglove on {addr}: {reason}")]
    Start {
        /// The address.
        addr: SocketAddr,
        /// Why.
        reason: String,
    },
    /// Zenoh refused a subscriber.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

/// The running Foxglove server (or the same channels handed to a sink, for
/// a recording). Dropping it stops the server and the feed.
pub struct FoxgloveLive {
    addr: Option<SocketAddr>,
    status: watch::Sender<Option<StatusReport>>,
    transmitters: watch::Sender<Option<TransmittersReport>>,
    server: Option<WebSocketServerHandle>,
    door: Option<JoinHandle<()>>,
    ticker: JoinHandle<()>,
    view: ViewSink,
    /// A recorder's own subscribers (`None` in the central unit).
    _feed: Option<Feed>,
}

impl FoxgloveLive {
    /// Starts serving `site` as `args` say (`None` when `--foxglove` is absent).
    pub async fn start(site: &Site, args: &FoxgloveArgs) -> Result<Option<Self>, FoxgloveError> {
        let Some(wanted) = args.foxglove else {
            return Ok(None);
        };
        let start_error = |e: &dyn std::fmt::Display| FoxgloveError::Start {
            addr: wanted,
            reason: e.to_string(),
        };
        // The public port is the front door's; the SDK's server listens on
        // loopback behind it.
        let door = tokio::net::TcpListener::bind(wanted)
            .await
            .map_err(|e| start_error(&e))?;
        let addr = door.local_addr().map_err(|e| start_error(&e))?;
        let context = Context::new();
        let channels = Channels::new(&context, site);
        let server = context
            .websocket_server()
            .name(format!("ickon-central {}", site.name))
            .bind("127.0.0.1", 0)
            .start()
            .await
            .map_err(|e| start_error(&e))?;
        let inner = SocketAddr::from(([127, 0, 0, 1], server.port()));
        let mut live = Self::feed(None, site, context, channels, true).await?;
        live.addr = Some(addr);
        live.server = Some(server);
        live.door = Some(tokio::spawn(front_door::serve(door, inner)));
        tracing::info!("Foxglove live server at ws://{addr} (read-only)");
        Ok(Some(live))
    }

    /// The same channels as the live server, handed to `sink` instead of
    /// served: a recording that holds them looks in Foxglove as the live
    /// view does. The status comes through [`Self::publish`] as for the
    /// server.
    pub async fn into_sink(
        session: &Session,
        keys: &Keys,
        site: &Site,
        sink: Arc<dyn foxglove::Sink>,
    ) -> Result<Self, FoxgloveError> {
        let context = Context::new();
        let channels = Channels::new(&context, site);
        context.add_sink(sink);
        Self::feed(Some((session, keys)), site, context, channels, false).await
    }

    /// Makes the view and starts the ticker on `context`; with a session,
    /// subscribes the view to the site (a recorder; the central unit's
    /// loop feeds it through [`Self::sink`]); with `own_warnings`, the
    /// process's warnings and errors go to the log channel too (the central
    /// unit's; a recorder's are not the site's).
    async fn feed(
        subscribe: Option<(&Session, &Keys)>,
        site: &Site,
        context: Arc<Context>,
        channels: Channels,
        own_warnings: bool,
    ) -> Result<Self, FoxgloveError> {
        let clock = Stopwatch::start();
        let view = SharedView::new(LiveView::new(site));
        let feed = match subscribe {
            Some((session, keys)) => Some(
                Feed::start(session, keys, &view, clock)
                    .await
                    .map_err(|e| FoxgloveError::Zenoh(e.to_string()))?,
            ),
            None => None,
        };
        let sink = ViewSink::new(view.clone(), clock);
        let (status_tx, status_rx) = watch::channel(None);
        let (transmitters_tx, transmitters_rx) = watch::channel(None);
        let ticker = tokio::spawn(tick(
            Ticker {
                context,
                site: site.clone(),
                channels,
                log: site_log::SiteLog::default(),
                own_warnings,
            },
            view,
            Reports {
                status: status_rx,
                transmitters: transmitters_rx,
            },
            clock,
        ));
        Ok(Self {
            addr: None,
            status: status_tx,
            transmitters: transmitters_tx,
            server: None,
            door: None,
            ticker,
            view: sink,
            _feed: feed,
        })
    }

    /// The address being served (`None` when the channels go to a sink).
    pub fn addr(&self) -> Option<SocketAddr> {
        self.addr
    }

    /// Where the central unit's loop hands the view what it draws.
    pub fn sink(&self) -> &ViewSink {
        &self.view
    }

    /// Hands the central unit's latest status to the server (never waits).
    pub fn publish(&self, status: StatusReport) {
        self.status.send_replace(Some(status));
    }

    /// Hands the central unit's latest transmitters report (each
    /// transmitter's health, the boards' air) to the server (never waits).
    pub fn publish_transmitters(&self, report: TransmittersReport) {
        self.transmitters.send_replace(Some(report));
    }

    /// A handle that hands statuses to the view from another task, as
    /// [`Self::publish`] does.
    pub fn status_sender(&self) -> impl Fn(StatusReport) + Send + 'static {
        let status = self.status.clone();
        move |report| {
            status.send_replace(Some(report));
        }
    }
}

impl Drop for FoxgloveLive {
    fn drop(&mut self) {
        self.ticker.abort();
        if let Some(door) = self.door.take() {
            door.abort();
        }
        if let Some(server) = self.server.take() {
            // The shutdown goes on in the server's own tasks.
            drop(server.stop());
        }
    }
}

/// The channels of the whole site, and those made for each robot and cell.
struct Channels {
    site_scene: Channel<foxglove::messages::SceneUpdate>,
    cells_scene: Channel<foxglove::messages::SceneUpdate>,
    robots_scene: Channel<foxglove::messages::SceneUpdate>,
    tf: Channel<FrameTransforms>,
    log: Channel<foxglove::messages::Log>,
    status: Arc<RawChannel>,
    speed: Arc<RawChannel>,
    transmitters_scene: Channel<foxglove::messages::SceneUpdate>,
    transmitters_status: Arc<RawChannel>,
    robots: BTreeMap<String, RobotChannels>,
    cells: BTreeMap<String, CellChannels>,
}

impl Channels {
    /// Every channel of `site`, advertised at once so that a client sees
    /// the whole list when it connects.
    fn new(context: &Arc<Context>, site: &Site) -> Self {
        let mut channels = Self {
            site_scene: context.channel_builder(topics::SITE_SCENE).build(),
            cells_scene: context.channel_builder(topics::CELLS_SCENE).build(),
            robots_scene: context.channel_builder(topics::ROBOTS_SCENE).build(),
            tf: context.channel_builder(topics::TF).build(),
            log: context.channel_builder(topics::LOG).build(),
            status: plots::status_channel(context, topics::SITE_STATUS),
            speed: air_health::speed_channel(context, topics::SPEED_OF_SOUND),
            transmitters_scene: context.channel_builder(topics::TRANSMITTERS_SCENE).build(),
            transmitters_status: air_health::health_channel(context, topics::TRANSMITTERS_STATUS),
            robots: BTreeMap::new(),
            cells: BTreeMap::new(),
        };
        for r in &site.robots {
            channels.robot(context, &r.id);
        }
        for c in &site.cells {
            channels.cell(context, &c.id);
        }
        channels
    }

    fn robot(&mut self, context: &Arc<Context>, id: &str) -> &RobotChannels {
        self.robots
            .entry(id.to_string())
            .or_insert_with(|| RobotChannels::new(context, id))
    }

    fn cell(&mut self, context: &Arc<Context>, id: &str) -> &CellChannels {
        self.cells
            .entry(id.to_string())
            .or_insert_with(|| CellChannels::new(context, id))
    }
}

/// What the ticker owns.
struct Ticker {
    context: Arc<Context>,
    site: Site,
    channels: Channels,
    log: site_log::SiteLog,
    /// Whether the process's own warnings go to the log channel.
    own_warnings: bool,
}

impl Ticker {
    /// Sends the speed of sound of `status` and, when a transmitters
    /// report has come, each transmitter's health.
    fn send_air_and_health(
        &self,
        status: &StatusReport,
        transmitters: Option<&TransmittersReport>,
        stamp: Timestamp,
    ) {
        air_health::log_speed(&self.channels.speed, status, transmitters);
        if let Some(report) = transmitters {
            self.channels
                .transmitters_scene
                .log(&air_health::transmitters_scene(&self.site, report, stamp));
            air_health::log_health(&self.channels.transmitters_status, report);
        }
    }

    /// Sends everything one snapshot shows.
    fn send(&mut self, snapshot: &Snapshot, tick: u64) {
        let stamp = Timestamp::now();
        if tick.is_multiple_of(SITE_SCENE_EVERY_TICKS) {
            // Routes only in a simulation: there they are what the robots drive.
            let simulated = snapshot.robots.iter().any(|r| r.truth.is_some());
            let scene = scene::site_scene(&self.site, simulated, stamp);
            self.channels.site_scene.log(&scene);
        }
        self.channels
            .cells_scene
            .log(&scene::cells_scene(&self.site, snapshot, stamp));
        self.channels
            .robots_scene
            .log(&scene::robots_scene(snapshot, stamp));
        let transforms = snapshot
            .robots
            .iter()
            .filter_map(|r| {
                let p = r.fused.as_ref()?;
                Some(FrameTransform {
                    timestamp: Some(stamp),
                    parent_frame_id: scene::MAP_FRAME.into(),
                    child_frame_id: r.health.id.clone(),
                    translation: Some(Vector3 {
                        x: p.x_m,
                        y: p.y_m,
                        z: 0.0,
                    }),
                    rotation: Some(scene::yaw_quaternion(p.theta_rad)),
                })
            })
            .collect();
        self.channels.tf.log(&FrameTransforms { transforms });
        plots::log_status(&self.channels.status, snapshot);
        let period = scene::cycle_period_ms(snapshot.update_rate_hz);
        for r in &snapshot.robots {
            self.channels
                .robot(&self.context, &r.health.id)
                .send(r, stamp);
        }
        for c in &snapshot.cells {
            self.channels
                .cell(&self.context, &c.health.id)
                .send(c, period);
        }
        for entry in self.log.update(snapshot, stamp) {
            self.channels.log.log(&entry);
        }
        if self.own_warnings {
            let (lines, lost) = ickon_runtime::warnings::drain();
            for entry in site_log::process_warnings(&lines, lost, stamp) {
                self.channels.log.log(&entry);
            }
        }
    }
}

/// The central unit's reports as they are handed to the server.
struct Reports {
    status: watch::Receiver<Option<StatusReport>>,
    transmitters: watch::Receiver<Option<TransmittersReport>>,
}

/// Makes and sends a snapshot every [`TICK_PERIOD`] until the status
/// channel closes.
async fn tick(mut ticker: Ticker, view: SharedView, mut reports: Reports, clock: Stopwatch) {
    let status = &mut reports.status;
    let mut ticks = tokio::time::interval(TICK_PERIOD);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut count = 0u64;
    loop {
        ticks.tick().await;
        if status.has_changed().is_err() {
            return;
        }
        let Some(report) = status.borrow_and_update().clone() else {
            continue;
        };
        let snapshot = view.lock().snapshot(&report, clock.now(), 0, 0);
        ticker.send(&snapshot, count);
        let transmitters = reports.transmitters.borrow_and_update().clone();
        ticker.send_air_and_health(&report, transmitters.as_ref(), Timestamp::now());
        count = count.wrapping_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: FoxgloveArgs,
    }

    fn parse(argv: &[&str]) -> Result<Option<SocketAddr>, clap::Error> {
        Cli::try_parse_from(std::iter::once("central").chain(argv.iter().copied()))
            .map(|c| c.args.foxglove)
    }

    #[test]
    fn the_server_binds_to_loopback_unless_an_address_is_given() {
        assert_eq!(parse(&[]).unwrap(), None);
        let default = parse(&["--foxglove"]).unwrap().unwrap();
        assert!(default.ip().is_loopback(), "{default}");
        assert_eq!(default.port(), 8765);
        assert_eq!(
            parse(&["--foxglove", "0.0.0.0:9000"]).unwrap(),
            Some("0.0.0.0:9000".parse().unwrap())
        );
        assert!(parse(&["--foxglove", "not-an-address"]).is_err());
    }
}
