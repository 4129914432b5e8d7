//! `ickon replay`: recorded measurements through the positioning stack.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Subcommand};

/// Recorded data sets `ickon replay` understands.
#[derive(Debug, Subcommand)]
pub enum ReplaySource {
    /// UTIL UWB TDOA flights with motion-capture truth.
    Util(UtilArgs),
}

/// Arguments of `ickon replay util`.
#[derive(Debug, Args)]
pub struct UtilArgs {
    /// The measurement CSV (`idA,idB,tdoa_meas,t_tdoa,pose_x,pose_y,pose_z,t_pose`).
    #[arg(long)]
    pub data: PathBuf,
    /// The anchor CSV (`constellation,anchor_id,x,y,z`).
    #[arg(long)]
    pub anchors: PathBuf,
    /// Which anchor constellation the flight used.
    #[arg(long)]
    pub constellation: u32,
    /// Print one JSON document on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// Runs a replay and returns the exit code.
pub fn run(source: ReplaySource) -> ExitCode {
    match source {
        ReplaySource::Util(_) => {
            eprintln!("error: replay is not available in this build yet");
            ExitCode::from(crate::cli::EXIT_FAILURE)
        }
    }
}
