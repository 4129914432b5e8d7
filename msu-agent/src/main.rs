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
    ickon_runtime::init_tracing("info");
    ickon_msu::node::main_with(Cli::parse().args)
}
