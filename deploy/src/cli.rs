//! Command-line interface of `ickon` and the dispatch to each subcommand.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::{admin, bench, eval, msu_cmd, node, record, replay, router, secure, sim, site_cmd};

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
        command: bench::BenchCommand,
    },
    /// Run a Zenoh router: the hub of a floor, every node its client.
    Router(router::RouterArgs),
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
        /// A built-in site (`lab`, `warehouse`) or a site file (TOML); the
        /// built-in `lab` when omitted.
        file: Option<PathBuf>,
        /// The same as the positional argument, spelled as elsewhere.
        #[arg(long = "site", conflicts_with = "file")]
        site: Option<PathBuf>,
    },
    /// Write a secured site: the router's configuration with access control
    /// (default deny) and one credential per node, all files 0600.
    Secure(secure::SecureArgs),
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

/// Runs the parsed command line and returns the process exit code.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command {
        Command::Site {
            action: SiteAction::Check { file, site },
        } => site_cmd::check(file.or(site).as_deref()),
        Command::Site {
            action: SiteAction::Secure(args),
        } => secure::run(args),
        Command::Msu {
            action: MsuAction::Check { file },
        } => msu_cmd::check(&file),
        Command::Record(args) => record::run(args),
        Command::Replay { source } => replay::run(source),
        Command::Sim(args) => sim::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Node { role } => node::run(role),
        Command::Router(args) => router::run(args),
        Command::Bench { command } => bench::run(command),
        Command::Admin { command } => admin::run(command),
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// clap checks a command line's definition only when it is parsed: a
    /// flag defined twice (a node's own `--config` beside the Zenoh one)
    /// would panic in the first process that starts that node.
    #[test]
    fn every_subcommand_is_well_formed() {
        super::Cli::command().debug_assert();
    }
}
