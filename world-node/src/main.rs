//! `ickon-world`: the simulated world in real time.
use clap::Parser;

/// The ICKON-rs simulated world: robots, sound and sensors in real time, for a simulation over Zenoh.
#[derive(Parser)]
#[command(name = "ickon-world", version, about)]
struct Cli {
    #[command(flatten)]
    args: ickon_world::node::WorldArgs,
}

fn main() -> std::process::ExitCode {
    ickon_runtime::init_tracing("info");
    ickon_world::node::main_with(Cli::parse().args)
}
