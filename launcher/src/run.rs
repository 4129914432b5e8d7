//! One run of the mesh, in the order a site comes up: build every node's
//! command line, start the routers and the central unit, open the
//! launcher's observer (and recorder), start the cells, the world and the
//! agents, wait until every node is live, observe for the run's duration,
//! stop everything and report.

use std::collections::BTreeSet;
use std::process::Command;
use std::time::{Duration, Instant};

use ickon_proto::keys::Keys;
use ickon_proto::site::Site;
use ickon_recording::sim_hook::{self, SimRecording};
use ickon_runtime::CommandError;
use ickon_sim::profile::NoiseProfile;
use zenoh::sample::SampleKind;

use crate::args::{SimArgs, check_args};
use crate::device_plan::Devices;
use crate::error::LaunchError;
use crate::launch::wait_for_listener;
use crate::metrics::RunStats;
use crate::nodes::{NodeCommands, msu_starts};
use crate::observe::{observe, open_observer};
use crate::ports::free_port;
use crate::report::{RunFacts, SimReport, render_report};
use crate::router_load::RouterLoad;
use crate::secure::SimSecurity;
use crate::supervisor::Supervisor;
use crate::usage;
use crate::zones::ZonedMesh;
use ickon_operator::secure::Identity;

/// How long the nodes get to come up and announce themselves.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the nodes get to stop after SIGTERM before they are killed.
const GRACE_TO_STOP: Duration = Duration::from_secs(5);

/// A run's report and, if the run failed after it started (a node died),
/// why.
pub type Measured = (SimReport, Option<String>);

/// Runs `ickon sim`: checks the flags, runs the mesh once, prints the report.
pub fn run(args: SimArgs) -> Result<(), CommandError> {
    let (site, profile) = check_args(&args)?;
    pin_launcher(&args)?;
    let (report, failure) = ickon_runtime::block_on(2, measure(&args, &site, &profile))
        .ok_or_else(|| CommandError::failure("cannot start the runtime"))??;
    if args.json {
        match serde_json::to_string_pretty(&report) {
            Ok(text) => println!("{text}"),
            Err(e) => eprintln!("error: {e}"),
        }
    } else {
        print!("{}", render_report(&report));
        if let Some(recorded) = &report.recorded {
            eprint!("{}", recorded.render());
        }
    }
    match failure {
        Some(why) => Err(CommandError::failure(why)),
        None => Ok(()),
    }
}

/// With `--split-cores`, pins the launcher (its observer) to the
/// simulation's CPUs: called before the runtime starts its threads.
pub(crate) fn pin_launcher(args: &SimArgs) -> Result<(), CommandError> {
    if args.split_cores {
        let split = crate::core_split::CoreSplit::of_this_machine()
            .map_err(|e| CommandError::bad_input(format!("--split-cores: {e}")))?;
        split
            .simulation
            .pin_current_thread()
            .map_err(|e| CommandError::failure(format!("--split-cores: {e}")))?;
    }
    Ok(())
}

/// What every process (the launcher too) has used so far, by name.
fn usage_now(sup: &Supervisor) -> Vec<(String, usage::ProcUsage)> {
    let mut used = sup.usage();
    if let Some(me) = usage::read(std::process::id()) {
        used.push(("launcher".to_string(), me));
    }
    used
}

/// A failure of the launcher itself (a port, a file, a Zenoh call).
fn failed(e: impl std::fmt::Display) -> CommandError {
    CommandError::failure(format!("{e:#}"))
}

/// Runs the mesh once and measures it (`ickon sim`, and each size of `ickon bench scale`).
pub async fn measure(
    args: &SimArgs,
    site: &Site,
    profile: &NoiseProfile,
) -> Result<Measured, CommandError> {
    // Installed first: a Ctrl-C or SIGTERM (a service manager, `timeout`)
    // during start-up is held until the mesh is up, then stops it like one
    // during the run, so the nodes are stopped and the run file and the
    // agents' temporary files removed.
    let mut shutdown = Box::pin(ickon_runtime::shutdown_signal(false));
    let keys = Keys::new(&site.name).map_err(failed)?;
    let robots: Vec<String> = site
        .robots
        .iter()
        .take(args.robots)
        .map(|r| r.id.clone())
        .collect();
    let security = SimSecurity::prepare(args, site, &robots)?;
    let scheme = security.as_ref().map_or("tcp", SimSecurity::scheme);
    let (zoned, hub, _) = zoned_mesh(args, site, &robots, scheme)?;
    let router_ports: Vec<u16> = zoned.listeners().iter().map(|(_, p)| *p).collect();
    let recorder_endpoint = match args.record {
        // Not bound before the routers start: their ports are excluded.
        Some(_) => Some(format!(
            "tcp/127.0.0.1:{}",
            free_port(&router_ports).map_err(failed)?
        )),
        None => None,
    };
    // Robots added to the site: every node reads the same extended site
    // from this file, kept until the run is over.
    let extended_site =
        crate::fleet_site::write_for_run(args.site.as_deref(), args.robots, args.seed)?;
    let msus = msu_starts(args, site, profile, &robots).map_err(failed)?;
    let commands = NodeCommands::build(
        args,
        site,
        profile,
        &zoned,
        recorder_endpoint.as_deref(),
        &msus,
        security.as_ref(),
        extended_site.as_ref().map(tempfile::NamedTempFile::path),
    )
    .map_err(failed)?;
    let mut sup = Supervisor::new();
    let started = start_mesh(
        args,
        site,
        &keys,
        &zoned,
        recorder_endpoint.as_deref(),
        &msus,
        security.as_ref(),
        commands,
        &mut sup,
    )
    .await;
    let mesh = match started {
        Ok(mesh) => mesh,
        Err(e) => {
            sup.stop_all(GRACE_TO_STOP);
            return Err(e);
        }
    };
    let quiet = args.json && !std::io::IsTerminal::is_terminal(&std::io::stderr());
    if let Err(e) = wait_until_live(args, site, &keys, &robots, &mesh, &mut sup, quiet).await {
        sup.stop_all(GRACE_TO_STOP);
        mesh.close().await;
        return Err(e);
    }
    let used_before = usage_now(&sup);
    let watched_from = Instant::now();
    let observed = observe_run(
        args,
        site,
        &keys,
        &hub,
        &mesh,
        &mut sup,
        quiet,
        security.as_ref(),
        &mut shutdown,
    )
    .await;
    let used = usage_now(&sup);
    let cost = crate::cost::Cost::over_window(
        &used_before,
        &used,
        watched_from.elapsed().as_secs_f64(),
        robots.len(),
        args.split_cores
            .then(crate::core_split::CoreSplit::of_this_machine)
            .and_then(Result::ok)
            .as_ref(),
    );
    let routers = RouterLoad::of_run(args.mesh, &zoned, &used);
    // The nodes stop first, so that the file holds everything they
    // published, the last poses the observer counted among it.
    let killed = sup.stop_all(GRACE_TO_STOP);
    let recorded = mesh.finish().await;
    let (stats, failure) = observed.map_err(failed)?;
    if !killed.is_empty() {
        eprintln!(
            "warning: nodes that did not stop within {} s were killed: {}",
            GRACE_TO_STOP.as_secs(),
            killed.join(", ")
        );
    }
    let all_cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    let update_rate_hz = ickon_central::update_rate_hz(
        &ickon_central::compute_schedule(site, &all_cells, 1, 0).map_err(failed)?,
    );
    let report = SimReport::assemble(
        args,
        site,
        &robots,
        &stats,
        RunFacts {
            update_rate_hz,
            secure: security.is_some(),
            central_endpoint: hub,
            processes: usage::by_kind(&used),
            cost,
            routers,
            recorded: recorded.as_ref().and_then(|r| r.as_ref().ok()).cloned(),
        },
    );
    let failure = match (failure, recorded) {
        (None, Some(Err(e))) => Some(e),
        (f, _) => f,
    };
    Ok((report, failure))
}

/// The launcher's own sessions on a started mesh: the observer, with its
/// liveliness subscriber, and with `--record` the recorder.
struct StartedMesh {
    session: zenoh::Session,
    alive: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    recorder: Option<(zenoh::Session, SimRecording)>,
    /// The URL of the live map, if one is served.
    web: Option<std::net::SocketAddr>,
    /// The address of the Foxglove server, if one is served.
    foxglove: Option<std::net::SocketAddr>,
    /// The agents' configuration file, kept until the run is over.
    _msu_file: tempfile::NamedTempFile,
}

impl StartedMesh {
    /// Closes the sessions without finishing a recording (a start that failed).
    async fn close(self) {
        if let Some((s, _)) = self.recorder {
            let _ = s.close().await;
        }
        let _ = self.session.close().await;
    }

    /// Finishes the recording and closes the sessions.
    async fn finish(self) -> Option<Result<ickon_recording::RecordReport, String>> {
        let mut recorded = None;
        if let Some((s, recording)) = self.recorder {
            recorded = Some(recording.finish().await);
            let _ = s.close().await;
        }
        let _ = self.session.close().await;
        recorded
    }
}

/// Starts the routers (waiting until each listens), the central unit and its
/// standby, the launcher's observer and recorder (before the first cell,
/// so that the recording holds every burst), then the cells, the world
/// and the agents.
#[allow(clippy::too_many_arguments)]
async fn start_mesh(
    args: &SimArgs,
    site: &Site,
    keys: &Keys,
    zoned: &ZonedMesh,
    recorder_endpoint: Option<&str>,
    msus: &[sim_hook::MsuStart],
    security: Option<&SimSecurity>,
    commands: NodeCommands,
    sup: &mut Supervisor,
) -> Result<StartedMesh, CommandError> {
    // The hub first: the others link to it as they start.
    for ((name, router), (_, port)) in commands.routers.into_iter().zip(zoned.listeners()) {
        sup.spawn(&name, router).map_err(failed)?;
        wait_for_listener(*port, sup, STARTUP_TIMEOUT)
            .await
            .map_err(failed)?;
    }
    let hub = zoned.hub();
    sup.spawn("central", commands.central).map_err(failed)?;
    if let Some(standby) = commands.standby {
        sup.spawn("central standby", standby).map_err(failed)?;
    }
    let as_identity = |who: Identity| security.map(|s| s.client_file(&who));
    let session = open_observer(hub, args.mesh, as_identity(Identity::Observer).as_deref())
        .await
        .map_err(failed)?;
    let recorder = match (&args.record, recorder_endpoint) {
        (Some(path), Some(listen)) => {
            match start_recording(args, site, keys, hub, listen, path, msus, &as_identity).await {
                Ok(r) => Some(r),
                Err(e) => {
                    let _ = session.close().await;
                    return Err(e);
                }
            }
        }
        _ => None,
    };
    let mesh = StartedMesh {
        alive: match session
            .liveliness()
            .declare_subscriber(keys.alive_all())
            .history(true)
            .await
        {
            Ok(alive) => alive,
            Err(e) => {
                let _ = session.close().await;
                return Err(failed(format!("liveliness subscriber: {e}")));
            }
        },
        session,
        recorder,
        web: commands.web,
        foxglove: commands.foxglove,
        _msu_file: commands.msu_file,
    };
    // With emulated devices the world is their other end: started first,
    // its boards are listening when the cells and agents first connect.
    let spawned = if args.devices == Devices::Emulated {
        spawn(sup, "world", commands.world).and_then(|()| spawn_all(sup, commands.cells))
    } else {
        spawn_all(sup, commands.cells).and_then(|()| spawn(sup, "world", commands.world))
    }
    .and_then(|()| spawn_all(sup, commands.msus));
    if let Err(e) = spawned {
        mesh.close().await;
        return Err(failed(e));
    }
    Ok(mesh)
}

/// The run's zones (`--routers`) and a free loopback port for each zone's
/// router (in a full mesh of peers, one: the central unit's), with the
/// hub's endpoint and port.
pub(crate) fn zoned_mesh(
    args: &SimArgs,
    site: &Site,
    robots: &[String],
    scheme: &str,
) -> Result<(ZonedMesh, String, u16), CommandError> {
    let zones = crate::zones::split(site, robots, args.routers)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let mut ports = Vec::new();
    for _ in &zones {
        ports.push(free_port(&ports).map_err(failed)?);
    }
    let listeners = ports
        .iter()
        .map(|p| (format!("{scheme}/127.0.0.1:{p}"), *p))
        .collect();
    let zoned = ZonedMesh::new(zones, listeners)
        .ok_or_else(|| CommandError::failure("a run needs at least one zone"))?;
    let hub = zoned.hub().to_string();
    let hub_port = ports.first().copied().unwrap_or_default();
    Ok((zoned, hub, hub_port))
}

/// Spawns each named command under the supervisor.
fn spawn_all(sup: &mut Supervisor, commands: Vec<(String, Command)>) -> Result<(), LaunchError> {
    for (name, cmd) in commands {
        spawn(sup, &name, cmd)?;
    }
    Ok(())
}

/// Spawns one named command under the supervisor.
fn spawn(sup: &mut Supervisor, name: &str, cmd: Command) -> Result<(), LaunchError> {
    sup.spawn(name, cmd).map_err(|error| LaunchError::Spawn {
        name: name.to_string(),
        error,
    })
}

/// Opens the recorder's session (listening on `listen` for the peers of a
/// full mesh) and starts writing the run into `path`.
#[allow(clippy::too_many_arguments)]
async fn start_recording(
    args: &SimArgs,
    site: &Site,
    keys: &Keys,
    hub: &str,
    listen: &str,
    path: &std::path::Path,
    msus: &[sim_hook::MsuStart],
    as_identity: &dyn Fn(Identity) -> Option<std::path::PathBuf>,
) -> Result<(zenoh::Session, SimRecording), CommandError> {
    let session = sim_hook::open_session(hub, listen, as_identity(Identity::Recorder).as_deref())
        .await
        .map_err(|e| CommandError::failure(format!("--record: {e}")))?;
    let robots: Vec<&str> = msus.iter().map(|m| m.robot.as_str()).collect();
    let settings = [
        ("profile", args.profile.clone()),
        ("seed", args.seed.to_string()),
        ("estimator", args.estimator.clone()),
        ("robots", robots.join(",")),
        ("duration_s", args.duration.to_string()),
    ];
    let metadata = sim_hook::sim_metadata(&site.name, &settings, msus);
    match SimRecording::start(&session, keys, path, &metadata, args.record_foxglove_view) {
        Ok(r) => Ok((session, r)),
        Err(e) => {
            let _ = session.close().await;
            Err(CommandError::bad_input(format!("--record: {e}")))
        }
    }
}

/// Waits until every node has announced itself, one died, or time is up.
async fn wait_until_live(
    args: &SimArgs,
    site: &Site,
    keys: &Keys,
    robots: &[String],
    mesh: &StartedMesh,
    sup: &mut Supervisor,
    quiet: bool,
) -> Result<(), CommandError> {
    let mut expected: BTreeSet<String> = [keys.alive_central(), keys.alive_world()]
        .into_iter()
        .chain(
            site.cells
                .iter()
                .map(|c| keys.alive_cell(&c.id))
                .collect::<Result<Vec<_>, _>>()
                .map_err(failed)?,
        )
        .chain(
            robots
                .iter()
                .map(|r| keys.alive_robot(r))
                .collect::<Result<Vec<_>, _>>()
                .map_err(failed)?,
        )
        .collect();
    let started = Instant::now();
    if !quiet {
        eprintln!(
            "ickon sim: site {:?}, {} cells, {} robots, estimator {}, profile {}, seed {}; waiting for {} nodes",
            site.name,
            site.cells.len(),
            robots.len(),
            args.estimator,
            args.profile,
            args.seed,
            sup.len()
        );
    }
    while !expected.is_empty() {
        if let Some(dead) = sup.first_dead() {
            return Err(CommandError::failure(format!(
                "node {} {} during start-up",
                dead.name, dead.status
            )));
        }
        if started.elapsed() > STARTUP_TIMEOUT {
            let missing: Vec<String> = expected.into_iter().collect();
            return Err(CommandError::failure(format!(
                "nodes not live after {} s: {}",
                STARTUP_TIMEOUT.as_secs(),
                missing.join(", ")
            )));
        }
        if let Ok(Ok(sample)) =
            tokio::time::timeout(Duration::from_millis(100), mesh.alive.recv_async()).await
            && sample.kind() == SampleKind::Put
        {
            expected.remove(sample.key_expr().as_str());
        }
    }
    if !quiet {
        eprintln!(
            "ickon sim: all {} nodes live after {:.1} s; running for {} s (Ctrl-C stops early)",
            sup.len(),
            started.elapsed().as_secs_f64(),
            args.duration
        );
    }
    Ok(())
}

/// Writes the run file that tells `ickon admin` on this machine where to
/// connect, watches the mesh for the run's duration, and removes the file.
#[allow(clippy::too_many_arguments)]
async fn observe_run(
    args: &SimArgs,
    site: &Site,
    keys: &Keys,
    hub: &str,
    mesh: &StartedMesh,
    sup: &mut Supervisor,
    quiet: bool,
    security: Option<&SimSecurity>,
    shutdown: &mut (impl std::future::Future<Output = ()> + Unpin),
) -> Result<(RunStats, Option<String>), LaunchError> {
    let run_dir = ickon_runtime::RunDir::standard();
    let run = ickon_runtime::RunFile {
        site: site.name.clone(),
        central: vec![hub.to_string()],
        pid: std::process::id(),
        started_unix_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
    };
    if let Err(e) = run_dir.write(&run) {
        eprintln!("warning: `ickon admin` will not find this run: {e}");
    }
    if let Some(addr) = mesh.web {
        eprintln!("ickon sim: live map at http://{addr}/");
    }
    if let Some(addr) = mesh.foxglove {
        eprintln!("ickon sim: Foxglove live server at ws://{addr}");
    }
    if let (Some(s), false) = (security, quiet) {
        eprintln!("ickon sim: {}", s.admin_hint());
    }
    let observer_credential = security.map(|s| s.client_file(&Identity::Observer));
    let outcome = observe(
        args,
        site,
        keys,
        &mesh.session,
        hub,
        &mesh.alive,
        sup,
        quiet,
        observer_credential.as_deref(),
        shutdown,
    )
    .await;
    let _ = run_dir.remove(&site.name, run.pid);
    outcome
}
