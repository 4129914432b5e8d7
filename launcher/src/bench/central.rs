//! `ickon bench central`: how many robots one central unit serves. The
//! site's servers run as `ickon sim` starts them (the router, the central
//! unit, one cell controller per cell, the same command lines) against a
//! synthetic fleet (`ickon node synthetic-fleet`): one process publishing
//! what N robots' MSU agents publish. The central unit is pinned to CPU 0
//! and everything else to the other CPUs, so that its figures are one
//! core's. Per size it reports the central unit's CPU and memory, how
//! regularly its cycle triggers arrive, the cells' sync error, and how fast
//! it answers `ickon admin status` and the web API while the fleet runs.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::Args;
use serde::Serialize;
use zenoh::sample::SampleKind;

use ickon_proto::decode;
use ickon_proto::keys::Keys;
use ickon_proto::msg::admin::StatusReport;
use ickon_proto::msg::control::{Burst, CycleTrigger};
use ickon_proto::site::Site;
use ickon_runtime::CommandError;

use crate::args::{Mesh, SimArgs};
use crate::core_split::{CoreSplit, Side};
use crate::launch::{node_command, wait_for_listener};
use crate::metrics::{CellStats, percentile};
use crate::nodes::NodeCommands;
use crate::observe::open_observer;
use crate::supervisor::Supervisor;
use crate::usage::ProcUsage;
use ickon_world::synthetic_fleet::FleetKeptUp;

/// How long the processes get to come up and announce themselves.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(60);
/// How long the processes get to stop after SIGTERM before they are killed.
const GRACE_TO_STOP: Duration = Duration::from_secs(5);
/// How often the admin status and the web API are asked during a run: an
/// operator's console refreshing twice a second.
const PROBE_PERIOD: Duration = Duration::from_millis(500);
/// How long an admin query or a web request may take before it counts as
/// unanswered.
const PROBE_TIMEOUT: Duration = Duration::from_secs(5);

/// Arguments of `ickon bench central`.
#[derive(Debug, Args)]
pub struct CentralArgs {
    /// A built-in site (`lab`, `warehouse`, `hall`) or a site file;
    /// extended with robots on its routes when a size exceeds its own.
    #[arg(long, default_value = "warehouse")]
    pub site: PathBuf,
    /// Fleet sizes, comma-separated (each up to 10000).
    #[arg(long, value_delimiter = ',', default_value = "100,300,1000")]
    pub robots: Vec<usize>,
    /// Seconds each size runs once every process is live.
    #[arg(long, default_value_t = 30.0)]
    pub duration: f64,
    /// Noise profile the fixes' residuals and hearing range follow, and
    /// the cells' clocks (as `ickon sim --profile`).
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which transmitters fire each cycle (`ickon sim --firing`).
    #[arg(long, value_enum, default_value_t = ickon_central::node::Firing::Occupancy)]
    pub firing: ickon_central::node::Firing,
    /// Zones, each with its own router (`ickon sim --routers`): the
    /// cells and the synthetic fleet's robots of a zone connect to its
    /// router (one fleet process per zone), the central unit to the first.
    #[arg(long, default_value_t = 1)]
    pub routers: usize,
    /// Print one JSON document instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// What one size measured.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CentralReport {
    /// Robots of the synthetic fleet.
    pub robots: usize,
    /// Zones, one router each.
    pub routers: usize,
    /// Seconds measured.
    pub duration_s: f64,
    /// Why the run failed (a process died), if it did; the numbers are
    /// of what was measured until then.
    pub failure: Option<String>,
    /// Seconds from the start of the cells and the synthetic fleet until
    /// every robot's, every cell's and the central unit's token was live at
    /// the bench's router.
    pub live_s: f64,
    /// Robots the central unit listed as up in its last status; `None`
    /// when it answered no status query.
    pub robots_up_at_central: Option<usize>,
    /// Robots in its last status with a pose; `None` likewise.
    pub robots_posed_at_central: Option<usize>,
    /// Cycle triggers received.
    pub cycles: usize,
    /// Mean cycle period of the triggers, ms.
    pub cycle_period_ms: Option<f64>,
    /// How far each trigger's arrival was from its predecessor's plus
    /// the cycle's nominal length, µs: median, 99th percentile, largest.
    pub trigger_jitter_p50_us: Option<f64>,
    /// See `trigger_jitter_p50_us`.
    pub trigger_jitter_p99_us: Option<f64>,
    /// See `trigger_jitter_p50_us`.
    pub trigger_jitter_max_us: Option<f64>,
    /// The central unit's CPU over the run, share of one core.
    pub central_cpu_share: Option<f64>,
    /// The same per robot, millionths of a core.
    pub central_cpu_per_robot_ppm: Option<f64>,
    /// The central unit's peak resident memory, MiB.
    pub central_peak_rss_mib: Option<f64>,
    /// The routers' CPU together, share of one core.
    pub router_cpu_share: Option<f64>,
    /// The synthetic fleet's CPU (all its processes), share of one core.
    pub fleet_cpu_share: Option<f64>,
    /// The cells' sync error (burst fired vs scheduled), 99th percentile
    /// and largest, µs.
    pub sync_error_p99_us: Option<f64>,
    /// See `sync_error_p99_us`.
    pub sync_error_max_us: Option<f64>,
    /// `ickon admin status` (the `central/admin/status` query) answered
    /// in, ms: median and 99th percentile.
    pub admin_status_p50_ms: Option<f64>,
    /// See `admin_status_p50_ms`.
    pub admin_status_p99_ms: Option<f64>,
    /// Admin queries asked, and those not answered in time.
    pub admin_status_asked: usize,
    /// See `admin_status_asked`.
    pub admin_status_unanswered: usize,
    /// The web API's `/api/status` answered in, ms: median and 99th
    /// percentile.
    pub web_status_p50_ms: Option<f64>,
    /// See `web_status_p50_ms`.
    pub web_status_p99_ms: Option<f64>,
    /// Web requests made, and those that failed or timed out.
    pub web_status_asked: usize,
    /// See `web_status_asked`.
    pub web_status_failed: usize,
    /// Survey calibrations the central unit published during the whole
    /// run (its start-up included), from its last status.
    pub survey_publications: u64,
    /// How long the central unit's step that computed and published one
    /// took, ms: mean and longest (as its status reports them).
    pub survey_publish_mean_ms: Option<f64>,
    /// See `survey_publish_mean_ms`.
    pub survey_publish_max_ms: Option<f64>,
    /// What the synthetic fleet said of itself when it stopped, its
    /// processes added up (`None`: one did not say, e.g. it was killed).
    pub fleet: Option<FleetKeptUp>,
}

impl CentralReport {
    /// Whether the synthetic fleet sent any robot's summary over a
    /// period late: then the central unit heard less than the fleet's
    /// rates, and the figures are the generator's limit, not its.
    pub fn generator_fell_behind(&self) -> bool {
        self.fleet.is_some_and(|f| f.late_turns > 0)
    }
}

/// Runs `ickon bench central`.
pub fn run(args: CentralArgs) -> Result<(), CommandError> {
    if args.robots.is_empty() {
        return Err(CommandError::bad_input("--robots needs at least one size"));
    }
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0) {
        return Err(CommandError::bad_input(
            "--duration must be between 0 and 86400 seconds",
        ));
    }
    ickon_sim::profile::NoiseProfile::load(&args.profile)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    // Every size checked before the first runs.
    for &n in &args.robots {
        if n == 0 {
            return Err(CommandError::bad_input(
                "--robots 0 is not possible: a fleet needs at least one robot",
            ));
        }
        crate::fleet_site::load(Some(&args.site), n, args.seed)?;
    }
    let mut reports = Vec::new();
    for &n in &args.robots {
        if !args.json {
            eprintln!(
                "ickon bench central: {n} robots on {} for {} s",
                args.site.display(),
                args.duration
            );
        }
        let report = ickon_runtime::block_on(2, measure(&args, n))
            .ok_or_else(|| CommandError::failure("cannot start the runtime"))??;
        if let Some(why) = &report.failure {
            eprintln!("warning: {n} robots: {why}");
        }
        if let Some(f) = report.fleet.filter(|_| report.generator_fell_behind()) {
            eprintln!(
                "warning: {n} robots: the synthetic fleet fell behind ({} of {} summaries \
                 over a period late): the central unit heard less than the fleet's rates",
                f.late_turns, f.summaries
            );
        }
        reports.push(report);
    }
    if args.json {
        let text = serde_json::to_string_pretty(&reports)
            .map_err(|e| CommandError::failure(e.to_string()))?;
        println!("{text}");
    } else {
        print!("{}", render(&reports));
    }
    if reports.iter().any(|r| r.failure.is_some()) {
        Err(CommandError::failure("a run failed (see its warning)"))
    } else {
        Ok(())
    }
}

/// The `ickon sim` arguments whose command lines the servers get.
fn sim_args(args: &CentralArgs, robots: usize) -> SimArgs {
    SimArgs {
        site: Some(args.site.clone()),
        robots,
        duration: args.duration,
        estimator: "tdoa-ekf".to_string(),
        profile: args.profile.clone(),
        seed: args.seed,
        json: true,
        mesh: Mesh::Router,
        http: Some(std::net::SocketAddr::from(([127, 0, 0, 1], 18_080))),
        http_token_file: None,
        foxglove: None,
        record: None,
        record_foxglove_view: false,
        ros2: false,
        secure: None,
        firing: args.firing,
        restart: false,
        standby: false,
        faults: None,
        learn_cell_sync: false,
        local_wind: false,
        no_survey_calibration: false,
        no_speed_of_sound: false,
        devices: Default::default(),
        receivers: Default::default(),
        robots_per_process: None,
        split_cores: false,
        routers: args.routers,
    }
}

/// Runs the servers and the synthetic fleet of `robots` once and measures.
async fn measure(args: &CentralArgs, robots: usize) -> Result<CentralReport, CommandError> {
    let failed = |e: &dyn std::fmt::Display| CommandError::failure(format!("{e:#}"));
    let sim = sim_args(args, robots);
    let (site, _) = crate::fleet_site::load(sim.site.as_deref(), robots, args.seed)?;
    let profile = ickon_sim::profile::NoiseProfile::load(&args.profile)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let extended = crate::fleet_site::write_for_run(sim.site.as_deref(), robots, args.seed)?;
    let site_file = extended
        .as_ref()
        .map(|f| f.path().to_path_buf())
        .or(sim.site.clone());
    let keys = Keys::new(&site.name).map_err(|e| failed(&e))?;
    let ids: Vec<String> = site
        .robots
        .iter()
        .take(robots)
        .map(|r| r.id.clone())
        .collect();
    let (zoned, hub, _) = crate::run::zoned_mesh(&sim, &site, &ids, "tcp")?;
    let commands = NodeCommands::build(
        &sim,
        &site,
        &profile,
        &zoned,
        None,
        &[],
        None,
        site_file.as_deref(),
    )
    .map_err(|e| failed(&e))?;
    let mut central = commands.central;
    let mut others: Vec<(String, Command)> = commands.cells;
    let mut kept_up_files = Vec::new();
    for (k, zone) in zoned.zones().iter().enumerate() {
        if zone.robots.is_empty() {
            continue;
        }
        let endpoint = &zoned.listeners()[k].0;
        let file = tempfile::NamedTempFile::new()
            .map_err(|e| CommandError::failure(format!("a file for the fleet's report: {e}")))?;
        let mut fleet = node_command(
            &sim,
            &site,
            site_file.as_deref(),
            "synthetic-fleet",
            endpoint,
            "tcp/127.0.0.1:0",
        )
        .map_err(|e| failed(&e))?;
        fleet.arg("--report").arg(file.path()).args([
            "--robots",
            &zone.robots.join(","),
            "--profile",
            &args.profile,
            "--seed",
            &args.seed.to_string(),
        ]);
        let name = if zoned.zones().len() == 1 {
            "fleet".to_string()
        } else {
            format!("fleet {}", zone.name)
        };
        others.push((name, fleet));
        kept_up_files.push(file);
    }
    let mut routers = commands.routers;
    if routers.is_empty() {
        return Err(CommandError::failure("no router"));
    }
    // The central unit alone on the first CPU, the rest on the others
    // (one CPU: nothing to separate).
    if let Ok(split) = CoreSplit::first_alone() {
        split.pin(&mut central, Side::Servers);
        for (_, cmd) in routers.iter_mut().chain(others.iter_mut()) {
            split.pin(cmd, Side::Simulation);
        }
    }
    let mut sup = Supervisor::new();
    let outcome = run_measured(
        args,
        (&site, &ids),
        &keys,
        &hub,
        &zoned.listeners().iter().map(|l| l.1).collect::<Vec<_>>(),
        (routers, central, others),
        commands.web,
        &mut sup,
    )
    .await;
    sup.stop_all(GRACE_TO_STOP);
    drop(commands.msu_file);
    drop(extended);
    let (observed, failure) = outcome?;
    let mut report = observed.report(robots, failure);
    report.routers = zoned.zones().len();
    report.fleet = fleet_kept_up(&kept_up_files);
    Ok(report)
}

/// What the fleet's processes said of themselves, added up (`None` when
/// one said nothing).
fn fleet_kept_up(files: &[tempfile::NamedTempFile]) -> Option<FleetKeptUp> {
    files.iter().try_fold(None::<FleetKeptUp>, |sum, file| {
        let text = std::fs::read_to_string(file.path()).ok()?;
        let one: FleetKeptUp = serde_json::from_str(&text).ok()?;
        Some(Some(match sum {
            None => one,
            Some(s) => FleetKeptUp {
                summaries: s.summaries + one.summaries,
                late_turns: s.late_turns + one.late_turns,
                failed_puts: s.failed_puts + one.failed_puts,
                elapsed_s: s.elapsed_s.max(one.elapsed_s),
                declare_s: s.declare_s.max(one.declare_s),
            },
        }))
    })?
}

/// The processes of one run: the routers (the hub first), the central
/// unit, and the cells and the fleet, with their names.
type Processes = (Vec<(String, Command)>, Command, Vec<(String, Command)>);

/// Starts the processes, waits until they are live, and observes.
#[allow(clippy::too_many_arguments)]
async fn run_measured(
    args: &CentralArgs,
    (site, robots): (&Site, &[String]),
    keys: &Keys,
    hub: &str,
    router_ports: &[u16],
    (routers, central, others): Processes,
    web: Option<std::net::SocketAddr>,
    sup: &mut Supervisor,
) -> Result<(Observed, Option<String>), CommandError> {
    let failed = |e: &dyn std::fmt::Display| CommandError::failure(format!("{e:#}"));
    for (name, router) in routers {
        sup.spawn(&name, router).map_err(|e| failed(&e))?;
    }
    for &port in router_ports {
        wait_for_listener(port, sup, STARTUP_TIMEOUT)
            .await
            .map_err(|e| failed(&e))?;
    }
    sup.spawn("central", central).map_err(|e| failed(&e))?;
    let session = open_observer(hub, Mesh::Router, None)
        .await
        .map_err(|e| failed(&e))?;
    let result = async {
        let alive = session
            .liveliness()
            .declare_subscriber(keys.alive_all())
            .history(true)
            .await
            .map_err(|e| failed(&e))?;
        for (name, cmd) in others {
            sup.spawn(&name, cmd).map_err(|e| failed(&e))?;
        }
        let live_s = wait_live(site, robots, keys, &alive, sup).await?;
        let (mut observed, failure) = observe(args, keys, &session, web, sup).await?;
        observed.live_s = live_s;
        Ok((observed, failure))
    }
    .await;
    let _ = session.close().await;
    result
}

/// Waits until the central unit, every cell and every robot of the fleet
/// hold their liveliness tokens; the seconds that took.
async fn wait_live(
    site: &Site,
    robots: &[String],
    keys: &Keys,
    alive: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    sup: &mut Supervisor,
) -> Result<f64, CommandError> {
    let failed = |e: &dyn std::fmt::Display| CommandError::failure(format!("{e:#}"));
    let mut expected: BTreeSet<String> = std::iter::once(keys.alive_central())
        .map(Ok)
        .chain(site.cells.iter().map(|c| keys.alive_cell(&c.id)))
        .chain(robots.iter().map(|r| keys.alive_robot(r)))
        .collect::<Result<_, _>>()
        .map_err(|e| failed(&e))?;
    let started = Instant::now();
    while !expected.is_empty() {
        if let Some(dead) = sup.first_dead() {
            return Err(CommandError::failure(format!(
                "process {} {} during start-up",
                dead.name, dead.status
            )));
        }
        if started.elapsed() > STARTUP_TIMEOUT {
            return Err(CommandError::failure(not_live(&expected)));
        }
        if let Ok(Ok(sample)) =
            tokio::time::timeout(Duration::from_millis(100), alive.recv_async()).await
            && sample.kind() == SampleKind::Put
        {
            expected.remove(sample.key_expr().as_str());
        }
    }
    Ok(started.elapsed().as_secs_f64())
}

/// Keys of the tokens not live named in the start-up's error: a few say
/// which kind of node is missing, ten thousand would bury it.
const NOT_LIVE_NAMED: usize = 5;

/// The start-up's error for the tokens still `missing`: how many, and
/// the first few.
fn not_live(missing: &BTreeSet<String>) -> String {
    let named: Vec<&str> = missing
        .iter()
        .take(NOT_LIVE_NAMED)
        .map(String::as_str)
        .collect();
    let more = missing.len().saturating_sub(named.len());
    format!(
        "{} tokens not live after {} s: {}{}",
        missing.len(),
        STARTUP_TIMEOUT.as_secs(),
        named.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    )
}

/// What the observer gathered over a run.
#[derive(Debug, Default)]
struct Observed {
    duration_s: f64,
    /// Seconds until every token was live.
    live_s: f64,
    /// Each trigger's arrival: (epoch, cycle), cycle start (master time,
    /// ns), when it arrived.
    triggers: Vec<TriggerArrival>,
    cells: CellStats,
    admin_ms: Vec<f64>,
    admin_asked: usize,
    last_status: Option<StatusReport>,
    web_ms: Vec<f64>,
    web_asked: usize,
    /// CPU and memory of each process at the start and the end.
    usage_from: Vec<(String, ProcUsage)>,
    usage_to: Vec<(String, ProcUsage)>,
}

/// Each trigger's arrival as [`Observed::triggers`] keeps it.
type TriggerArrival = ((u64, u64), i64, Instant);

/// Watches the triggers and the bursts for the run's duration while the
/// admin status and the web API are asked, and reads every process's
/// CPU at both ends. A trigger's arrival is stamped in Zenoh's receive
/// path, and the admin status is asked from a task of its own: stamped in
/// the observer's loop, a trigger that came while the loop waited for an
/// answer would count the answer's wait as the trigger's lateness.
async fn observe(
    args: &CentralArgs,
    keys: &Keys,
    session: &zenoh::Session,
    web: Option<std::net::SocketAddr>,
    sup: &mut Supervisor,
) -> Result<(Observed, Option<String>), CommandError> {
    let failed = |e: &dyn std::fmt::Display| CommandError::failure(format!("{e:#}"));
    let arrivals: Arc<std::sync::Mutex<Vec<TriggerArrival>>> = Arc::default();
    let stamped = arrivals.clone();
    let triggers = session
        .declare_subscriber(keys.central_cycle())
        .callback(move |s| {
            let at = Instant::now();
            if let Ok(t) = decode::<CycleTrigger>(&s.payload().to_bytes())
                && let Ok(mut kept) = stamped.lock()
            {
                kept.push(((t.epoch, t.cycle), t.start.as_nanos(), at));
            }
        })
        .await
        .map_err(|e| failed(&e))?;
    let bursts = session
        .declare_subscriber(keys.cell_burst_all())
        .await
        .map_err(|e| failed(&e))?;
    let stop = Arc::new(AtomicBool::new(false));
    let web_probe = web.map(|addr| {
        let stop = stop.clone();
        tokio::task::spawn_blocking(move || probe_web(addr, &stop))
    });
    let status_key = keys.central_admin("status").map_err(|e| failed(&e))?;
    let admin_probe = tokio::spawn(probe_admin(session.clone(), status_key, stop.clone()));
    let mut seen = Observed {
        usage_from: sup.usage(),
        ..Observed::default()
    };
    let started = Instant::now();
    let until = started + Duration::from_secs_f64(args.duration);
    let mut checks = tokio::time::interval(PROBE_PERIOD);
    let mut failure = None;
    while Instant::now() < until {
        tokio::select! {
            _ = tokio::time::sleep_until(until.into()) => break,
            _ = checks.tick() => {
                if let Some(dead) = sup.first_dead() {
                    failure = Some(format!("process {} {}", dead.name, dead.status));
                    break;
                }
            }
            Ok(s) = bursts.recv_async() => {
                if let Ok(b) = decode::<Burst>(&s.payload().to_bytes()) {
                    seen.cells.on_burst(&b);
                }
            }
        }
    }
    seen.duration_s = started.elapsed().as_secs_f64();
    seen.usage_to = sup.usage();
    stop.store(true, Ordering::Relaxed);
    drop(triggers);
    seen.triggers = std::mem::take(&mut *arrivals.lock().unwrap_or_else(|e| e.into_inner()));
    if let Some(probe) = web_probe
        && let Ok((ms, asked)) = probe.await
    {
        seen.web_ms = ms;
        seen.web_asked = asked;
    }
    if let Ok(admin) = admin_probe.await {
        (seen.admin_ms, seen.admin_asked, seen.last_status) = admin;
    }
    Ok((seen, failure))
}

/// Asks the central unit's admin status every [`PROBE_PERIOD`] until
/// `stop` (one question at a time, as an operator's console does): how
/// long each answer took, ms, how many were asked, and the last answer.
async fn probe_admin(
    session: zenoh::Session,
    key: String,
    stop: Arc<AtomicBool>,
) -> (Vec<f64>, usize, Option<StatusReport>) {
    let (mut ms, mut asked, mut last) = (Vec::new(), 0, None);
    let mut probes = tokio::time::interval(PROBE_PERIOD);
    loop {
        probes.tick().await;
        if stop.load(Ordering::Relaxed) {
            return (ms, asked, last);
        }
        asked += 1;
        let started = Instant::now();
        if let Some(status) = ask_status(&session, &key).await {
            ms.push(started.elapsed().as_secs_f64() * 1e3);
            last = Some(status);
        }
    }
}

/// The central unit's status, or `None` when it did not answer in time.
async fn ask_status(session: &zenoh::Session, key: &str) -> Option<StatusReport> {
    let replies = session.get(key).timeout(PROBE_TIMEOUT).await.ok()?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result()
            && let Ok(status) = decode::<StatusReport>(&sample.payload().to_bytes())
        {
            return Some(status);
        }
    }
    None
}

/// Asks the web API for the status every [`PROBE_PERIOD`] until `stop`:
/// how long each answer took, ms, and how many were asked.
fn probe_web(addr: std::net::SocketAddr, stop: &AtomicBool) -> (Vec<f64>, usize) {
    let (mut ms, mut asked) = (Vec::new(), 0);
    while !stop.load(Ordering::Relaxed) {
        asked += 1;
        let started = Instant::now();
        if get_status(addr).is_ok() {
            ms.push(started.elapsed().as_secs_f64() * 1e3);
        }
        std::thread::sleep(PROBE_PERIOD);
    }
    (ms, asked)
}

/// One `GET /api/status`, read to its end; an error unless it is a 200.
fn get_status(addr: std::net::SocketAddr) -> std::io::Result<()> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect_timeout(&addr, PROBE_TIMEOUT)?;
    s.set_read_timeout(Some(PROBE_TIMEOUT))?;
    s.write_all(b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")?;
    let mut answer = Vec::new();
    s.read_to_end(&mut answer)?;
    if answer.starts_with(b"HTTP/1.1 200") {
        Ok(())
    } else {
        Err(std::io::Error::other("not a 200 answer"))
    }
}

impl Observed {
    /// The figures of one size.
    fn report(&self, robots: usize, failure: Option<String>) -> CentralReport {
        let (jitter_us, period_ms) = self.trigger_jitter();
        let share = |kind: &str| self.cpu_share(kind);
        let central_cpu_share = share("central");
        let sync = self.cells.summary("all", &BTreeSet::new());
        let status = self.last_status.as_ref();
        CentralReport {
            robots,
            routers: 1,
            duration_s: self.duration_s,
            live_s: self.live_s,
            failure,
            robots_up_at_central: status
                .map(|s| (s.robot_counts.up + s.robot_counts.stale) as usize),
            robots_posed_at_central: status.map(|s| s.robots_posed as usize),
            cycles: self.triggers.len(),
            cycle_period_ms: period_ms,
            trigger_jitter_p50_us: percentile(&jitter_us, 50.0),
            trigger_jitter_p99_us: percentile(&jitter_us, 99.0),
            trigger_jitter_max_us: jitter_us.iter().copied().reduce(f64::max),
            central_cpu_share,
            central_cpu_per_robot_ppm: central_cpu_share.map(|s| s * 1e6 / robots as f64),
            central_peak_rss_mib: self
                .usage_to
                .iter()
                .find(|(n, _)| n == "central")
                .map(|(_, u)| u.peak_rss_bytes as f64 / (1024.0 * 1024.0)),
            router_cpu_share: share("router"),
            fleet_cpu_share: share("fleet"),
            sync_error_p99_us: sync.sync_error_us,
            sync_error_max_us: sync.sync_error_max_us,
            admin_status_p50_ms: percentile(&self.admin_ms, 50.0),
            admin_status_p99_ms: percentile(&self.admin_ms, 99.0),
            admin_status_asked: self.admin_asked,
            admin_status_unanswered: self.admin_asked - self.admin_ms.len(),
            web_status_p50_ms: percentile(&self.web_ms, 50.0),
            web_status_p99_ms: percentile(&self.web_ms, 99.0),
            web_status_asked: self.web_asked,
            web_status_failed: self.web_asked - self.web_ms.len(),
            survey_publications: status.map_or(0, |s| s.survey_publications),
            survey_publish_mean_ms: status
                .filter(|s| s.survey_publications > 0)
                .map(|s| s.survey_publish_mean_us / 1e3),
            survey_publish_max_ms: status
                .filter(|s| s.survey_publications > 0)
                .map(|s| s.survey_publish_max_us / 1e3),
            fleet: None,
        }
    }

    /// Each trigger's lateness against its predecessor's arrival plus the
    /// cycle between their starts (µs), and the mean cycle (ms).
    fn trigger_jitter(&self) -> (Vec<f64>, Option<f64>) {
        trigger_jitter(&self.triggers)
    }

    /// The CPU share of one core the processes named `kind` (or starting
    /// with `kind `) used between the two readings.
    fn cpu_share(&self, kind: &str) -> Option<f64> {
        let of = |usage: &[(String, ProcUsage)]| -> Option<f64> {
            let mut found = false;
            let mut cpu_s = 0.0;
            for (name, u) in usage {
                if name == kind || name.starts_with(&format!("{kind} ")) {
                    found = true;
                    cpu_s += u.cpu_s;
                }
            }
            found.then_some(cpu_s)
        };
        let used_s = of(&self.usage_to)? - of(&self.usage_from)?;
        (self.duration_s > 0.0).then(|| used_s / self.duration_s)
    }
}

/// How late each trigger arrived against its predecessor's arrival plus
/// the time between their cycle starts, µs (the absolute value; only
/// consecutive cycles of one epoch), and the mean time between cycle
/// starts, ms.
fn trigger_jitter(triggers: &[TriggerArrival]) -> (Vec<f64>, Option<f64>) {
    let mut jitter_us = Vec::new();
    let mut periods_ms = Vec::new();
    for w in triggers.windows(2) {
        let ((e0, c0), start0, at0) = w[0];
        let ((e1, c1), start1, at1) = w[1];
        if e0 != e1 || c1 != c0 + 1 {
            continue;
        }
        let nominal_s = (start1 - start0) as f64 * 1e-9;
        let seen_s = at1.duration_since(at0).as_secs_f64();
        jitter_us.push((seen_s - nominal_s).abs() * 1e6);
        periods_ms.push(nominal_s * 1e3);
    }
    let period =
        (!periods_ms.is_empty()).then(|| periods_ms.iter().sum::<f64>() / periods_ms.len() as f64);
    (jitter_us, period)
}

/// The table: one row per size.
fn render(reports: &[CentralReport]) -> String {
    use std::fmt::Write;
    let show =
        |v: Option<f64>, digits: usize| v.map_or("-".to_string(), |v| format!("{v:.digits$}"));
    let count = |v: Option<usize>| v.map_or("-".to_string(), |v| v.to_string());
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:>6} {:>6} {:>9} {:>7} {:>8} {:>8} {:>14} {:>11} {:>14} {:>14} {:>9} {:>9} {:>14}",
        "robots",
        "live",
        "up/posed",
        "cycles",
        "central",
        "RSS MiB",
        "jitter p50/p99",
        "jitter max",
        "admin p50/p99",
        "web p50/p99",
        "sync p99",
        "fleet",
        "survey mean/max"
    );
    let _ = writeln!(
        out,
        "{:>6} {:>6} {:>9} {:>7} {:>8} {:>8} {:>14} {:>11} {:>14} {:>14} {:>9} {:>9} {:>14}",
        "", "s", "", "", "% core", "", "µs", "µs", "ms", "ms", "µs", "% core", "ms"
    );
    for r in reports {
        let _ = writeln!(
            out,
            "{:>6} {:>6} {:>9} {:>7} {:>8} {:>8} {:>14} {:>11} {:>14} {:>14} {:>9} {:>9} {:>14}",
            r.robots,
            format!("{:.1}", r.live_s),
            format!(
                "{}/{}",
                count(r.robots_up_at_central),
                count(r.robots_posed_at_central)
            ),
            r.cycles,
            show(r.central_cpu_share.map(|s| s * 100.0), 1),
            show(r.central_peak_rss_mib, 1),
            format!(
                "{}/{}",
                show(r.trigger_jitter_p50_us, 0),
                show(r.trigger_jitter_p99_us, 0)
            ),
            show(r.trigger_jitter_max_us, 0),
            format!(
                "{}/{}",
                show(r.admin_status_p50_ms, 1),
                show(r.admin_status_p99_ms, 1)
            ),
            format!(
                "{}/{}",
                show(r.web_status_p50_ms, 1),
                show(r.web_status_p99_ms, 1)
            ),
            show(r.sync_error_p99_us, 0),
            show(r.fleet_cpu_share.map(|s| s * 100.0), 0),
            format!(
                "{}/{}",
                show(r.survey_publish_mean_ms, 1),
                show(r.survey_publish_max_ms, 1)
            ),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jitter_is_the_arrival_interval_against_the_cycle_starts() {
        let t0 = Instant::now();
        let ms = |m: u64| t0 + Duration::from_millis(m);
        let triggers = vec![
            ((1, 0), 0, ms(0)),
            ((1, 1), 100_000_000, ms(101)),
            ((1, 2), 200_000_000, ms(200)),
            // A gap in the cycles and another epoch are not compared.
            ((1, 4), 400_000_000, ms(450)),
            ((2, 5), 500_000_000, ms(460)),
        ];
        let (jitter_us, period_ms) = trigger_jitter(&triggers);
        assert_eq!(jitter_us.len(), 2);
        assert!((jitter_us[0] - 1_000.0).abs() < 1.0);
        assert!((jitter_us[1] - 1_000.0).abs() < 1.0);
        assert!((period_ms.expect("cycles") - 100.0).abs() < 1e-9);
    }

    #[test]
    fn the_start_up_error_counts_the_missing_tokens_and_names_a_few() {
        let missing: BTreeSet<String> = (0..5_000)
            .map(|i| format!("ickon/w/alive/robot/r{i:05}"))
            .collect();
        let text = not_live(&missing);
        assert!(
            text.starts_with("5000 tokens not live after 60 s: ickon/w/alive/robot/r00000, "),
            "{text}"
        );
        assert!(text.ends_with(" and 4995 more"), "{text}");
        assert!(text.len() < 300, "{text}");
        let one: BTreeSet<String> = std::iter::once("ickon/w/alive/central".to_string()).collect();
        assert_eq!(
            not_live(&one),
            "1 tokens not live after 60 s: ickon/w/alive/central"
        );
    }
}
