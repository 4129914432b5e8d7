//! The cell controller as a Zenoh node: a thin adapter around [`CellCore`].
//! It decodes triggers and schedules, watches the central unit's liveliness,
//! carries out the core's requests (clock exchanges over `central/clock`,
//! schedule queries) in tasks beside the loop so that nothing the core must
//! do on time waits behind them, programs bursts through the
//! [`TransmitterDriver`] chosen at start, and publishes bursts and status.

use std::future::Future;
use std::process::ExitCode;
use std::time::Duration as StdDuration;

use clap::Args;
use ickon_proto::keys::Keys;
use ickon_proto::msg::control::{AirTemperature, ClockReply, ClockRequest, CycleTrigger, Schedule};
use ickon_proto::time::Time;
use ickon_proto::{decode, encode};
use ickon_runtime::{
    NodeArgs, NodeError, SimulatedClock, SiteJoin, Stamped, put_counted, query_once, query_stamped,
    zerr,
};
use tokio::sync::mpsc;
use zenoh::Session;
use zenoh::pubsub::Publisher;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::SampleKind;

use crate::core::{CellConfig, CellCore, Event, Output};
use crate::device::BoardTransmitters;
use crate::driver::{SimulatedDriver, TransmitterDriver};
use crate::sync::ClockSample;
use ickon_runtime::link::LinkAddress;

/// Which transmitter driver the cell uses.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum DriverKind {
    /// The simulated transmitters of `ickon sim` (bursts reported at their
    /// true emission time, for the simulated world to hear).
    #[default]
    Sim,
    /// A transmitter board of the device protocol at this address.
    Board(LinkAddress),
}

impl std::str::FromStr for DriverKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "sim" {
            return Ok(DriverKind::Sim);
        }
        s.parse()
            .map(DriverKind::Board)
            .map_err(|e| format!("{e} (or `sim`)"))
    }
}

impl std::fmt::Display for DriverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DriverKind::Sim => f.write_str("sim"),
            DriverKind::Board(a) => a.fmt(f),
        }
    }
}

/// Arguments of `ickon-cell` (and `ickon node cell`).
#[derive(Debug, Clone, Args)]
pub struct CellArgs {
    /// Connection and simulation flags.
    #[command(flatten)]
    pub node: NodeArgs,
    /// The cell this controller drives.
    #[arg(long)]
    pub cell: String,
    /// The transmitter driver: `sim` (the simulated transmitters), or a
    /// transmitter board of the ICKON device protocol at `serial:PATH[@BAUD]`
    /// (115200 baud when not given) or `tcp:HOST:PORT`.
    #[arg(long, default_value_t = DriverKind::Sim, value_name = "sim|serial:PATH[@BAUD]|tcp:HOST:PORT")]
    pub driver: DriverKind,
}

/// How long a clock exchange may take before it counts as unanswered.
const CLOCK_TIMEOUT: StdDuration = StdDuration::from_millis(500);
/// How long a schedule query may take.
const SCHEDULE_TIMEOUT: StdDuration = StdDuration::from_millis(500);

/// Runs the cell controller as a process until Ctrl-C/SIGTERM.
pub fn main_with(args: CellArgs) -> ExitCode {
    if let Err(e) = ickon_proto::keys::validate_id(&args.cell) {
        eprintln!("error: --cell: {e}");
        return ExitCode::from(2);
    }
    ickon_runtime::run_node(1, async {
        let session = args.node.open().await?;
        let r = run(&session, &args, args.node.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

/// The cell's transmitters: simulated, or a board (whose reports come
/// through [`BoardTransmitters::next`]).
enum Transmitters {
    Sim(Box<dyn TransmitterDriver>),
    Board(Box<BoardTransmitters>),
}

impl Transmitters {
    /// The driver `kind` for `cell` on `clock`.
    fn open(kind: &DriverKind, cell: &str, clock: SimulatedClock) -> Self {
        match kind {
            DriverKind::Sim => Self::Sim(Box::new(SimulatedDriver::new(cell, move |local| {
                clock.true_time(local)
            }))),
            DriverKind::Board(address) => Self::Board(Box::new(BoardTransmitters::open(
                cell,
                address.clone(),
                clock,
            ))),
        }
    }

    fn driver(&mut self) -> &mut dyn TransmitterDriver {
        match self {
            Self::Sim(d) => d.as_mut(),
            Self::Board(b) => b.as_mut(),
        }
    }

    /// The transmitter device in a line for an operator (nothing for the
    /// simulated driver).
    fn summary(&self) -> String {
        match self {
            Self::Sim(_) => String::new(),
            Self::Board(b) => b.summary(),
        }
    }

    /// The board's air temperature readings since the last call (none for
    /// simulated transmitters): (local time, degrees Celsius).
    fn take_air(&mut self) -> Vec<(Time, f64)> {
        match self {
            Self::Sim(_) => Vec::new(),
            Self::Board(b) => b.take_air(),
        }
    }

    /// The board's next emission reports; never, for simulated transmitters.
    async fn reports(&mut self) -> Vec<ickon_proto::msg::control::Burst> {
        match self {
            Self::Sim(_) => std::future::pending().await,
            Self::Board(b) => b.next().await,
        }
    }
}

/// One four-timestamp exchange with the master; `None` if it did not answer.
/// `t4` is read in Zenoh's receive path (see [`query_stamped`]); `t1` is the
/// middle of the time Zenoh took to send the request.
/// With `epoch` (the central unit followed), only its answer is taken, so
/// a rogue or standby answer that comes first does not hide it.
async fn exchange(
    session: Session,
    key: String,
    cell: String,
    clock: SimulatedClock,
    epoch: Option<u64>,
) -> Result<Option<ClockSample>, NodeError> {
    let t1 = clock.now();
    let request = encode(&ClockRequest { cell_id: cell, t1 })?;
    let wanted = move |r: &ClockReply| r.t1 == t1 && epoch.is_none_or(|e| r.epoch == e);
    let reply: Option<Stamped<ClockReply>> = query_stamped(
        &session,
        &key,
        request,
        CLOCK_TIMEOUT,
        move || clock.now(),
        wanted,
    )
    .await?;
    // The request left some time between the call and Zenoh having taken
    // it; the sync slave allows for the typical time (see `crate::sync`).
    Ok(reply.filter(|r| r.value.t1 == t1).map(|r| ClockSample {
        t1,
        t2: r.value.t2,
        t3: r.value.t3,
        t4: r.received,
        epoch: r.value.epoch,
        queued_ns: r.sent.since(t1).as_nanos(),
    }))
}

/// Counts of what the adapter could not do; logged at the end of the run.
#[derive(Debug, Default)]
struct Failures {
    puts: u64,
    driver: u64,
    undecodable: u64,
}

/// Drives cell `args.cell` until `shutdown` completes.
pub async fn run(
    session: &Session,
    args: &CellArgs,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NodeError> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(args.node.site_name())?;
    let cell = args.cell.as_str();
    let clock = args.node.clock();
    args.node.listen_for_clock_steps(clock)?;
    let driver = Transmitters::open(&args.driver, cell, clock);
    let mut core = CellCore::new(cell, CellConfig::default(), clock.now());
    let join = SiteJoin::new(session, &keys);
    let triggers = join.subscribe(keys.central_cycle()).await?;
    let schedules = join.subscribe(keys.central_schedule()).await?;
    let central_alive = join.watch_tokens(keys.alive_central()).await?;
    let [burst_pub, status_pub, air_pub] = declare_publishers(session, &keys, cell).await?;
    // Replies to the core's requests come back through this channel.
    let (replies_tx, mut replies) = mpsc::unbounded_channel::<Event>();
    // The schedule in force now, before the token: the central unit
    // schedules this cell when it sees the token, and by then the cell
    // hears schedules and triggers.
    if let Ok(Some(s)) = join.schedule_once(SCHEDULE_TIMEOUT).await {
        let _ = replies_tx.send(Event::Schedule(s));
    }
    let _token = join.announce(keys.alive_cell(cell)?).await?;
    // Its link to the router, for `ickon admin status` (when it last came back).
    ickon_runtime::router_watch::report(session.clone(), keys.cell_link(cell)?, cell.into())
        .map_err(|e| NodeError::Setup(format!("cannot start the router link report: {e}")))?;
    tracing::info!(
        "cell {cell}: up, driver {}, clock offset {} us, drift {} ppm",
        args.driver,
        args.node.clock_offset_us,
        args.node.clock_drift_ppm
    );

    let mut outlets = Outlets {
        session,
        keys: &keys,
        cell,
        clock,
        driver,
        burst_pub,
        status_pub,
        air_pub,
        replies_tx,
        failures: Failures::default(),
        driver_log: ickon_runtime::LogLimiter::default(),
    };
    let mut stopping = false;
    while !stopping {
        let wake = core.next_wake().since(clock.now()).to_std();
        let event = tokio::select! {
            _ = &mut shutdown => {
                stopping = true;
                Event::Shutdown
            }
            _ = tokio::time::sleep(wake) => Event::Tick,
            Some(ev) = replies.recv() => ev,
            reports = outlets.driver.reports() => {
                for report in reports {
                    outlets.publish_burst(&report).await;
                }
                outlets.publish_air(&core).await;
                continue;
            }
            Ok(s) = central_alive.recv_async() => Event::CentralAlive(s.kind() != SampleKind::Delete),
            Ok(s) = schedules.recv_async() => match decode::<Schedule>(&s.payload().to_bytes()) {
                Ok(schedule) => Event::Schedule(schedule),
                Err(e) => {
                    outlets.failures.undecodable += 1;
                    tracing::debug!("cell {cell}: undecodable schedule: {e}");
                    continue;
                }
            },
            Ok(s) = triggers.recv_async() => match decode::<CycleTrigger>(&s.payload().to_bytes()) {
                Ok(t) => Event::Trigger(t),
                Err(e) => {
                    outlets.failures.undecodable += 1;
                    tracing::debug!("cell {cell}: undecodable trigger: {e}");
                    continue;
                }
            },
        };
        for output in core.handle(clock.now(), event) {
            outlets.carry_out(output, &core).await;
        }
    }
    let failures = outlets.failures;
    if failures.puts + failures.driver + failures.undecodable > 0 {
        tracing::info!("cell {cell}: stopped; {failures:?}");
    }
    Ok(())
}

/// The cell's burst, status and air temperature publishers; the bursts
/// sent at once with real-time priority, blocking rather than dropping
/// when a link is busy.
async fn declare_publishers(
    session: &Session,
    keys: &Keys,
    cell: &str,
) -> Result<[Publisher<'static>; 3], NodeError> {
    let burst_pub = session
        .declare_publisher(keys.cell_burst(cell)?)
        .express(true)
        .priority(Priority::RealTime)
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(zerr)?;
    let status_pub = session
        .declare_publisher(keys.cell_status(cell)?)
        .await
        .map_err(zerr)?;
    let air_pub = session
        .declare_publisher(keys.cell_air(cell)?)
        .await
        .map_err(zerr)?;
    Ok([burst_pub, status_pub, air_pub])
}

/// Where the core's outputs go: the transmitter driver, the burst and
/// status publishers, and the requests carried out beside the loop (their
/// replies come back through `replies_tx`).
struct Outlets<'a> {
    session: &'a Session,
    keys: &'a Keys,
    cell: &'a str,
    clock: SimulatedClock,
    driver: Transmitters,
    burst_pub: Publisher<'static>,
    status_pub: Publisher<'static>,
    air_pub: Publisher<'static>,
    replies_tx: mpsc::UnboundedSender<Event>,
    failures: Failures,
    /// A driver that cannot fire (a board not ready, gone) fails every
    /// slot: logged once per window, with the count held back.
    driver_log: ickon_runtime::LogLimiter<&'static str>,
}

impl Outlets<'_> {
    /// Publishes an emission report.
    async fn publish_burst(&mut self, report: &ickon_proto::msg::control::Burst) {
        if !put_counted(&self.burst_pub, report).await {
            self.failures.puts += 1;
        }
    }

    /// Publishes the board's air temperature readings, stamped on the
    /// master time base as the cell knows it (its own clock before it is
    /// synchronised).
    async fn publish_air(&mut self, core: &CellCore) {
        for (local, temperature_c) in self.driver.take_air() {
            let stamp = core.sync().estimate().map_or(local, |e| e.to_master(local));
            let reading = AirTemperature {
                cell_id: self.cell.to_string(),
                stamp,
                temperature_c,
            };
            if !put_counted(&self.air_pub, &reading).await {
                self.failures.puts += 1;
            }
        }
    }

    /// Carries out one output of `core`: programs a burst and publishes its
    /// report, publishes a status, or starts a clock exchange or a schedule
    /// query.
    async fn carry_out(&mut self, output: Output, core: &CellCore) {
        let cell = self.cell;
        match output {
            Output::Fire(b) => match self.driver.driver().program(&b) {
                Ok(Some(report)) => self.publish_burst(&report).await,
                Ok(None) => {}
                Err(e) => {
                    self.failures.driver += 1;
                    if let Some(held) = self
                        .driver_log
                        .admit("not programmed", std::time::Instant::now())
                    {
                        tracing::warn!(
                            "cell {cell}: tx {} not programmed: {e} ({held} more since)",
                            b.tx_id
                        );
                    }
                }
            },
            Output::Status(mut status) => {
                status.device = self.driver.summary();
                if !put_counted(&self.status_pub, &status).await {
                    self.failures.puts += 1;
                }
            }
            Output::RequestClock => {
                spawn_exchange(
                    self.session,
                    self.keys,
                    cell,
                    self.clock,
                    core.epoch(),
                    &self.replies_tx,
                );
            }
            Output::RequestSchedule => {
                let (session, key, tx) = (
                    self.session.clone(),
                    self.keys.central_schedule(),
                    self.replies_tx.clone(),
                );
                tokio::spawn(async move {
                    let ev = match query_once::<Schedule>(&session, &key, None, SCHEDULE_TIMEOUT)
                        .await
                    {
                        Ok(Some(s)) => Event::Schedule(s),
                        _ => Event::ScheduleUnanswered,
                    };
                    let _ = tx.send(ev);
                });
            }
        }
    }
}

/// Starts one clock exchange beside the loop; its result comes back as an event.
fn spawn_exchange(
    session: &Session,
    keys: &Keys,
    cell: &str,
    clock: SimulatedClock,
    epoch: Option<u64>,
    replies: &mpsc::UnboundedSender<Event>,
) {
    let (session, key, cell, tx) = (
        session.clone(),
        keys.central_clock(),
        cell.to_string(),
        replies.clone(),
    );
    tokio::spawn(async move {
        let sample = match exchange(session, key, cell.clone(), clock, epoch).await {
            Ok(s) => s,
            Err(e) => {
                tracing::debug!("cell {cell}: clock exchange failed: {e}");
                None
            }
        };
        let _ = tx.send(Event::ClockExchange(sample));
    });
}

#[cfg(test)]
mod tests {
    use clap::Args;

    /// The `ickon-cell` binary's command line (`src/main.rs`): a flag defined
    /// twice panics only when parsed, so the definition is checked here.
    #[test]
    fn the_binarys_command_line_is_well_formed() {
        let command = clap::Command::new("ickon-cell").version("0");
        super::CellArgs::augment_args(command).debug_assert();
    }
}
