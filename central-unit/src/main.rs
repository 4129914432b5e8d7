//! `ickon-central`: the central unit of one site.
use clap::Parser;

/// The ICKON-rs central unit: site model, schedule, cycle triggers, master clock, health, admin.
#[derive(Parser)]
#[command(name = "ickon-central", version, about)]
struct Cli {
    #[command(flatten)]
    args: ickon_central::node::CentralArgs,
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    ickon_central::node::main_with(Cli::parse().args)
}
