//! Command-line interface of `ickon` and the dispatch to each subcommand.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::{admin, eval, node, record, replay, sim, site_cmd};

/// Exit code for bad input: a broken site file, a malformed data file, bad flags.
pub const EXIT_BAD_INPUT: u8 = 2;
/// Exit code for a failure at run time (a child died, nobody answered).
pub const EXIT_FAILURE: u8 = 1;

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
    Sim(sim::SimArgs),
    /// Evaluate estimators on the simulated world in virtual time (seed 000 tables).
    Eval(eval::EvalArgs),
    /// Query and control a running site through the central unit.
    Admin {
        /// What to ask or tell the central unit.
        #[command(subcommand)]
        command: admin::AdminCommand,
    },
    /// Work with site files.
    Site {
        /// What to do with the site file.
        #[command(subcommand)]
        action: SiteAction,
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
    Record(record::RecordArgs),
    /// Replay recorded measurements through the positioning stack.
    Replay {
        /// Which recorded data set.
        #[command(subcommand)]
        source: replay::ReplaySource,
    },
}

/// Actions on site files.
#[derive(Debug, Subcommand)]
pub enum SiteAction {
    /// Validate a site file and print a summary; exit code 2 when it is invalid.
    Check {
        /// The site file (TOML); the built-in default site when omitted.
        file: Option<PathBuf>,
    },
}

/// Runs the parsed command line and returns the process exit code.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command {
        Command::Site {
            action: SiteAction::Check { file },
        } => site_cmd::check(file.as_deref()),
        Command::Record(args) => record::run(args),
        Command::Replay { source } => replay::run(source),
        Command::Sim(args) => sim::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Node { role } => node::run(role),
        Command::Admin { command } => admin::run(command),
    }
}
