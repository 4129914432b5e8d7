//! `ickon sim`: the whole system as separate OS processes over a loopback
//! Zenoh mesh, started and stopped with one command.
//!
//! The launcher spawns itself as `ickon node <role>` for the central unit, one
//! cell controller per cell, the world, and one MSU agent per robot: the same
//! library code as the standalone `ickon-central`, `ickon-cell`, `ickon-world`
//! and `ickon-msu` binaries, so that `cargo run -p ickon -- sim` needs no other
//! build step. As on a site, a Zenoh router (`ickon router`, its own
//! supervised process) listens on a loopback port and every node is its
//! client (`--mesh peer` lays out the old full mesh of peers instead, to
//! compare); multicast scouting is off so that two runs on one machine never
//! meet, and Zenoh's thread pools are kept small in every node. The launcher watches the mesh with its own
//! session (liveliness, bursts, arrivals, fixes, poses, truth), prints a live
//! status line, and a summary at the end.

pub mod faults;
mod launch;
mod metrics;
mod msu_file;
mod observe;
mod report;
mod secure;
mod supervisor;
mod usage;

pub use metrics::{CellSummary, RobotSummary};

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use ickon_proto::keys::Keys;
use ickon_proto::site::Site;
use rand::SeedableRng;
use serde::Serialize;
use zenoh::sample::SampleKind;

use crate::cli::{EXIT_BAD_INPUT, EXIT_FAILURE};
pub use launch::Mesh;
use launch::{
    CLOCK_STREAM, clock_flags, free_port, node_command, router_command, wait_for_listener,
};
use observe::{observe, open_observer};
use report::render_report;

/// Arguments of `ickon sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// A built-in site (`lab`, `warehouse`) or a site file (TOML); `lab` when omitted.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Number of robots: the first N robots of the site, each on its own route.
    #[arg(long, default_value_t = 3)]
    pub robots: usize,
    /// How long to run once every node is live, seconds.
    #[arg(long, default_value_t = 30.0)]
    pub duration: f64,
    /// Estimator every MSU agent runs (`tdoa-ekf`, ours, by default).
    #[arg(long, default_value = "tdoa-ekf")]
    pub estimator: String,
    /// Noise profile of the simulated world: ideal, paper, harsh, or a TOML file (deploy/profiles/paper.toml is a template).
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Seed of every random draw (world noise, injected clock errors).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON document on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Run the ROS 2 path end to end: the world publishes each robot's
    /// odometry and gyro as ROS 2 topics (rmw_zenoh) and the MSU agents read
    /// them there (`ickon-msu --ros2`) and publish ROS 2 poses too.
    #[arg(long)]
    pub ros2: bool,
    /// Serve the live web map from the central unit on ADDR, or the next
    /// free port above it (with no ADDR: 127.0.0.1:8080); the URL is printed.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8080")]
    pub http: Option<std::net::SocketAddr>,
    /// File with the token that allows pause, resume and reload over HTTP.
    #[arg(long, value_name = "FILE", requires = "http")]
    pub http_token_file: Option<PathBuf>,
    /// How the nodes reach each other: through a router, as on a site, or
    /// as a full mesh of peers (the layout before routers, to compare).
    #[arg(long, value_enum, default_value = "router")]
    pub mesh: Mesh,
    /// Record every message of the run into this MCAP file (as `ickon
    /// record`; refused if it exists), with what a replay needs to run the
    /// MSU cores as the agents did.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Access control on the router, default deny, and every node (the
    /// launcher too) authenticated with its own credential: the files of
    /// `ickon site secure --sim` in DIR, or with no DIR a fresh set in a
    /// temporary directory removed at exit.
    #[arg(long, value_name = "DIR", num_args = 0..=1)]
    pub secure: Option<Option<PathBuf>>,
    /// Which transmitters the central unit fires each cycle: `occupancy`
    /// (only where robots may be, issue 20; everything while no robot is
    /// known) or `all` (the whole schedule every cycle).
    #[arg(long, value_enum, default_value_t = ickon_central::node::Firing::Occupancy)]
    pub firing: ickon_central::node::Firing,
    /// Start a node again when it dies, as systemd would, instead of
    /// stopping the run.
    #[arg(long)]
    pub restart: bool,
    /// Run a second central unit as a hot standby (`ickon-central --standby`)
    /// that takes over when the first goes.
    #[arg(long)]
    pub standby: bool,
    /// Faults to inject, e.g. `kill:central@10s,stop:cell/c2@15s+3s,clockstep:cell/c3@20s+5ms,kill:msu/r1@25s`
    /// (times from the moment every node is live; see `deploy/src/sim/faults.rs`).
    #[arg(long, value_name = "PLAN")]
    pub faults: Option<String>,
    /// Every agent's `tdoa-ekf` learns each cell's sync error as a state
    /// (`learn_cell_sync = true` in the configuration file they are given).
    #[arg(long)]
    pub learn_cell_sync: bool,
    /// The central unit does not learn the transmitters' survey errors
    /// from the robots' fixes (on by default).
    #[arg(long)]
    pub no_survey_calibration: bool,
}

impl SimArgs {
    /// The filter options every agent's configuration file gets.
    pub fn filter_options(&self) -> ickon_sim::engine::FilterOptions {
        ickon_sim::engine::FilterOptions {
            learn_cell_sync: self.learn_cell_sync,
        }
    }
}

/// How long the nodes get to come up and announce themselves.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the nodes get to stop after SIGTERM before they are killed.
const STOP_GRACE: Duration = Duration::from_secs(5);
/// Injected clock errors of cells and robots: up to this offset...
const MAX_CLOCK_OFFSET_US: f64 = 50_000.0;
/// ...and this drift.
const MAX_CLOCK_DRIFT_PPM: f64 = 100.0;

/// The JSON document of `ickon sim --json`.
#[derive(Debug, Serialize)]
pub struct SimReport {
    pub site: String,
    pub profile: String,
    pub estimator: String,
    pub seed: u64,
    /// Whether odometry and gyro went over ROS 2 (`--ros2`).
    pub ros2: bool,
    pub duration_s: f64,
    /// Cycles per second of the schedule with every cell up: the fixes each
    /// robot can get per second at most.
    pub update_rate_hz: f64,
    /// How the nodes reached each other.
    pub mesh: Mesh,
    /// Whether the router enforced access control (`--secure`).
    pub secure: bool,
    /// The endpoint every node connected to: the router's (the central
    /// unit's with `--mesh peer`); it tells this run's processes apart.
    pub central_endpoint: String,
    pub zenoh_hop_p50_us: Option<f64>,
    pub zenoh_hop_p99_us: Option<f64>,
    pub robots: Vec<RobotSummary>,
    pub cells: Vec<CellSummary>,
    pub bad_messages: u64,
    /// Cycles the central unit triggered while the run was watched.
    pub cycles_triggered: u64,
    /// Of those, per second of the run.
    pub cycles_per_s: f64,
    /// CPU time and peak memory per kind of process, read just before they stopped.
    pub processes: Vec<usage::KindUsage>,
    /// The recording of `--record`: file, messages per topic, rates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recorded: Option<crate::record::RecordReport>,
    /// Faults injected (`--faults`) and when, seconds from the start.
    pub faults_done: Vec<(String, f64)>,
    /// Nodes restarted after they died (`--restart`).
    pub restarts: Vec<String>,
}

/// Runs `ickon sim` and returns the exit code.
pub fn run(args: SimArgs) -> ExitCode {
    let (site, profile) = match check_args(&args) {
        Ok(checked) => checked,
        Err(code) => return code,
    };
    match ickon_runtime::block_on(2, measure(&args, &site, &profile)) {
        None => ExitCode::from(EXIT_FAILURE),
        Some(Err(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(EXIT_FAILURE)
        }
        Some(Ok(Err(code))) => code,
        Some(Ok(Ok((report, failure)))) => {
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
                Some(why) => {
                    eprintln!("error: {why}");
                    ExitCode::from(EXIT_FAILURE)
                }
                None => ExitCode::SUCCESS,
            }
        }
    }
}

/// Loads the site and checks the flags; on bad input, says why and gives exit code 2.
pub fn check_args(args: &SimArgs) -> Result<(Site, ickon_sim::profile::NoiseProfile), ExitCode> {
    let (site, _text, _name) = match Site::load_or_default(args.site.as_deref()) {
        Ok(loaded) => loaded,
        Err(e) => {
            eprintln!("error: {e}");
            return Err(ExitCode::from(EXIT_BAD_INPUT));
        }
    };
    if args.robots == 0 || args.robots > site.robots.len() {
        eprintln!(
            "error: --robots {} is not possible: the site {:?} has {} robots (1 to {})",
            args.robots,
            site.name,
            site.robots.len(),
            site.robots.len()
        );
        return Err(ExitCode::from(EXIT_BAD_INPUT));
    }
    let profile = match ickon_sim::profile::NoiseProfile::load(&args.profile) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return Err(ExitCode::from(EXIT_BAD_INPUT));
        }
    };
    if let Err(e) = ickon_fusion::estimator::EstimatorConfig::default_for(&args.estimator) {
        eprintln!("error: {e}");
        return Err(ExitCode::from(EXIT_BAD_INPUT));
    }
    if let Err(e) = args.filter_options().check_for(&args.estimator) {
        eprintln!("error: {e}");
        return Err(ExitCode::from(EXIT_BAD_INPUT));
    }
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0) {
        eprintln!("error: --duration must be between 0 and 86400 seconds");
        return Err(ExitCode::from(EXIT_BAD_INPUT));
    }
    // Read here as the central unit will: a bad token file is the user's
    // input, refused before a node starts, not a central dying at start-up.
    if let Some(path) = &args.http_token_file {
        if let Err(e) = ickon_central::http::read_token(path) {
            eprintln!("error: --http-token-file: {e}");
            return Err(ExitCode::from(EXIT_BAD_INPUT));
        }
    }
    if let Some(plan) = &args.faults {
        match faults::parse_plan(plan) {
            Err(e) => {
                eprintln!("error: {e}");
                return Err(ExitCode::from(EXIT_BAD_INPUT));
            }
            Ok(plan) => {
                if let Some(f) = plan.iter().find(|f| {
                    matches!(f.action, faults::FaultAction::ClockStep(_))
                        && !faults::keeps_a_clock(&f.node)
                }) {
                    eprintln!(
                        "error: --faults: {:?}: only a cell or a central unit keeps a clock to step",
                        f.text
                    );
                    return Err(ExitCode::from(EXIT_BAD_INPUT));
                }
                let nodes: Vec<String> = std::iter::once("central".to_string())
                    .chain(args.standby.then(|| "central standby".to_string()))
                    .chain(["world".to_string(), "router".to_string()])
                    .chain(site.cells.iter().map(|c| format!("cell {}", c.id)))
                    .chain(
                        site.robots
                            .iter()
                            .take(args.robots)
                            .map(|r| format!("msu {}", r.id)),
                    )
                    .collect();
                if let Some(f) = plan.iter().find(|f| !nodes.contains(&f.node)) {
                    eprintln!(
                        "error: --faults: {:?}: this run has no node {}",
                        f.text, f.node
                    );
                    return Err(ExitCode::from(EXIT_BAD_INPUT));
                }
            }
        }
    }
    Ok((site, profile))
}

/// What a run gives: its report and, if it failed, why; or, when it could
/// not start (already said on stderr), the exit code.
pub type Measured = Result<(SimReport, Option<String>), ExitCode>;

/// Runs the mesh once and measures it (`ickon sim`, and each size of `ickon bench scale`).
pub async fn measure(
    args: &SimArgs,
    site: &Site,
    profile: &ickon_sim::profile::NoiseProfile,
) -> anyhow::Result<Measured> {
    // Installed first: a Ctrl-C or SIGTERM (a service manager, `timeout`)
    // during start-up is held until the mesh is up, then stops it like one
    // during the run, so the nodes are stopped and the run file and the
    // agents' temporary files removed.
    let mut shutdown = Box::pin(ickon_runtime::shutdown_signal(false));
    let keys = Keys::new(&site.name)?;
    let all_cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    let update_rate_hz =
        ickon_central::update_rate_hz(&ickon_central::compute_schedule(site, &all_cells, 1, 0)?);
    let hub_port = free_port()?;
    let hub = format!("tcp/127.0.0.1:{hub_port}");
    let robots: Vec<String> = site
        .robots
        .iter()
        .take(args.robots)
        .map(|r| r.id.clone())
        .collect();
    let mut clocks = rand_chacha::ChaCha8Rng::seed_from_u64(args.seed ^ CLOCK_STREAM);
    let security = match secure::SimSecurity::prepare(args, site, &robots) {
        Ok(s) => s,
        Err(code) => return Ok(Err(code)),
    };
    let credential = |cmd: &mut std::process::Command, who: &crate::secure::Identity| {
        if let Some(s) = &security {
            s.client(cmd, who);
        }
    };
    let mut sup = supervisor::Supervisor::new();
    // The clock steps of the plan (checked already), given to each node at
    // its start: it takes the next at each SIGUSR1 the plan sends.
    let plan = args
        .faults
        .as_deref()
        .and_then(|p| faults::parse_plan(p).ok())
        .unwrap_or_default();
    let clock_steps = |cmd: &mut std::process::Command, node: &str| {
        if let Some(steps) = faults::clock_steps_flag(&plan, node) {
            cmd.arg("--sim-clock-steps-us").arg(steps);
        }
    };

    let mut central_cmd = match args.mesh {
        Mesh::Router => {
            let mut router = router_command(&hub)?;
            if let Some(s) = &security {
                s.router(&mut router);
            }
            sup.spawn("router", router)?;
            if let Err(e) = wait_for_listener(hub_port, &mut sup, STARTUP_TIMEOUT).await {
                sup.stop_all(STOP_GRACE);
                eprintln!("error: {e:#}");
                return Ok(Err(ExitCode::from(EXIT_FAILURE)));
            }
            node_command(args, site, "central", &hub, "")?
        }
        Mesh::Peer => node_command(args, site, "central", "", &hub)?,
    };
    // The flag's own spelling, from the same clap definition that parses it.
    let firing = clap::ValueEnum::to_possible_value(&args.firing)
        .map(|v| v.get_name().to_string())
        .unwrap_or_default();
    let timing_sigma_us = format!("{}", ickon_sim::engine::timing_sigma_s(profile) * 1e6);
    let sync_sigma_us = format!("{}", ickon_sim::engine::cell_sync_sigma_s(profile) * 1e6);
    let survey_flags: Vec<&str> = if args.no_survey_calibration {
        vec!["--no-survey-calibration"]
    } else {
        vec![
            "--timing-sigma-us",
            &timing_sigma_us,
            "--cell-sync-sigma-us",
            &sync_sigma_us,
        ]
    };
    central_cmd.args(["--firing", &firing]).args(&survey_flags);
    credential(&mut central_cmd, &crate::secure::Identity::Central);
    let web = launch::http_flags(args, &mut central_cmd)?;
    clock_steps(&mut central_cmd, "central");
    sup.spawn("central", central_cmd)?;
    if args.standby {
        // A second central unit that follows the first and takes over.
        let mut standby = match args.mesh {
            Mesh::Router => node_command(args, site, "central", &hub, "")?,
            Mesh::Peer => node_command(args, site, "central", "", &hub)?,
        };
        standby
            .args(["--standby", "--firing", &firing])
            .args(&survey_flags);
        clock_steps(&mut standby, "central standby");
        credential(&mut standby, &crate::secure::Identity::Central);
        sup.spawn("central standby", standby)?;
    }
    let msus = msu_starts(args, site, profile, &robots)?;
    let as_identity = |who: crate::secure::Identity| security.as_ref().map(|s| s.client_file(&who));
    let session = match open_observer(
        &hub,
        args.mesh,
        as_identity(crate::secure::Identity::Observer).as_deref(),
    )
    .await
    {
        Ok(s) => s,
        Err(e) => {
            sup.stop_all(STOP_GRACE);
            return Err(e);
        }
    };
    // Recording starts before the first cell, so that it holds every burst.
    let recorder_endpoint = match args.record {
        Some(_) => Some(format!("tcp/127.0.0.1:{}", free_port()?)),
        None => None,
    };
    let recorder_session = match &recorder_endpoint {
        Some(listen) => match crate::record::sim_hook::open_session(
            &hub,
            listen,
            as_identity(crate::secure::Identity::Recorder).as_deref(),
        )
        .await
        {
            Ok(s) => Some(s),
            Err(e) => {
                sup.stop_all(STOP_GRACE);
                let _ = session.close().await;
                eprintln!("error: --record: {e}");
                return Ok(Err(ExitCode::from(EXIT_FAILURE)));
            }
        },
        None => None,
    };
    let recording = match (&args.record, &recorder_session) {
        (Some(path), Some(rec_session)) => {
            let settings = [
                ("profile", args.profile.clone()),
                ("seed", args.seed.to_string()),
                ("estimator", args.estimator.clone()),
                ("robots", robots.join(",")),
                ("duration_s", args.duration.to_string()),
            ];
            let metadata = crate::record::sim_hook::sim_metadata(&site.name, &settings, &msus);
            match crate::record::sim_hook::SimRecording::start(rec_session, &keys, path, &metadata)
            {
                Ok(r) => Some(r),
                Err(e) => {
                    sup.stop_all(STOP_GRACE);
                    let _ = session.close().await;
                    eprintln!("error: --record: {e}");
                    return Ok(Err(ExitCode::from(EXIT_BAD_INPUT)));
                }
            }
        }
        _ => None,
    };
    // In a peer mesh, the nodes whose messages a replay needs also connect
    // to the recorder directly; through a router (a client keeps one
    // connection) the recorder hears them by the router, as every observer.
    let to_recorder: Vec<String> = recorder_endpoint
        .iter()
        .filter(|_| args.mesh == Mesh::Peer)
        .flat_map(|e| ["--connect".to_string(), e.clone()])
        .collect();
    let alive = session
        .liveliness()
        .declare_subscriber(keys.alive_all())
        .history(true)
        .await
        .map_err(|e| anyhow::anyhow!("liveliness subscriber: {e}"))?;
    for cell in &site.cells {
        let mut cmd = node_command(args, site, "cell", &hub, "tcp/127.0.0.1:0")?;
        cmd.args(["--cell", &cell.id])
            .args(clock_flags(&mut clocks))
            .args(&to_recorder);
        clock_steps(&mut cmd, &format!("cell {}", cell.id));
        credential(&mut cmd, &crate::secure::Identity::Cell(cell.id.clone()));
        sup.spawn(&format!("cell {}", cell.id), cmd)?;
    }
    let mut world = node_command(args, site, "world", &hub, "tcp/127.0.0.1:0")?;
    world.args([
        "--robots",
        &robots.join(","),
        "--profile",
        &args.profile,
        "--seed",
        &args.seed.to_string(),
    ]);
    world.args(&to_recorder);
    credential(&mut world, &crate::secure::Identity::World);
    if args.ros2 {
        world.arg("--ros2");
    }
    sup.spawn("world", world)?;
    // Every agent reads one configuration file, as a deployed one does: the
    // estimator as `ickon eval` sets it up for the profile's data sheet,
    // the simulated robots' nominal drive, the arrivals' timing noise (the
    // site gives each agent its robot's start pose).
    let drive = ickon_sim::robot::DriveSpec::default();
    let msu_file = msu_file::write_temp(&msu_file::render(
        &ickon_sim::engine::estimator_config(
            &args.estimator,
            [0.0; 3],
            site,
            profile,
            args.filter_options(),
        )?,
        ickon_sim::engine::timing_sigma_s(profile),
        drive.geometry(),
        args.ros2,
    )?)?;
    for msu in &msus {
        let mut cmd = node_command(args, site, "msu", &hub, "tcp/127.0.0.1:0")?;
        cmd.args(["--robot", &msu.robot, "--config"])
            .arg(msu_file.path())
            .args(&to_recorder);
        credential(&mut cmd, &crate::secure::Identity::Robot(msu.robot.clone()));
        sup.spawn(&format!("msu {}", msu.robot), cmd)?;
    }

    // Wait until every node has announced itself, or one died, or time is up.
    let mut expected: std::collections::BTreeSet<String> = std::iter::once(keys.alive_central())
        .chain(std::iter::once(keys.alive_world()))
        .chain(
            site.cells
                .iter()
                .map(|c| keys.alive_cell(&c.id))
                .collect::<Result<Vec<_>, _>>()?,
        )
        .chain(
            robots
                .iter()
                .map(|r| keys.alive_robot(r))
                .collect::<Result<Vec<_>, _>>()?,
        )
        .collect();
    let started = Instant::now();
    let quiet = args.json && !std::io::IsTerminal::is_terminal(&std::io::stderr());
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
            sup.stop_all(STOP_GRACE);
            eprintln!("error: node {} {} during start-up", dead.name, dead.status);
            return Ok(Err(ExitCode::from(EXIT_FAILURE)));
        }
        if started.elapsed() > STARTUP_TIMEOUT {
            sup.stop_all(STOP_GRACE);
            let missing: Vec<String> = expected.into_iter().collect();
            anyhow::bail!(
                "nodes not live after {} s: {}",
                STARTUP_TIMEOUT.as_secs(),
                missing.join(", ")
            );
        }
        if let Ok(Ok(sample)) =
            tokio::time::timeout(Duration::from_millis(100), alive.recv_async()).await
        {
            if sample.kind() == SampleKind::Put {
                expected.remove(sample.key_expr().as_str());
            }
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

    // The run file tells `ickon admin` on this machine where to connect.
    let run_dir = ickon_runtime::RunDir::standard();
    let run = ickon_runtime::RunFile {
        site: site.name.clone(),
        central: vec![hub.clone()],
        pid: std::process::id(),
        started_unix_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
    };
    if let Err(e) = run_dir.write(&run) {
        eprintln!("warning: `ickon admin` will not find this run: {e}");
    }
    if let Some(addr) = web {
        eprintln!("ickon sim: live map at http://{addr}/");
    }
    if let (Some(s), false) = (&security, quiet) {
        eprintln!("ickon sim: {}", s.admin_hint());
    }
    let observer_credential = as_identity(crate::secure::Identity::Observer);
    let outcome = observe(
        args,
        site,
        &keys,
        &session,
        &hub,
        &alive,
        &mut sup,
        quiet,
        observer_credential.as_deref(),
        &mut shutdown,
    )
    .await;
    let _ = run_dir.remove(&site.name, run.pid);
    let mut used = sup.usage();
    if let Some(me) = usage::read(std::process::id()) {
        used.push(("launcher".to_string(), me));
    }
    // The nodes stop first, so that the file holds everything they
    // published, the last poses the observer counted among it.
    let killed = sup.stop_all(STOP_GRACE);
    let recorded = match recording {
        Some(r) => Some(r.finish().await),
        None => None,
    };
    if let Some(s) = recorder_session {
        let _ = s.close().await;
    }
    let _ = session.close().await;
    let (stats, failure) = outcome?;
    if !killed.is_empty() {
        eprintln!(
            "warning: nodes that did not stop within {} s were killed: {}",
            STOP_GRACE.as_secs(),
            killed.join(", ")
        );
    }
    let completed = metrics::completed_cycles(&stats.cycles_triggered);
    let report = SimReport {
        site: site.name.clone(),
        profile: args.profile.clone(),
        estimator: args.estimator.clone(),
        seed: args.seed,
        ros2: args.ros2,
        duration_s: args.duration,
        update_rate_hz,
        mesh: args.mesh,
        secure: security.is_some(),
        central_endpoint: hub.clone(),
        zenoh_hop_p50_us: metrics::percentile(&stats.hop_latencies_us, 50.0),
        zenoh_hop_p99_us: metrics::percentile(&stats.hop_latencies_us, 99.0),
        robots: robots
            .iter()
            .map(|r| {
                stats
                    .robots
                    .get(r)
                    .map(|s| s.summary(r, completed.len()))
                    .unwrap_or_else(|| metrics::RobotStats::default().summary(r, completed.len()))
            })
            .collect(),
        cells: site
            .cells
            .iter()
            .map(|c| {
                let due = stats.cycles_for_cell(&c.id, &completed);
                stats
                    .cells
                    .get(&c.id)
                    .map(|s| s.summary(&c.id, &due))
                    .unwrap_or_else(|| metrics::CellStats::default().summary(&c.id, &due))
            })
            .collect(),
        bad_messages: stats.bad_messages.values().sum(),
        cycles_triggered: stats.cycles_triggered.len() as u64,
        cycles_per_s: stats.cycles_triggered.len() as f64 / args.duration,
        processes: usage::by_kind(&used),
        recorded: recorded.as_ref().and_then(|r| r.as_ref().ok()).cloned(),
        faults_done: stats.faults_done.clone(),
        restarts: stats.restarts.clone(),
    };
    let failure = match (failure, recorded) {
        (None, Some(Err(e))) => Some(e),
        (f, _) => f,
    };
    Ok(Ok((report, failure)))
}

/// What each MSU agent is started with: the same estimator set-up as `ickon
/// eval` (the robot's start pose and the profile's sensor data sheet), and
/// the nominal drive of the simulated robots (what the agent converts
/// encoder ticks with).
fn msu_starts(
    args: &SimArgs,
    site: &Site,
    profile: &ickon_sim::profile::NoiseProfile,
    robots: &[String],
) -> anyhow::Result<Vec<crate::record::sim_hook::MsuStart>> {
    let drive = ickon_sim::robot::DriveSpec::default();
    robots
        .iter()
        .map(|robot| {
            let start = site
                .robots
                .iter()
                .find(|r| &r.id == robot)
                .map_or([0.0; 3], |r| r.start);
            let config = ickon_sim::engine::estimator_config(
                &args.estimator,
                start,
                site,
                profile,
                args.filter_options(),
            )?;
            // The value the agent's configuration file holds (`msu_file`):
            // a float written in full, so the replay uses the agent's value.
            let timing_sigma_us = ickon_sim::engine::timing_sigma_s(profile) * 1e6;
            Ok(crate::record::sim_hook::MsuStart {
                robot: robot.clone(),
                estimator_json: serde_json::to_string(&config)?,
                timing_sigma_us,
                wheel_base_m: drive.wheel_base_m,
                m_per_tick: drive.m_per_tick(),
            })
        })
        .collect()
}
