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
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    ickon_cell::node::main_with(Cli::parse().args)
}
