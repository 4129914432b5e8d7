//! The flags of `ickon sim` and their checks, made before any process starts.

use std::path::PathBuf;

use clap::Args;
use ickon_proto::site::Site;
use ickon_runtime::CommandError;

use crate::device_plan::{Devices, SimReceivers};
use crate::faults;

/// How the nodes of a run reach each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mesh {
    /// As on a site: one router process, every node its client.
    Router,
    /// Every node a peer listening on loopback, connected to the central
    /// unit, gossip making a full mesh (the layout before routers; kept to
    /// compare).
    Peer,
}

/// Arguments of `ickon sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// A built-in site (`lab`, `warehouse`, `hall`) or a site file (TOML); `lab` when omitted.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Number of robots: the first N robots of the site, each on its own
    /// route; above the robots the site defines (up to 10000), the site's
    /// robots and more added on its routes, spread along them by the seed.
    #[arg(long, default_value_t = 3)]
    pub robots: usize,
    /// How long to run once every node is live, seconds.
    #[arg(long, default_value_t = 30.0)]
    pub duration: f64,
    /// Estimator every MSU agent runs (`tdoa-ekf`, ours, by default).
    #[arg(long, default_value = "tdoa-ekf")]
    pub estimator: String,
    /// Noise profile of the simulated world: ideal, paper, building, harsh, or a TOML file (deploy/profiles/paper.toml is a template).
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
    /// Serve the run live to the Foxglove app (read-only; docs/foxglove.md)
    /// from the central unit on ADDR, or the next free port above it (with
    /// no ADDR: 127.0.0.1:8765); the address is printed.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = ickon_central::foxglove::DEFAULT_ADDR)]
    pub foxglove: Option<std::net::SocketAddr>,
    /// How the nodes reach each other: through a router, as on a site, or
    /// as a full mesh of peers (the layout before routers, to compare).
    #[arg(long, value_enum, default_value = "router")]
    pub mesh: Mesh,
    /// Routers, one per zone: the site's cells split into N contiguous,
    /// balanced zones along its longest axis; each cell and each robot (by
    /// where it starts) a client of its zone's router; routers 2 to N linked
    /// to the first, where the central unit, the world and the launcher
    /// connect. 1 is one router for the whole site.
    #[arg(long, default_value_t = 1, allow_hyphen_values = true)]
    pub routers: usize,
    /// Record every message of the run into this MCAP file (as `ickon
    /// record`; refused if it exists), with what a replay needs to run the
    /// MSU cores as the agents did.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// With `--record`: hold the Foxglove view in the file too (as `ickon
    /// record --foxglove-view`), for Foxglove; `ros2 bag` does not open such
    /// a file.
    #[arg(long, requires = "record")]
    pub record_foxglove_view: bool,
    /// Mutual TLS on every link, access control on the router, default
    /// deny, and every node (the launcher too) authenticated with its own
    /// certificate and password: the files of `ickon site secure --sim` in
    /// DIR (its links in clear if it was written with `tcp/` endpoints), or
    /// with no DIR a fresh set in a temporary directory removed at exit.
    #[arg(long, value_name = "DIR", num_args = 0..=1)]
    pub secure: Option<Option<PathBuf>>,
    /// Which transmitters the central unit fires each cycle: `needs` (a
    /// few in good geometry for each robot, spaced by the room's
    /// reverberation), `occupancy` (everything audible where robots may
    /// be; with both, everything while no robot is known) or `all` (the
    /// whole schedule every cycle).
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
    /// (times from the moment every node is live), and transmitters failing in
    /// the world: `dead:tx/22@10s`, `weak:tx/22@10s=0.25`, `moved:tx/22@10s=0.3,0,0`
    /// (times from the world's start).
    #[arg(long, value_name = "PLAN")]
    pub faults: Option<String>,
    /// Every agent's `tdoa-ekf` learns each cell's sync error as a state
    /// (`learn_cell_sync = true` in the configuration file they are given).
    #[arg(long)]
    pub learn_cell_sync: bool,
    /// Every agent's `tdoa-ekf` carries the wind where its robot is as a
    /// state (`sensors.local_wind_sigma_m_s = 0.5` in the configuration
    /// file they are given): for a hall with drafts.
    #[arg(long)]
    pub local_wind: bool,
    /// The central unit does not learn the transmitters' survey errors
    /// from the robots' fixes (on by default).
    #[arg(long)]
    pub no_survey_calibration: bool,
    /// The central unit does not publish the speed of sound it learns
    /// from the robots' fixes: the MSUs use the site file's throughout.
    #[arg(long)]
    pub no_speed_of_sound: bool,
    /// How the nodes reach the simulated hardware: `direct` (the simulated
    /// driver and receivers), or `emulated`: every cell fires through a
    /// transmitter board and every robot hears (and reads its wheel ticks
    /// and gyro) through a receiver board of the ICKON device protocol,
    /// over TCP, each board emulated by the world with a clock of its own.
    #[arg(long, value_enum, default_value_t = Devices::Direct)]
    pub devices: Devices,
    /// What every robot's agent hears: `sim` (the cells' bursts) or
    /// `marvelmind` (a Marvelmind hedgehog the world emulates, ranging to
    /// the site's transmitters as the kit's beacons; the run's report
    /// scores the kit's own positions beside the agent's poses).
    #[arg(long, value_enum, default_value_t = SimReceivers::Sim)]
    pub receivers: SimReceivers,
    /// Robots whose MSU agents share one process (`ickon node fleet`):
    /// each keeps its own core, keys, configuration and outputs, and they
    /// share the process's runtime and Zenoh session, so that a large
    /// fleet does not cost one process per robot on one machine. `1` runs
    /// one process per robot, as deployed robots do. Default: 16, or 1
    /// with `--ros2`, `--secure DIR` or a fault plan that names an agent.
    #[arg(long, value_name = "K", allow_hyphen_values = true, value_parser = parse_robots_per_process)]
    pub robots_per_process: Option<usize>,
    /// Pin the site's servers (router, central unit, cells) to one half of
    /// this machine's CPUs and the world, the agents and the launcher to
    /// the other, so that the servers are measured as if every robot had
    /// a computer of its own; the report gives each side's CPU.
    #[arg(long)]
    pub split_cores: bool,
}

/// Robots per process when `--robots-per-process` is not given: chosen on
/// `warehouse` with 64 robots on two cores (docs/performance.md), the
/// smallest grouping past which pose latency stopped improving.
pub const DEFAULT_ROBOTS_PER_PROCESS: usize = 16;

/// `--robots-per-process`: 1 to the most one process hosts.
pub(crate) fn parse_robots_per_process(text: &str) -> Result<usize, String> {
    let max = ickon_msu::fleet::MAX_ROBOTS_PER_PROCESS;
    match text.trim().parse::<usize>() {
        Ok(k) if (1..=max).contains(&k) => Ok(k),
        _ => Err(format!(
            "{text:?} is not a number of robots from 1 to {max}"
        )),
    }
}

impl SimArgs {
    /// Robots per agent process: `--robots-per-process`, else 1 where an
    /// agent must be a process of its own (ROS 2 nodes, faults aimed at one
    /// agent), else [`DEFAULT_ROBOTS_PER_PROCESS`].
    pub fn robots_per_process(&self) -> usize {
        self.robots_per_process.unwrap_or_else(|| {
            let given_credentials = matches!(self.secure, Some(Some(_)));
            if self.ros2 || self.faults_name_an_agent() || given_credentials {
                1
            } else {
                DEFAULT_ROBOTS_PER_PROCESS
            }
        })
    }

    /// Whether `--faults` aims at an MSU agent.
    fn faults_name_an_agent(&self) -> bool {
        self.faults
            .as_deref()
            .and_then(|p| faults::parse_plan(p).ok())
            .is_some_and(|plan| plan.iter().any(|f| f.node.starts_with("msu ")))
    }

    /// The filter options every agent's configuration file gets.
    pub fn filter_options(&self) -> ickon_sim::engine::FilterOptions {
        ickon_sim::engine::FilterOptions {
            learn_cell_sync: self.learn_cell_sync,
            local_wind: self.local_wind,
        }
    }
}

/// `--robots-per-process` above 1 where every agent must be a process of
/// its own, and `--split-cores` where there is nothing to split.
fn check_grouping(args: &SimArgs) -> Result<(), CommandError> {
    if args.robots_per_process.is_some_and(|k| k > 1) {
        let why = if args.ros2 {
            Some("each ROS 2 node is an agent process of its own")
        } else if args.faults_name_an_agent() {
            Some("--faults aims at an agent, which needs a process of its own")
        } else if matches!(args.secure, Some(Some(_))) {
            Some(
                "--secure DIR holds one credential per robot, and grouped robots share a fleet credential that only a generated set has (use --secure without DIR)",
            )
        } else {
            None
        };
        if let Some(why) = why {
            return Err(CommandError::bad_input(format!(
                "--robots-per-process above 1 is not possible here: {why}; use --robots-per-process 1"
            )));
        }
    }
    if args.split_cores {
        crate::core_split::CoreSplit::of_this_machine()
            .map_err(|e| CommandError::bad_input(format!("--split-cores: {e}")))?;
    }
    Ok(())
}

/// The names of the run's router processes (`router`, or `router z1` ...).
fn router_names(site: &Site, routers: usize) -> Vec<String> {
    crate::zones::split(site, &[], routers)
        .unwrap_or_default()
        .iter()
        .map(|z| crate::zones::router_name(z, routers))
        .collect()
}

/// Loads the site and checks the flags, before any process is started.
pub fn check_args(
    args: &SimArgs,
) -> Result<(Site, ickon_sim::profile::NoiseProfile), CommandError> {
    if args.robots == 0 {
        return Err(CommandError::bad_input(
            "--robots 0 is not possible: a run needs at least one robot",
        ));
    }
    let (site, _) = crate::fleet_site::load(args.site.as_deref(), args.robots, args.seed)?;
    let profile = ickon_sim::profile::NoiseProfile::load(&args.profile)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    ickon_fusion::estimator::EstimatorConfig::default_for(&args.estimator)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    args.filter_options()
        .check_for(&args.estimator)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    if args.routers != 1 && args.mesh != Mesh::Router {
        return Err(CommandError::bad_input(format!(
            "--routers {} needs --mesh router: a full mesh of peers has no router",
            args.routers
        )));
    }
    crate::zones::split(&site, &[], args.routers)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    if args.receivers == SimReceivers::Marvelmind
        && let Some(why) = crate::device_plan::marvelmind_refusal(&site)
    {
        return Err(CommandError::bad_input(why));
    }
    check_grouping(args)?;
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 86_400.0) {
        return Err(CommandError::bad_input(
            "--duration must be between 0 and 86400 seconds",
        ));
    }
    // Read here as the central unit will: a bad token file is the user's
    // input, refused before a node starts, not a central dying at start-up.
    if let Some(path) = &args.http_token_file {
        ickon_central::http::read_token(path)
            .map_err(|e| CommandError::bad_input(format!("--http-token-file: {e}")))?;
    }
    if let Some(plan) = &args.faults {
        ickon_sim::tx_faults::TransmitterFault::parse_plan(plan, &site)
            .map_err(|e| CommandError::bad_input(e.to_string()))?;
        match faults::parse_plan(plan) {
            Err(e) => {
                return Err(CommandError::bad_input(format!("{e}")));
            }
            Ok(plan) => {
                if let Some(f) = plan.iter().find(|f| {
                    matches!(f.action, faults::FaultAction::ClockStep(_))
                        && !faults::keeps_a_clock(&f.node)
                }) {
                    return Err(CommandError::bad_input(format!(
                        "--faults: {:?}: only a cell or a central unit keeps a clock to step",
                        f.text
                    )));
                }
                let nodes: Vec<String> = std::iter::once("central".to_string())
                    .chain(args.standby.then(|| "central standby".to_string()))
                    .chain(["world".to_string()])
                    .chain(router_names(&site, args.routers))
                    .chain(site.cells.iter().map(|c| format!("cell {}", c.id)))
                    .chain(
                        site.robots
                            .iter()
                            .take(args.robots)
                            .map(|r| format!("msu {}", r.id)),
                    )
                    .collect();
                if let Some(f) = plan.iter().find(|f| !nodes.contains(&f.node)) {
                    return Err(CommandError::bad_input(format!(
                        "--faults: {:?}: this run has no node {}",
                        f.text, f.node
                    )));
                }
            }
        }
    }
    Ok((site, profile))
}
