//! The central unit as a Zenoh node: serves the site, the schedule and the
//! master clock, publishes cycle triggers, watches liveliness, bursts, cell
//! status and the robots' summaries, and answers the admin queryables. All decisions
//! are the [`CentralCore`]'s; this loop only moves bytes.

use std::future::Future;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use clap::Args;
use ickon_proto::keys::{Key, Keys};
use ickon_proto::msg::admin::{CoverageRequest, RobotCounts, RobotPage, RobotsRequest};
use ickon_proto::msg::control::{
    AirTemperature, Burst, CellStatus, ClockRequest, RouterLink, Schedule,
};
use ickon_proto::msg::robot::{MsuStatus, RobotSummary, Truth};

use crate::survey_calibration::SavedCalibration;
use ickon_proto::site::Site;
use ickon_proto::time::Time;
use ickon_proto::{decode, encode};
use ickon_runtime::{LogLimiter, NodeArgs, NodeError, SimulatedClock, put_counted, zerr};
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::query::{Query, Queryable};
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, Wait};

use crate::core::{CentralConfig, CentralCore, Event, Output};

/// Arguments of `ickon-central` (and `ickon node central`).
#[derive(Debug, Clone, Args)]
pub struct CentralArgs {
    /// Connection and simulation flags.
    #[command(flatten)]
    pub node: NodeArgs,
    /// The web map's flags.
    #[command(flatten)]
    pub http: crate::http::HttpArgs,
    /// The Foxglove live server's flag.
    #[command(flatten)]
    pub foxglove: crate::foxglove::FoxgloveArgs,
    /// Start as a hot standby: follow the active central unit and take
    /// over when its liveliness token goes or its triggers stop for two
    /// cycles (see `ickon_central::core::standby`).
    #[arg(long)]
    pub standby: bool,
    /// Which transmitters fire each cycle: `needs` (a few in good geometry
    /// for each robot, spaced by the room's reverberation), `occupancy`
    /// (everything audible where robots may be) or `all` (the whole
    /// schedule every cycle). With `needs` and `occupancy` the whole
    /// schedule fires while no robot is known, and the MSU agents follow
    /// the cycle triggers' firing sets.
    #[arg(long, value_enum, default_value_t = Firing::Occupancy)]
    pub firing: Firing,
    /// Do not learn the transmitters' survey errors from the robots' fixes
    /// (nor publish them on `central/survey`).
    #[arg(long)]
    pub no_survey_calibration: bool,
    /// Do not publish the speed of sound learnt from the robots' fixes:
    /// the MSUs use the site file's throughout.
    #[arg(long)]
    pub no_speed_of_sound: bool,
    /// One-sigma timing noise of one arrival, microseconds: what the MSUs'
    /// data sheet states (their `timing_sigma_us`); weighs each fix in the
    /// survey calibration.
    #[arg(long, default_value_t = 50.0, value_parser = timing_sigma_us)]
    pub timing_sigma_us: f64,
    /// One-sigma error of a cell's sync, microseconds: how far the site's
    /// network may leave a cell's clock from the central unit's (half its
    /// paths' asymmetry, which no clock exchange sees). The prior of each
    /// cell's lateness in the survey calibration, which the MSUs take from
    /// that cell's pseudo-ranges; 0 keeps every cell on time.
    #[arg(long, default_value_t = 60.0, value_parser = cell_sync_sigma_us)]
    pub cell_sync_sigma_us: f64,
    /// How long the survey calibration remembers a cell's lateness,
    /// hours (its correlation time): a cell whose network path changes is
    /// followed within about this long; 0 remembers it for good.
    #[arg(long, default_value_t = 24.0, value_parser = cell_sync_memory_h)]
    pub cell_sync_memory_h: f64,
    /// Keep the survey calibration in this file (JSON), so that a restart
    /// goes on from what the fleet taught it: read at start when it
    /// exists (a file of another site or transmitter table is set aside
    /// with a warning; an unreadable or broken one stops the start, exit
    /// 2), written every minute and at shutdown.
    #[arg(long)]
    pub survey_file: Option<std::path::PathBuf>,
}

/// Largest survey calibration file read, bytes (a site of 1000
/// transmitters keeps about 9 million numbers; this is far above any site
/// this unit can serve, and below what would exhaust memory).
const MAX_SURVEY_FILE_BYTES: u64 = 256 << 20;

/// How often the survey calibration file is written.
const SURVEY_SAVE_PERIOD: std::time::Duration = std::time::Duration::from_secs(60);

/// Reads the survey calibration kept in `path` for `site`: `Ok(None)` when
/// there is no file or it is of another site or table (said in a
/// warning); `Err` with the file and the reason when it cannot be read or
/// its numbers are broken.
pub fn load_survey_file(
    path: &std::path::Path,
    site: &Site,
    config: crate::survey_calibration::CalibrationConfig,
) -> Result<Option<SavedCalibration>, String> {
    use crate::survey_calibration::{SavedMismatch, SurveyCalibration};
    let shown = path.display();
    let size = match std::fs::metadata(path) {
        Ok(m) => m.len(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{shown}: {e}")),
    };
    if size > MAX_SURVEY_FILE_BYTES {
        return Err(format!(
            "{shown}: {size} bytes, more than a survey calibration ({MAX_SURVEY_FILE_BYTES} at most)"
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("{shown}: {e}"))?;
    let saved: SavedCalibration = serde_json::from_str(&text)
        .map_err(|e| format!("{shown}: not a survey calibration: {e}"))?;
    match SurveyCalibration::restored(site, config, &saved) {
        Ok(_) => Ok(Some(saved)),
        Err(SavedMismatch::OtherSite) => {
            tracing::warn!(
                "{shown}: the calibration is of another site or transmitter table: starting from the survey (the file is overwritten)"
            );
            Ok(None)
        }
        Err(e @ SavedMismatch::Broken(_)) => Err(format!("{shown}: {e}")),
    }
}

/// Writes `saved` to `path` through a temporary file beside it, so that a
/// crash mid-write leaves the previous file whole.
fn save_survey_file(path: &std::path::Path, saved: &SavedCalibration) {
    let tmp = path.with_extension("tmp");
    let written = serde_json::to_vec(saved)
        .map_err(std::io::Error::other)
        .and_then(|bytes| std::fs::write(&tmp, bytes))
        .and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = written {
        tracing::warn!("survey calibration not saved to {}: {e}", path.display());
    }
}

/// `--cell-sync-sigma-us`: microseconds from 0 up to a second.
fn cell_sync_sigma_us(text: &str) -> Result<f64, String> {
    micros_up_to_a_second(text, true)
}

/// `--cell-sync-memory-h`: hours from 0 up to a year (8760).
fn cell_sync_memory_h(text: &str) -> Result<f64, String> {
    let v = text.parse::<f64>().map_err(|e| format!("{text:?}: {e}"))?;
    if (0.0..=8760.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is not in [0, 8760] h"))
    }
}

/// `--timing-sigma-us`: a positive number of microseconds up to a second.
fn timing_sigma_us(text: &str) -> Result<f64, String> {
    micros_up_to_a_second(text, false)
}

/// A number of microseconds up to a second, above 0 (or from 0 when
/// `zero_allowed`); NaN is in no range.
fn micros_up_to_a_second(text: &str, zero_allowed: bool) -> Result<f64, String> {
    let v = text.parse::<f64>().map_err(|e| format!("{text:?}: {e}"))?;
    let above_floor = if zero_allowed { v >= 0.0 } else { v > 0.0 };
    if above_floor && v <= 1e6 {
        Ok(v)
    } else {
        let open = if zero_allowed { '[' } else { '(' };
        Err(format!("{v} is not in {open}0, 1000000] us"))
    }
}

/// The central unit's firing policy, as a flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Firing {
    /// Every emission of the schedule, every cycle.
    All,
    /// Only the transmitters audible from some robot's uncertainty region.
    Occupancy,
    /// A few transmitters in good geometry for each robot, spaced by the
    /// room's reverberation
    Needs,
}

impl CentralArgs {
    /// The core's configuration these flags ask for on `site`.
    pub fn core_config(&self, site: &Site) -> CentralConfig {
        let mut config = CentralConfig::default();
        config.firing.occupancy = self.firing != Firing::All;
        if self.firing == Firing::Needs {
            config.firing.needs = Some(crate::selection::NeedsConfig::default());
            config.firing.reverb = Some(crate::spacing::Reverb::default());
        }
        config.survey =
            (!self.no_survey_calibration).then(|| crate::survey_calibration::CalibrationConfig {
                range_sigma_m: self.timing_sigma_us * 1e-6 * site.speed_of_sound_m_s,
                cell_sync_sigma_m: self.cell_sync_sigma_us * 1e-6 * site.speed_of_sound_m_s,
                cell_sync_memory_s: self.cell_sync_memory_h * 3600.0,
                learn_speed_of_sound: !self.no_speed_of_sound,
                ..Default::default()
            });
        config
    }
}

/// The central unit's site name is its site file's `name`; a `--site-name`
/// given as well must say the same, for the other nodes take theirs from
/// the flag and a central unit serving another name would never meet them.
pub fn check_site_name(given: Option<&str>, in_file: &str, file: &str) -> Result<(), String> {
    match given {
        Some(given) if given != in_file => Err(format!(
            "--site-name {given:?} differs from the name {in_file:?} in the site file {file}: \
             the central unit takes the name from the file; give the same name to every node \
             or leave --site-name out here"
        )),
        _ => Ok(()),
    }
}

/// Runs the central unit as a process: loads the site, opens the session,
/// serves until Ctrl-C/SIGTERM. Exit code 2 for a bad site file.
pub fn main_with(args: CentralArgs) -> ExitCode {
    let (site, text, name) = match Site::load_or_default(args.node.site.as_deref()) {
        Ok(loaded) => loaded,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = check_site_name(args.node.site_name.as_deref(), &site.name, &name) {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let config = args.core_config(&site);
    let saved = match (&args.survey_file, config.survey) {
        (Some(path), Some(survey)) => match load_survey_file(path, &site, survey) {
            Ok(saved) => saved,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        },
        _ => None,
    };
    ickon_runtime::run_node(2, async {
        let session = args.node.open().await?;
        tracing::info!(
            "central unit for site {:?} from {name}, listening on {:?}",
            site.name,
            args.node.zenoh.listen
        );
        let keys = Keys::new(&site.name)?;
        let web = crate::http::WebMap::start(&session, &keys, &site, &args.http)
            .await
            .map_err(|e| NodeError::Setup(e.to_string()))?;
        let foxglove = crate::foxglove::FoxgloveLive::start(&site, &args.foxglove)
            .await
            .map_err(|e| NodeError::Setup(e.to_string()))?;
        let viewers = Viewers { web, foxglove };
        let clock = args.node.clock();
        args.node.listen_for_clock_steps(clock)?;
        let r = run(
            &session,
            site,
            text,
            clock,
            &viewers,
            args.standby,
            config,
            SurveyFile {
                path: args.survey_file.clone(),
                saved,
            },
            args.node.shutdown(),
        )
        .await;
        let _ = session.close().await;
        r
    })
}

/// How often the viewers are handed the whole status (every robot's
/// health, every cell's): as often as a robot's health can change, at its
/// summary (the robots move on the viewers with each summary, handed over
/// as it is taken: `SUMMARY_PERIOD`). At the viewers' own 20 Hz, 10,000 robots' health made
/// and copied twenty times a second was a large part of the central
/// unit's core.
const VIEWER_STATUS_PERIOD: std::time::Duration = std::time::Duration::from_millis(500);

/// Whoever watches the central unit's status live: the web map
/// (`--http`) and the Foxglove server (`--foxglove`), each optional.
#[derive(Default)]
pub struct Viewers {
    /// The web map.
    pub web: Option<crate::http::WebMap>,
    /// The Foxglove live server.
    pub foxglove: Option<crate::foxglove::FoxgloveLive>,
}

impl Viewers {
    /// Whether there is any.
    pub fn any(&self) -> bool {
        self.web.is_some() || self.foxglove.is_some()
    }

    /// Hands the transmitters report `make` gives to the Foxglove server,
    /// made only when there is one (never waits).
    pub fn publish_transmitters(
        &self,
        make: impl FnOnce() -> ickon_proto::msg::admin::TransmittersReport,
    ) {
        if let Some(f) = &self.foxglove {
            f.publish_transmitters(make());
        }
    }

    /// Hands `status` to each (never waits).
    pub fn publish(&self, status: ickon_proto::msg::admin::StatusReport) {
        if let Some(f) = &self.foxglove {
            f.publish(status.clone());
        }
        if let Some(w) = &self.web {
            w.publish(status);
        }
    }

    /// Where each draws from: what the central unit's loop hands them is
    /// all they see of the robots.
    fn sinks(&self) -> impl Iterator<Item = &crate::http::feed::ViewSink> {
        let web = self.web.as_ref().map(|w| w.sink());
        web.into_iter()
            .chain(self.foxglove.as_ref().map(|f| f.sink()))
    }

    /// A robot's summary the central unit took.
    fn summary(&self, robot: &str, summary: &RobotSummary) {
        self.sinks().for_each(|v| v.summary(robot, summary));
    }

    /// A burst report.
    fn burst(&self, burst: &Burst) {
        self.sinks().for_each(|v| v.burst(burst));
    }

    /// A robot's truth (simulation only).
    fn truth(&self, robot: &str, truth: Truth) {
        self.sinks().for_each(|v| v.truth(robot, truth));
    }
}

/// Answers a query. A requester that went away is its own problem: the
/// failure is logged and the central unit carries on.
async fn reply<T: serde::Serialize>(query: &Query, value: &T) {
    let sent = match encode(value) {
        Ok(bytes) => query
            .reply(query.key_expr().clone(), bytes)
            .await
            .map_err(zerr),
        Err(e) => Err(e.into()),
    };
    if let Err(e) = sent {
        tracing::warn!("reply on {} failed: {e}", query.key_expr());
    }
}

/// The longest a central unit waits at start to learn whether another is
/// active (the routers answer a liveliness query at once; this bounds a
/// router that does not).
const ACTIVE_QUERY_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(1_000);

/// Serves `site` until `shutdown` completes. `clock` is the master time base
/// (the system clock, with an injected offset and drift in a simulation);
/// `viewers` (the web map, the Foxglove server) are handed the status
/// twice a second. With
/// `standby`, or when another central unit is active at its start, it
/// follows the active central unit until it takes over: until
/// then it answers no clock or schedule query and holds no `alive/central`
/// token, so that no cell follows it by mistake.
#[allow(clippy::too_many_arguments)]
pub async fn run(
    session: &Session,
    site: Site,
    site_toml: String,
    clock: SimulatedClock,
    viewers: &Viewers,
    standby: bool,
    config: CentralConfig,
    survey_file: SurveyFile,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NodeError> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&site.name)?;
    let active_seen = active_elsewhere(session, &keys, standby).await?;
    let mut core =
        CentralCore::starting(site, site_toml, config, clock.now(), standby, active_seen)
            .map_err(|e| NodeError::Setup(e.to_string()))?;
    restore_survey(&mut core, &survey_file);
    let mut survey_saves = tokio::time::interval(SURVEY_SAVE_PERIOD);
    survey_saves.tick().await;
    log_schedule(core.latest_schedule());
    // 0: a standby, which does not answer clock requests.
    let epoch = Arc::new(AtomicU64::new(if core.is_active() {
        core.epoch()
    } else {
        0
    }));
    let ends = Endpoints::declare(session, &keys, clock, epoch.clone(), viewers.any()).await?;
    // Declared last: whoever sees the token can query every queryable
    // above. A standby declares it when it takes over.
    let token = if core.is_active() {
        Some(
            session
                .liveliness()
                .declare_token(keys.alive_central())
                .await
                .map_err(zerr)?,
        )
    } else {
        tracing::info!("standing by: following the active central unit");
        None
    };

    let mut node = event_loop::NodeLoop {
        session,
        keys,
        clock,
        viewers,
        core,
        ends,
        survey_file,
        epoch,
        token,
        reloads: reload::Reloads::new(),
        unknown_admin: LogLimiter::default(),
        links: crate::router_links::RouterLinks::default(),
        survey_saves,
        web_ticks: tokio::time::interval(VIEWER_STATUS_PERIOD),
        failed_puts: 0,
        undecodable: 0,
    };
    loop {
        let input = tokio::select! {
            _ = &mut shutdown => break,
            input = node.next_input() => input,
        };
        node.take(input).await;
    }
    node.survey_file.save(&node.core);
    let (failed_puts, undecodable) = (node.failed_puts, node.undecodable);
    if failed_puts + undecodable > 0 {
        tracing::info!(
            "central unit stopped; {failed_puts} triggers or schedules not sent, {undecodable} undecodable reports"
        );
    }
    Ok(())
}

/// After the core took an event: the clock answers name its epoch (0 when
/// it stands by), and the `alive/central` token is held exactly while it
/// is active.
async fn follow_role(
    session: &Session,
    keys: &Keys,
    core: &CentralCore,
    epoch: &AtomicU64,
    token: &mut Option<LivelinessToken>,
) {
    epoch.store(
        if core.is_active() { core.epoch() } else { 0 },
        Ordering::Relaxed,
    );
    if core.is_active() != token.is_some() {
        *token = if core.is_active() {
            session
                .liveliness()
                .declare_token(keys.alive_central())
                .await
                .ok()
        } else {
            None
        };
    }
}

/// Whether another central unit is active already (this one was restarted
/// after the standby took over): then this one stands by instead of taking
/// the site back. Not asked when starting as a standby anyway.
async fn active_elsewhere(
    session: &Session,
    keys: &Keys,
    standby: bool,
) -> Result<bool, NodeError> {
    let active_seen = !standby
        && ickon_runtime::token_present(session, &keys.alive_central(), ACTIVE_QUERY_TIMEOUT)
            .await?;
    if active_seen {
        tracing::info!("another central unit is active: starting as its standby");
    }
    Ok(active_seen)
}

/// Goes on with the survey calibration kept in the file, if any.
fn restore_survey(core: &mut CentralCore, survey_file: &SurveyFile) {
    if let Some(saved) = &survey_file.saved {
        // Checked against this site when the file was read.
        if core.restore_survey(saved).is_ok() {
            tracing::info!(
                "survey calibration goes on from {} fixes kept in the file",
                saved.fixes_taken
            );
        }
    }
}

/// Logs the schedule the central unit starts with.
fn log_schedule(s: &Schedule) {
    tracing::info!(
        "schedule v{}: {} emissions, slot {}, cycle {} ({:.2} Hz)",
        s.version,
        s.emissions.len(),
        s.slot_length,
        s.cycle_period,
        crate::schedule::update_rate_hz(s)
    );
}

/// A subscriber or queryable with its queue.
type Queue<T> = FifoChannelHandler<T>;

/// The central unit's queryables, publishers and subscribers.
struct Endpoints {
    site_q: Queryable<Queue<Query>>,
    schedule_q: Queryable<Queue<Query>>,
    /// Answers in Zenoh's receive path; kept only to stay declared.
    _clock_q: Queryable<()>,
    admin_q: Queryable<Queue<Query>>,
    cycle_pub: Publisher<'static>,
    schedule_pub: Publisher<'static>,
    survey_pub: Publisher<'static>,
    alive: Subscriber<Queue<Sample>>,
    status_sub: Subscriber<Queue<Sample>>,
    burst_sub: Subscriber<Queue<Sample>>,
    air_sub: Subscriber<Queue<Sample>>,
    /// The robots' summaries: all the central unit hears of a robot but
    /// its token and status (never its poses and fixes, which come at the
    /// odometry and cycle rates).
    summary_sub: Subscriber<Queue<Sample>>,
    robot_status_sub: Subscriber<Queue<Sample>>,
    /// Each node's link to its router, as the node reports it.
    cell_link_sub: Subscriber<Queue<Sample>>,
    robot_link_sub: Subscriber<Queue<Sample>>,
    /// The simulation's truth, for the viewers only (declared when there
    /// are viewers).
    truth_sub: Option<Subscriber<Queue<Sample>>>,
    /// Its own keys, to notice what it did not send (its own puts come
    /// back too).
    cycle_sub: Subscriber<Queue<Sample>>,
    schedule_sub: Subscriber<Queue<Sample>>,
}

impl Endpoints {
    /// Declares everything but the liveliness token. Clock requests are
    /// answered with `clock` and the epoch in `epoch` (0: not at all); the
    /// truth is subscribed to only `for_viewers`.
    async fn declare(
        session: &Session,
        keys: &Keys,
        clock: SimulatedClock,
        epoch: Arc<AtomicU64>,
        for_viewers: bool,
    ) -> Result<Self, NodeError> {
        let site_q = session
            .declare_queryable(keys.central_site())
            .await
            .map_err(zerr)?;
        let schedule_q = session
            .declare_queryable(keys.central_schedule())
            .await
            .map_err(zerr)?;
        // Clock requests are answered in Zenoh's receive path, not in the
        // node's loop: t2 must not wait for the loop to get round to the
        // query. The answer names the epoch, which the loop may change.
        let _clock_q = session
            .declare_queryable(keys.central_clock())
            .callback(move |q| answer_clock(&q, &clock, epoch.load(Ordering::Relaxed)))
            .await
            .map_err(zerr)?;
        let admin_q = session
            .declare_queryable(keys.central_admin_all())
            .await
            .map_err(zerr)?;
        let cycle_pub = realtime_publisher(session, keys.central_cycle()).await?;
        // Like the triggers (see the survey's below): a subscriber hears a
        // schedule before the triggers that name it.
        let schedule_pub = realtime_publisher(session, keys.central_schedule()).await?;
        // With the triggers' priority and, like them, sent at once: a
        // subscriber then hears a calibration and the triggers in the order
        // they were sent (one priority's queue keeps its order; another's may
        // overtake it when a link is busy), and an MSU takes a calibration
        // from the first cycle triggered after it, so that a recorder and the
        // MSU agree on which cycle that is (`ickon_msu::control_timing`).
        let survey_pub = realtime_publisher(session, keys.central_survey()).await?;
        let alive = session
            .liveliness()
            .declare_subscriber(keys.alive_all())
            .history(true)
            .await
            .map_err(zerr)?;
        Ok(Self {
            site_q,
            schedule_q,
            _clock_q,
            admin_q,
            cycle_pub,
            schedule_pub,
            survey_pub,
            alive,
            status_sub: subscriber(session, keys.cell_status_all()).await?,
            burst_sub: subscriber(session, keys.cell_burst_all()).await?,
            air_sub: subscriber(session, keys.cell_air_all()).await?,
            summary_sub: subscriber(session, keys.robot_summary_all()).await?,
            robot_status_sub: subscriber(session, keys.robot_status_all()).await?,
            cell_link_sub: subscriber(session, keys.cell_link_all()).await?,
            robot_link_sub: subscriber(session, keys.robot_link_all()).await?,
            truth_sub: if for_viewers {
                Some(subscriber(session, keys.sim_truth_all()).await?)
            } else {
                None
            },
            cycle_sub: subscriber(session, keys.central_cycle()).await?,
            schedule_sub: subscriber(session, keys.central_schedule()).await?,
        })
    }

    /// Publishes the core's outputs; returns how many puts failed.
    async fn publish(&self, outputs: Vec<Output>) -> u64 {
        publish(
            [&self.cycle_pub, &self.schedule_pub, &self.survey_pub],
            outputs,
        )
        .await
    }
}

/// A publisher sent at once with real-time priority, blocking rather than
/// dropping when a link is busy.
async fn realtime_publisher(
    session: &Session,
    key: String,
) -> Result<Publisher<'static>, NodeError> {
    session
        .declare_publisher(key)
        .express(true)
        .priority(Priority::RealTime)
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(zerr)
}

/// A subscriber on `key` with the default queue.
async fn subscriber(
    session: &Session,
    key: String,
) -> Result<Subscriber<Queue<Sample>>, NodeError> {
    session.declare_subscriber(key).await.map_err(zerr)
}

/// A liveliness change as an event for the core (`None`: nothing it
/// follows). The active central unit's token going matters only to a
/// standby.
fn alive_event(keys: &Keys, s: &Sample, active: bool) -> Option<Event> {
    let up = s.kind() == SampleKind::Put;
    match keys.parse(s.key_expr().as_str()) {
        Ok(Key::AliveCell(id)) => Some(Event::CellAlive { id, up }),
        Ok(Key::AliveRobot(id)) => Some(Event::RobotAlive { id, up }),
        Ok(Key::AliveCentral) if !up && !active => Some(Event::ActiveGone),
        _ => None,
    }
}

/// A cell's status report, counting one that does not decode.
fn status_event(s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match decode::<CellStatus>(&s.payload().to_bytes()) {
        Ok(st) => Some(Event::CellStatus(st)),
        Err(e) => {
            *undecodable += 1;
            tracing::debug!("undecodable status on {}: {e}", s.key_expr());
            None
        }
    }
}

/// A cell board's air temperature reading, counting one that does not
/// decode. The cell is the key's: a payload naming another is not taken
/// for it.
fn air_event(keys: &Keys, s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<AirTemperature>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::CellAir(cell_id)), Ok(reading)) => {
            Some(Event::AirTemperature(AirTemperature { cell_id, ..reading }))
        }
        (_, Err(e)) => {
            *undecodable += 1;
            tracing::debug!("undecodable air temperature on {}: {e}", s.key_expr());
            None
        }
        _ => None,
    }
}

/// A node's report of its router link, under the key's id, counting one
/// that does not decode.
fn link_report(
    keys: &Keys,
    s: &Sample,
    undecodable: &mut u64,
) -> Option<(crate::router_links::NodeKind, String, RouterLink)> {
    use crate::router_links::NodeKind;
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<RouterLink>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::CellLink(id)), Ok(link)) => Some((NodeKind::Cell, id, link)),
        (Ok(Key::RobotLink(id)), Ok(link)) => Some((NodeKind::Robot, id, link)),
        (_, Err(e)) => {
            *undecodable += 1;
            tracing::debug!("undecodable router link on {}: {e}", s.key_expr());
            None
        }
        _ => None,
    }
}

/// A cell's burst report, counting one that does not decode.
fn burst_event(s: &Sample, clock: &SimulatedClock, undecodable: &mut u64) -> Option<Event> {
    match decode::<Burst>(&s.payload().to_bytes()) {
        // A simulated driver reports the true emission time: on
        // the master time base it is what this clock read then.
        Ok(b) => Some(Event::Burst(Burst {
            actual: clock.local(b.actual),
            ..b
        })),
        Err(e) => {
            *undecodable += 1;
            tracing::debug!("undecodable burst on {}: {e}", s.key_expr());
            None
        }
    }
}

/// A robot's summary, counting one whose payload does not decode.
fn summary_event(keys: &Keys, s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<RobotSummary>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::RobotSummary(robot)), Ok(summary)) => Some(Event::Summary {
            robot,
            summary: Box::new(summary),
        }),
        (_, Err(_)) => {
            *undecodable += 1;
            None
        }
        _ => None,
    }
}

/// A robot's truth (`None` when its key or payload does not parse).
fn truth_of(keys: &Keys, s: &Sample) -> Option<(String, Truth)> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<Truth>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::SimTruth(robot)), Ok(truth)) => Some((robot, truth)),
        _ => None,
    }
}

/// The next sample of `sub`; never, without one.
async fn next_sample(sub: &Option<Subscriber<Queue<Sample>>>) -> Option<Sample> {
    match sub {
        Some(sub) => sub.recv_async().await.ok(),
        None => std::future::pending().await,
    }
}

/// A robot's agent's status, counting one whose payload does not decode.
fn robot_status_event(keys: &Keys, s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<MsuStatus>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::RobotStatus(robot)), Ok(status)) => Some(Event::RobotStatus { robot, status }),
        (_, Err(_)) => {
            *undecodable += 1;
            None
        }
        _ => None,
    }
}

/// A sample's payload decoded, counting one that does not decode.
fn decode_counted<T: serde::de::DeserializeOwned>(s: &Sample, undecodable: &mut u64) -> Option<T> {
    match decode::<T>(&s.payload().to_bytes()) {
        Ok(t) => Some(t),
        Err(_) => {
            *undecodable += 1;
            None
        }
    }
}

/// Where the survey calibration is kept, and what was read from it.
#[derive(Debug, Clone, Default)]
pub struct SurveyFile {
    /// The file (`--survey-file`); `None`: not kept.
    pub path: Option<std::path::PathBuf>,
    /// What it held for this site, checked.
    pub saved: Option<SavedCalibration>,
}

impl SurveyFile {
    fn save(&self, core: &CentralCore) {
        if let (Some(path), Some(saved)) = (&self.path, core.survey_saved()) {
            save_survey_file(path, &saved);
        }
    }
}

/// Publishes the core's outputs; returns how many puts failed.
async fn publish(
    [cycle_pub, schedule_pub, survey_pub]: [&Publisher<'_>; 3],
    outputs: Vec<Output>,
) -> u64 {
    let mut failed = 0;
    for o in outputs {
        let sent = match o {
            Output::Trigger(t) => put_counted(cycle_pub, &t).await,
            Output::Schedule(s) => put_counted(schedule_pub, &s).await,
            Output::Survey(s) => put_counted(survey_pub, &s).await,
        };
        failed += u64::from(!sent);
    }
    failed
}

/// Answers a clock request at once: t2 on arrival, t3 just before the
/// reply; not at all with epoch 0 (a standby).
fn answer_clock(q: &Query, clock: &SimulatedClock, epoch: u64) {
    if epoch == 0 {
        return;
    }
    let t2 = clock.now();
    let Some(Ok(req)) = q.payload().map(|p| decode::<ClockRequest>(&p.to_bytes())) else {
        tracing::warn!("clock query without a valid request");
        return;
    };
    let sent = encode(&CentralCore::clock_reply(epoch, req.t1, t2, clock.now()))
        .map_err(NodeError::from)
        .and_then(|bytes| {
            q.reply(q.key_expr().clone(), bytes)
                .express(true)
                .wait()
                .map_err(zerr)
        });
    if let Err(e) = sent {
        tracing::warn!("clock reply failed: {e}");
    }
}

/// Answers one admin query (`reload` excepted: see [`reload`]). Queries
/// naming no command are logged through `unknown`: anyone allowed on the
/// admin keys can send them by the thousand.
async fn answer_admin(
    keys: &Keys,
    core: &mut CentralCore,
    q: &Query,
    now: Time,
    unknown: &mut LogLimiter<()>,
) {
    let Ok(Key::CentralAdmin(command)) = keys.parse(q.key_expr().as_str()) else {
        return;
    };
    match command.as_str() {
        // With a request, a page of the robots; without, the whole status
        // (the recorder's Foxglove view and older admins' question).
        "robots" if q.payload().is_some() => {
            let page = match q.payload().map(|p| decode::<RobotsRequest>(&p.to_bytes())) {
                Some(Ok(request)) => core.robots_page(now, &request),
                _ => RobotPage {
                    error: "the payload is not a robots request".into(),
                    page: 0,
                    pages: 1,
                    matching: 0,
                    counts: RobotCounts::default(),
                    robots: Vec::new(),
                },
            };
            reply(q, &page).await;
        }
        "robots" => reply(q, &core.status(now)).await,
        "status" | "cells" | "sync" => reply(q, &core.status_summary(now)).await,
        "schedule" => reply(q, &core.current_firing()).await,
        "transmitters" => reply(q, &core.transmitters(now)).await,
        "coverage" => {
            // No payload (or an unreadable one): the default grid.
            let resolution_m = q
                .payload()
                .and_then(|p| decode::<CoverageRequest>(&p.to_bytes()).ok())
                .map_or(crate::coverage::DEFAULT_RESOLUTION_M, |r| r.resolution_m);
            reply(q, &core.coverage(resolution_m)).await;
        }
        "pause" => reply(q, &core.set_paused(true)).await,
        "resume" => reply(q, &core.set_paused(false)).await,
        other => {
            if let Some(held) = unknown.admit((), std::time::Instant::now()) {
                tracing::warn!(
                    "unknown admin command {other:?} ignored ({held} more since the last such line)"
                );
            }
        }
    }
}

mod event_loop;
mod reload;

#[cfg(test)]
mod survey_file_tests;

#[cfg(test)]
mod site_name_tests;
