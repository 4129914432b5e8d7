//! `ickon-msu`: the MSU agent of one robot.
use clap::Parser;

/// The ICKON-rs MSU agent: arrivals to fixes, fused with odometry and gyro into the pose of one robot.
#[derive(Parser)]
#[command(name = "ickon-msu", version, about)]
struct Cli {
    #[command(flatten)]
    args: ickon_msu::node::MsuArgs,
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    ickon_msu::node::main_with(Cli::parse().args)
}
