//! `ickon sim`: the whole system as separate OS processes over a loopback
//! Zenoh mesh, started and stopped with one command.
//!
//! The launcher spawns itself as `ickon node <role>` for the central unit, one
//! cell controller per cell, the world, and one MSU agent per robot: the same
//! library code as the standalone `ickon-central`, `ickon-cell`, `ickon-world`
//! and `ickon-msu` binaries, so that `cargo run -p ickon -- sim` needs no other
//! build step. Every node is a Zenoh peer listening on its own loopback port
//! and connecting to the central unit's; multicast scouting is off so that two
//! runs on one machine never meet. The launcher watches the mesh with its own
//! session (liveliness, bursts, arrivals, fixes, poses, truth), prints a live
//! status line, and a summary at the end.

mod launch;
mod metrics;
mod msu_file;
mod observe;
mod report;
mod supervisor;

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
use launch::{CLOCK_STREAM, clock_flags, free_port, node_command};
use observe::{observe, open_observer};
use report::render_report;

/// Arguments of `ickon sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// Site file (TOML); the built-in lab site when omitted.
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
    /// Noise profile of the simulated world: ideal, paper or harsh.
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
struct SimReport {
    site: String,
    profile: String,
    estimator: String,
    seed: u64,
    /// Whether odometry and gyro went over ROS 2 (`--ros2`).
    ros2: bool,
    duration_s: f64,
    /// Cycles per second of the schedule with every cell up: the fixes each
    /// robot can get per second at most.
    update_rate_hz: f64,
    /// The central unit's endpoint (tells this run's processes apart).
    central_endpoint: String,
    zenoh_hop_p50_us: Option<f64>,
    zenoh_hop_p99_us: Option<f64>,
    robots: Vec<RobotSummary>,
    cells: Vec<CellSummary>,
    bad_messages: u64,
}

/// Runs `ickon sim` and returns the exit code.
pub fn run(args: SimArgs) -> ExitCode {
    let (site, _text, _name) = match Site::load_or_default(args.site.as_deref()) {
        Ok(loaded) => loaded,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_BAD_INPUT);
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
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let profile = match ickon_sim::profile::NoiseProfile::by_name(&args.profile) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    if let Err(e) = ickon_fusion::estimator::EstimatorConfig::default_for(&args.estimator) {
        eprintln!("error: {e}");
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0) {
        eprintln!("error: --duration must be between 0 and 86400 seconds");
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    match ickon_runtime::block_on(2, run_mesh(&args, &site, &profile)) {
        Some(Ok(code)) => code,
        None => ExitCode::from(EXIT_FAILURE),
        Some(Err(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(EXIT_FAILURE)
        }
    }
}

async fn run_mesh(
    args: &SimArgs,
    site: &Site,
    profile: &ickon_sim::profile::NoiseProfile,
) -> anyhow::Result<ExitCode> {
    let keys = Keys::new(&site.name)?;
    let all_cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    let update_rate_hz =
        ickon_central::update_rate_hz(&ickon_central::compute_schedule(site, &all_cells, 1, 0)?);
    let central = format!("tcp/127.0.0.1:{}", free_port()?);
    let robots: Vec<String> = site
        .robots
        .iter()
        .take(args.robots)
        .map(|r| r.id.clone())
        .collect();
    let mut clocks = rand_chacha::ChaCha8Rng::seed_from_u64(args.seed ^ CLOCK_STREAM);
    let mut sup = supervisor::Supervisor::new();

    sup.spawn(
        "central",
        node_command(args, site, "central", "", &central)?,
    )?;
    let session = open_observer(&central).await?;
    let alive = session
        .liveliness()
        .declare_subscriber(keys.alive_all())
        .history(true)
        .await
        .map_err(|e| anyhow::anyhow!("liveliness subscriber: {e}"))?;
    for cell in &site.cells {
        let mut cmd = node_command(args, site, "cell", &central, "tcp/127.0.0.1:0")?;
        cmd.args(["--cell", &cell.id])
            .args(clock_flags(&mut clocks));
        sup.spawn(&format!("cell {}", cell.id), cmd)?;
    }
    let mut world = node_command(args, site, "world", &central, "tcp/127.0.0.1:0")?;
    world.args([
        "--robots",
        &robots.join(","),
        "--profile",
        &args.profile,
        "--seed",
        &args.seed.to_string(),
    ]);
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
        &ickon_sim::engine::estimator_config(&args.estimator, [0.0; 3], site, profile)?,
        ickon_sim::engine::timing_sigma_s(profile),
        drive.geometry(),
    )?)?;
    for robot in &robots {
        let mut cmd = node_command(args, site, "msu", &central, "tcp/127.0.0.1:0")?;
        cmd.args(["--robot", robot, "--config"])
            .arg(msu_file.path());
        if args.ros2 {
            cmd.arg("--ros2");
        }
        sup.spawn(&format!("msu {robot}"), cmd)?;
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
            return Ok(ExitCode::from(EXIT_FAILURE));
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
        central: vec![central.clone()],
        pid: std::process::id(),
        started_unix_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
    };
    if let Err(e) = run_dir.write(&run) {
        eprintln!("warning: `ickon admin` will not find this run: {e}");
    }
    let outcome = observe(
        args, site, &keys, &session, &central, &alive, &mut sup, quiet,
    )
    .await;
    let _ = run_dir.remove(&site.name, run.pid);
    let killed = sup.stop_all(STOP_GRACE);
    let _ = session.close().await;
    let (stats, failure) = outcome?;
    if !killed.is_empty() {
        eprintln!(
            "warning: nodes that did not stop within {} s were killed: {}",
            STOP_GRACE.as_secs(),
            killed.join(", ")
        );
    }
    let report = SimReport {
        site: site.name.clone(),
        profile: args.profile.clone(),
        estimator: args.estimator.clone(),
        seed: args.seed,
        ros2: args.ros2,
        duration_s: args.duration,
        update_rate_hz,
        central_endpoint: central.clone(),
        zenoh_hop_p50_us: metrics::percentile(&stats.hop_latencies_us, 50.0),
        zenoh_hop_p99_us: metrics::percentile(&stats.hop_latencies_us, 99.0),
        robots: robots
            .iter()
            .map(|r| {
                stats
                    .robots
                    .get(r)
                    .map(|s| s.summary(r))
                    .unwrap_or_else(|| metrics::RobotStats::default().summary(r))
            })
            .collect(),
        cells: site
            .cells
            .iter()
            .map(|c| {
                stats
                    .cells
                    .get(&c.id)
                    .map(|s| s.summary(&c.id))
                    .unwrap_or_else(|| metrics::CellStats::default().summary(&c.id))
            })
            .collect(),
        bad_messages: stats.bad_messages.values().sum(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_report(&report));
    }
    match failure {
        Some(why) => {
            eprintln!("error: {why}");
            Ok(ExitCode::from(EXIT_FAILURE))
        }
        None => Ok(ExitCode::SUCCESS),
    }
}
