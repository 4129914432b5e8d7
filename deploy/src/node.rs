//! `ickon node <role>`: one node of the mesh in this process. `ickon sim`
//! spawns itself with these subcommands so that `cargo run -p ickon -- sim`
//! needs no other binary; they run the same library code as the standalone
//! binaries meant for deployment.

use std::process::ExitCode;

use clap::{Args, Subcommand};
use ickon_fusion::estimator::{EstimatorConfig, WheelGeometry};
use ickon_runtime::NodeArgs;
use ickon_sim::profile::NoiseProfile;

use crate::cli::{EXIT_BAD_INPUT, EXIT_FAILURE};

/// The roles a node can play.
#[derive(Debug, Subcommand)]
pub enum Role {
    /// The central unit.
    Central(ickon_central::node::CentralArgs),
    /// One cell controller.
    Cell(ickon_cell::node::CellArgs),
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
    pub mesh: NodeArgs,
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
    pub mesh: NodeArgs,
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

/// Runs one node and returns the exit code.
pub fn run(role: Role) -> ExitCode {
    let role = match role {
        Role::Central(args) => return ickon_central::node::main_with(args),
        Role::Cell(args) => return ickon_cell::node::main_with(args),
        other => other,
    };
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
        Role::Central(_) | Role::Cell(_) => unreachable!("handled in run"),
        Role::World(args) => {
            let profile = match NoiseProfile::by_name(&args.profile) {
                Ok(p) => p,
                Err(e) => {
                    eprintln!("error: {e}");
                    return Ok(ExitCode::from(EXIT_BAD_INPUT));
                }
            };
            let session = args.mesh.open().await?;
            let settings = ickon_sim::node::WorldSettings {
                site_name: args.mesh.site_name.clone(),
                robots: args.robots,
                profile,
                seed: args.seed,
            };
            let result = ickon_sim::node::run(&session, settings, args.mesh.shutdown()).await;
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
            let session = args.mesh.open().await?;
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
            let result = ickon_msu::node::run(&session, settings, args.mesh.shutdown()).await;
            let _ = session.close().await;
            result.map(|_| ExitCode::SUCCESS)
        }
    }
}
