//! `ickon-world`: the simulated world in real time.
use clap::Parser;

/// The ICKON-rs simulated world: robots, sound and sensors in real time, for a simulation over Zenoh.
#[derive(Parser)]
#[command(name = "ickon-world", version, about)]
struct Cli {
    #[command(flatten)]
    args: ickon_sim::node::WorldArgs,
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    ickon_sim::node::main_with(Cli::parse().args)
}
