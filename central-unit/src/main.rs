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
    // The Foxglove SDK logs every client's coming and going and every bad
    // message a client sends, unbounded: off unless RUST_LOG asks for it.
    ickon_runtime::init_tracing("info,foxglove=off");
    ickon_central::node::main_with(Cli::parse().args)
}
