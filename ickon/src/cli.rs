//! Command-line interface of `ickon` and the dispatch to each subcommand.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use ickon_evaluation::{
    ConvertPlazaArgs, ConvertUtilArgs, EvalArgs, PlazaArgs, TdoaArgs, UtilArgs,
};
use ickon_launcher::{BenchCommand, SimArgs};
use ickon_operator::{AdminCommand, DeviceCheckArgs, RouterArgs, SecureArgs};
use ickon_recording::{ConvertMcapArgs, McapArgs, RecordArgs};
use ickon_runtime::CommandError;
use ickon_world::emulate::EmulateCommand;

use crate::node;

/// ICKON-rs: ultrasonic indoor positioning for fleets of mobile robots.
#[derive(Debug, Parser)]
#[command(name = "ickon", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands of `ickon`.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the multi-robot simulation as separate processes over a loopback Zenoh mesh.
    Sim(SimArgs),
    /// Evaluate estimators on the simulated world in virtual time (the ICKON paper's tables).
    Eval(EvalArgs),
    /// Query and control a running site through the central unit.
    Admin {
        /// What to ask or tell the central unit.
        #[command(subcommand)]
        command: AdminCommand,
    },
    /// Work with site files.
    Site {
        /// What to do with the site file.
        #[command(subcommand)]
        action: SiteAction,
    },
    /// Work with MSU agent configuration files.
    Msu {
        /// What to do with the configuration file.
        #[command(subcommand)]
        action: MsuAction,
    },
    /// Benchmarks of the whole system.
    Bench {
        /// Which benchmark.
        #[command(subcommand)]
        command: BenchCommand,
    },
    /// Run a Zenoh router: the hub of a floor, every node its client.
    Router(RouterArgs),
    /// Work with boards of the ICKON device protocol (transmitter and receiver boards).
    Device {
        /// What to do with the board.
        #[command(subcommand)]
        action: DeviceAction,
    },
    /// Emulate a board of the ICKON device protocol, or a Marvelmind hedgehog,
    /// on a pseudo-terminal or a TCP port.
    Emulate {
        /// Which board.
        #[command(subcommand)]
        board: EmulateCommand,
    },
    /// Run one node of the mesh (used by `ickon sim`; the standalone binaries
    /// do the same for deployment).
    #[command(hide = true)]
    Node {
        /// The role of the node.
        #[command(subcommand)]
        role: node::Role,
    },
    /// Record every message of a running site into an MCAP file (Foxglove, `ros2 bag`).
    Record(RecordArgs),
    /// Replay recorded measurements through the positioning stack.
    Replay {
        /// Which recorded data set.
        #[command(subcommand)]
        source: ReplaySource,
    },
    /// Write a recorded data set in another format.
    Convert {
        /// Which recorded data set.
        #[command(subcommand)]
        source: ConvertSource,
    },
}

/// Data sets `ickon convert` reads.
#[derive(Debug, Subcommand)]
pub enum ConvertSource {
    /// A UTIL UWB TDOA flight, written as an arrival-time log
    /// (`--to tdoa`, docs/log-format.md).
    Util(ConvertUtilArgs),
    /// A CMU Plaza run (ranges, wheel odometry, truth), written as an
    /// arrival-time log with its odometry (`--to tdoa`, docs/log-format.md).
    Plaza(ConvertPlazaArgs),
    /// A recording of `ickon record` or `ickon sim --record`, each robot
    /// written as an arrival-time log with its truth and odometry
    /// (`--to tdoa`, docs/log-format.md).
    Mcap(ConvertMcapArgs),
}

/// Actions on site files.
#[derive(Debug, Subcommand)]
pub enum SiteAction {
    /// Validate a site file and print a summary; exit code 2 when it is invalid.
    Check {
        /// A built-in site (`lab`, `warehouse`, `hall`) or a site file (TOML); the
        /// built-in `lab` when omitted.
        file: Option<PathBuf>,
        /// The same as the positional argument, spelled as elsewhere.
        #[arg(long = "site", conflicts_with = "file")]
        site: Option<PathBuf>,
    },
    /// Write a secured site: the router's configuration with access control
    /// (default deny) and one credential per node, all files 0600.
    Secure(SecureArgs),
}

/// Recorded data sets `ickon replay` understands.
#[derive(Debug, Subcommand)]
pub enum ReplaySource {
    /// UTIL UWB TDOA flights with motion-capture truth.
    Util(UtilArgs),
    /// CMU Plaza runs: a wheeled robot's odometry and radio ranges, with truth.
    Plaza(PlazaArgs),
    /// An MCAP recording of `ickon record` or `ickon sim --record`, through
    /// the MSU cores again (scored against its truth).
    Mcap(McapArgs),
    /// An arrival-time log of any system (docs/log-format.md): anchors,
    /// measurements, optionally truth; the estimators beside the per-epoch
    /// least-squares fix.
    Tdoa(TdoaArgs),
}

/// Actions on device boards.
#[derive(Debug, Subcommand)]
pub enum DeviceAction {
    /// Try a board as a cell or an MSU would (handshake, clock exchanges,
    /// bursts or arrivals) and print what it did; exit code 1 when it did
    /// not do everything asked.
    Check(DeviceCheckArgs),
}

/// Actions on MSU configuration files.
#[derive(Debug, Subcommand)]
pub enum MsuAction {
    /// Validate an MSU configuration file (`ickon-msu --config FILE`) and
    /// print what it sets; exit code 2 when it is invalid.
    Check {
        /// The configuration file (TOML; `deploy/msu.toml` is an example).
        file: PathBuf,
    },
}

/// Runs the parsed command line and returns the process exit code: the
/// only place where an outcome becomes one (a node's own, for `ickon node`).
pub fn run(cli: Cli) -> ExitCode {
    let outcome = match cli.command {
        Command::Node { role } => return node::run(role),
        Command::Site {
            action: SiteAction::Check { file, site },
        } => ickon_operator::check_site(file.or(site).as_deref()),
        Command::Site {
            action: SiteAction::Secure(args),
        } => ickon_operator::run_secure(args),
        Command::Msu {
            action: MsuAction::Check { file },
        } => ickon_operator::check_msu_config(&file),
        Command::Record(args) => ickon_recording::run_record(args),
        Command::Replay { source } => match source {
            ReplaySource::Util(args) => ickon_evaluation::run_util(&args),
            ReplaySource::Plaza(args) => ickon_evaluation::run_plaza(&args),
            ReplaySource::Mcap(args) => ickon_recording::run_replay(&args),
            ReplaySource::Tdoa(args) => ickon_evaluation::run_tdoa(&args),
        },
        Command::Convert { source } => match source {
            ConvertSource::Util(args) => ickon_evaluation::run_convert_util(&args),
            ConvertSource::Plaza(args) => ickon_evaluation::run_convert_plaza(&args),
            ConvertSource::Mcap(args) => ickon_recording::run_convert(&args),
        },
        Command::Sim(args) => ickon_launcher::run_sim(args),
        Command::Eval(args) => ickon_evaluation::run_eval(args),
        Command::Router(args) => ickon_operator::run_router(args),
        Command::Device {
            action: DeviceAction::Check(args),
        } => ickon_operator::check_device(&args),
        Command::Emulate { board } => ickon_world::emulate::run_emulate(board),
        Command::Bench { command } => ickon_launcher::run_bench(command),
        Command::Admin { command } => ickon_operator::run_admin(command),
    };
    exit_code(outcome)
}

/// Says why a command did not succeed, on stderr, and gives its exit code.
fn exit_code(outcome: Result<(), CommandError>) -> ExitCode {
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
