//! `ickon convert mcap FILE --to tdoa DIR`: each robot of a recording
//! written in the arrival-time log format (docs/log-format.md), as
//! `ickon eval --export-tdoa` writes a simulated run, so that
//! `ickon replay tdoa` can be held against `ickon replay mcap`.
//!
//! One directory per robot, `DIR/ROBOT/`: the recorded site's
//! transmitters, each cycle's arrivals as `toa_s` rows (arrival minus the
//! transmitter's offset in the schedule last received before the cycle:
//! the one the MSU solved it with), the recorded truth on the robot's
//! clock and the wheel odometry as body-frame increments.

use std::path::{Path, PathBuf};

use clap::Args;
use ickon_evaluation::tdoa_log::convert::Target;
use ickon_runtime::CommandError;

use crate::replay::feed::{self, recording_of};
use crate::replay::{read, recorded_site, recorded_timing_sigma_s};

/// Arguments of `ickon convert mcap`.
#[derive(Debug, Args)]
pub struct ConvertMcapArgs {
    /// The recording (`ickon record`, `ickon sim --record`).
    pub file: PathBuf,
    /// Site file, for a recording that holds no site; the built-in site
    /// otherwise.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// The format to write.
    #[arg(long, value_enum)]
    pub to: Target,
    /// The directory to write one directory per robot into (`anchors.csv`,
    /// `measurements.csv`, `truth.csv`, `odometry.csv`; existing files are
    /// refused).
    pub dir: PathBuf,
}

/// Converts a recording.
pub fn run(args: &ConvertMcapArgs) -> Result<(), CommandError> {
    let Target::Tdoa = args.to;
    let rec = read::read(&args.file).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let (streams, mut problems) = feed::streams(&rec);
    problems.extend(rec.problems.iter().cloned());
    if streams.is_empty() {
        return Err(CommandError::bad_input(format!(
            "{}: nothing to convert: it holds no robot's arrivals",
            args.file.display()
        )));
    }
    let site = recorded_site(&rec, &args.file, args.site.as_deref(), &mut problems)
        .map_err(CommandError::bad_input)?;
    for p in &problems {
        eprintln!("warning: {}: {}", args.file.display(), p.0);
    }
    for stream in &streams {
        let (run, unscheduled) = recording_of(stream, &site);
        if run.cycles.is_empty() {
            eprintln!(
                "robot {}: no cycle with a schedule before it: nothing written",
                stream.id
            );
            continue;
        }
        if unscheduled > 0 {
            eprintln!(
                "robot {}: {unscheduled} cycle(s) before the first schedule left out",
                stream.id
            );
        }
        let sigma_s = recorded_timing_sigma_s(&rec, &stream.id);
        let dir = args.dir.join(&stream.id);
        let source = format!("ickon convert mcap from {}", file_name(&args.file));
        ickon_evaluation::tdoa_log::export::write_run(&dir, &source, &site, sigma_s, &run)?;
    }
    Ok(())
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    )
}
