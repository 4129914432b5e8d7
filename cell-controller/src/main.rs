//! `ickon-cell`: one cell controller.
use clap::Parser;

/// The ICKON-rs cell controller: clock sync with the central unit and the burst timer of one cell.
#[derive(Parser)]
#[command(name = "ickon-cell", version, about)]
struct Cli {
    #[command(flatten)]
    args: ickon_cell::node::CellArgs,
}

fn main() -> std::process::ExitCode {
    ickon_runtime::init_tracing("info");
    ickon_cell::node::main_with(Cli::parse().args)
}
