//! `ickon`: the launcher of ICKON-rs.
//!
//! Thin by design: parse the command line, set up logging, hand over to the
//! library crate of the subcommand, and turn its result into an exit code.
//! A library with a one-line binary around it, so that the end-to-end tests
//! (the `ickon-tests` crate in `tests/`) build the same program as a target
//! of their own (`docs/testing.md`).

pub mod cli;
mod closed_stdout;
mod node;

use std::process::ExitCode;

use clap::Parser;

/// The whole program: the command line of this process, run.
pub fn main() -> ExitCode {
    closed_stdout::exit_quietly_when_stdout_closes();
    // Before any thread starts, so that every thread inherits the set.
    if let Err(e) = ickon_runtime::cpus::pin_from_env() {
        eprintln!("error: {}: {e}", ickon_runtime::cpus::CPUS_ENV);
        return ExitCode::from(2);
    }
    let cli = cli::Cli::parse();
    init_tracing();
    cli::run(cli)
}

/// Logs go to stderr so that `--json` output on stdout stays clean;
/// `RUST_LOG` overrides the default level. Zenoh's own warnings (scouting
/// delays at start-up, late data at shutdown) are routine in a mesh that
/// starts and ends at once, so only its errors are shown by default, except
/// its TLS link's warnings: a router's say why it refused a handshake (no
/// client certificate, another CA's, an expired one), at most ten a second
/// (Zenoh pauses its accept loop after each). The
/// Foxglove SDK's lines (every client's coming and going, every bad message
/// a client sends) are unbounded, so they are off unless asked for. Colour
/// codes only on a terminal.
fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
        tracing_subscriber::EnvFilter::new(
            "warn,zenoh=error,zenoh_transport=error,zenoh_link_tls=warn,foxglove=off",
        )
    });
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(ickon_runtime::stderr_is_terminal())
        .init();
}
