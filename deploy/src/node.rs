//! `ickon node <role>`: one node of the mesh in this process. `ickon sim`
//! spawns itself with these subcommands so that `cargo run -p ickon -- sim`
//! needs no other binary; they run the same library code as the standalone
//! binaries meant for deployment.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Subcommand};
use ickon_fusion::estimator::{EstimatorConfig, WheelGeometry};
use ickon_sim::profile::NoiseProfile;

use crate::cli::{EXIT_BAD_INPUT, EXIT_FAILURE};

/// Connection flags shared by every node (the same as Zenoh's own examples).
#[derive(Debug, Clone, Args)]
pub struct MeshArgs {
    /// A Zenoh configuration file (JSON5); the flags below override it.
    #[arg(short = 'c', long = "config")]
    pub config: Option<PathBuf>,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447`.
    #[arg(short = 'e', long = "connect")]
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:0`.
    #[arg(short = 'l', long = "listen")]
    pub listen: Vec<String>,
    /// Turn multicast scouting off (isolated meshes, tests).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// Site name, the `<site>` of every key.
    #[arg(long, default_value = "lab")]
    pub site_name: String,
    /// Site file (accepted for symmetry; the world and MSU agents take the
    /// site from the central unit).
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Stop when the parent process (the launcher) goes away.
    #[arg(long)]
    pub exit_with_parent: bool,
}

/// The roles a node can play.
#[derive(Debug, Subcommand)]
pub enum Role {
    /// The simulated world.
    World(WorldArgs),
    /// One robot's MSU agent.
    Msu(MsuArgs),
}

/// Arguments of `ickon node world`.
#[derive(Debug, Args)]
pub struct WorldArgs {
    /// Connection flags.
    #[command(flatten)]
    pub mesh: MeshArgs,
    /// Robots to simulate, comma-separated ids.
    #[arg(long, value_delimiter = ',', required = true)]
    pub robots: Vec<String>,
    /// Noise profile: ideal, paper or harsh.
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Arguments of `ickon node msu`.
#[derive(Debug, Args)]
pub struct MsuArgs {
    /// Connection flags.
    #[command(flatten)]
    pub mesh: MeshArgs,
    /// The robot this agent serves.
    #[arg(long)]
    pub robot: String,
    /// Estimator name.
    #[arg(long, default_value = "ickon-akf")]
    pub estimator: String,
    /// Estimator configuration as JSON (`{"name": "...", ...}`); overrides `--estimator`.
    #[arg(long)]
    pub estimator_json: Option<String>,
    /// One-sigma timing noise of one arrival, microseconds (the MSU's data sheet).
    #[arg(long, default_value_t = 50.0)]
    pub timing_sigma_us: f64,
    /// Wheel base of the robot, metres.
    #[arg(long, default_value_t = 0.33)]
    pub wheel_base_m: f64,
    /// Distance per encoder tick, metres.
    #[arg(long)]
    pub m_per_tick: Option<f64>,
}

fn zenoh_config(mesh: &MeshArgs) -> anyhow::Result<zenoh::Config> {
    let mut config = match &mesh.config {
        Some(path) => zenoh::Config::from_file(path)
            .map_err(|e| anyhow::anyhow!("Zenoh config {}: {e}", path.display()))?,
        None => zenoh::Config::default(),
    };
    let mut set = |k: &str, v: String| {
        config
            .insert_json5(k, &v)
            .map_err(|e| anyhow::anyhow!("Zenoh config {k}: {e}"))
    };
    if !mesh.connect.is_empty() {
        set("connect/endpoints", serde_json::to_string(&mesh.connect)?)?;
    }
    if !mesh.listen.is_empty() {
        set("listen/endpoints", serde_json::to_string(&mesh.listen)?)?;
    }
    if mesh.no_multicast_scouting {
        set("scouting/multicast/enabled", "false".into())?;
    }
    Ok(config)
}

/// Completes on Ctrl-C, SIGTERM, or (with `exit_with_parent`) when the parent goes away.
async fn shutdown_signal(exit_with_parent: bool) {
    let parent = std::os::unix::process::parent_id();
    let orphaned = async move {
        loop {
            tokio::time::sleep(std::time::Duration::from_millis(250)).await;
            if exit_with_parent && std::os::unix::process::parent_id() != parent {
                return;
            }
        }
    };
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
        _ = orphaned => {}
    }
}

/// Runs one node and returns the exit code.
pub fn run(role: Role) -> ExitCode {
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::from(EXIT_FAILURE);
        }
    };
    match runtime.block_on(run_role(role)) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(EXIT_FAILURE)
        }
    }
}

async fn run_role(role: Role) -> anyhow::Result<ExitCode> {
    match role {
        Role::World(args) => {
            let profile = match NoiseProfile::by_name(&args.profile) {
                Ok(p) => p,
                Err(e) => {
                    eprintln!("error: {e}");
                    return Ok(ExitCode::from(EXIT_BAD_INPUT));
                }
            };
            let session = zenoh::open(zenoh_config(&args.mesh)?)
                .await
                .map_err(|e| anyhow::anyhow!("cannot open the Zenoh session: {e}"))?;
            let settings = ickon_sim::node::WorldSettings {
                site_name: args.mesh.site_name.clone(),
                robots: args.robots,
                profile,
                seed: args.seed,
            };
            let result = ickon_sim::node::run(
                &session,
                settings,
                shutdown_signal(args.mesh.exit_with_parent),
            )
            .await;
            let _ = session.close().await;
            result.map(|_| ExitCode::SUCCESS)
        }
        Role::Msu(args) => {
            let estimator = match &args.estimator_json {
                Some(json) => match serde_json::from_str::<EstimatorConfig>(json) {
                    Ok(c) => Some(c),
                    Err(e) => {
                        eprintln!("error: --estimator-json: {e}");
                        return Ok(ExitCode::from(EXIT_BAD_INPUT));
                    }
                },
                None => {
                    if let Err(e) = EstimatorConfig::default_for(&args.estimator) {
                        eprintln!("error: {e}");
                        return Ok(ExitCode::from(EXIT_BAD_INPUT));
                    }
                    None
                }
            };
            let drive = ickon_sim::robot::DriveSpec::default();
            let m_per_tick = args.m_per_tick.unwrap_or_else(|| drive.m_per_tick());
            let session = zenoh::open(zenoh_config(&args.mesh)?)
                .await
                .map_err(|e| anyhow::anyhow!("cannot open the Zenoh session: {e}"))?;
            let settings = ickon_msu::node::MsuSettings {
                site_name: args.mesh.site_name.clone(),
                robot: args.robot,
                estimator,
                estimator_name: args.estimator,
                timing_sigma_s: args.timing_sigma_us * 1e-6,
                wheels: WheelGeometry {
                    wheel_base_m: args.wheel_base_m,
                    left_m_per_tick: m_per_tick,
                    right_m_per_tick: m_per_tick,
                },
            };
            let result = ickon_msu::node::run(
                &session,
                settings,
                shutdown_signal(args.mesh.exit_with_parent),
            )
            .await;
            let _ = session.close().await;
            result.map(|_| ExitCode::SUCCESS)
        }
    }
}
