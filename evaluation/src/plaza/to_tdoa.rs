//! `ickon convert plaza --to tdoa DIR`: a CMU Plaza run written in the
//! arrival-time log format (`docs/log-format.md`), so that
//! `ickon replay tdoa` with its odometry can be held against
//! `ickon replay plaza` on the original.
//!
//! Each range is a `range_m` row in an epoch of its own (the ranges come
//! one at a time, each at its own time), with the replay's range sigma;
//! each odometry increment a body-frame `(dx, dy, dtheta)` row (the chord
//! of its arc); the truth with the body's heading (Plaza2's, the direction
//! of travel plus pi in the data, turned by pi), all on one clock. Every
//! stream is written in time order, as the run is read.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use clap::Args;
use ickon_runtime::CommandError;

use super::dataset::{PlazaRun, read_run};
use super::{RANGE_SIGMA_M, heading_reversed, run_dirs};
use crate::tdoa_log::convert::{Target, Writers};
use crate::tdoa_log::format::{FORMAT, OdometryRow};

/// Arguments of `ickon convert plaza`.
#[derive(Debug, Args)]
pub struct ConvertPlazaArgs {
    /// A Plaza run's directory (`gt.csv`, `odometry.csv`, `ranges.csv`,
    /// `beacons.csv`), or a directory of runs (each written into a
    /// directory of its name under DIR).
    #[arg(long)]
    pub data: PathBuf,
    /// The format to write.
    #[arg(long, value_enum)]
    pub to: Target,
    /// The directory to write `anchors.csv`, `measurements.csv`,
    /// `truth.csv` and `odometry.csv` into (created; existing files are
    /// refused).
    pub dir: PathBuf,
}

/// Converts one Plaza run or a directory of them.
pub fn run(args: &ConvertPlazaArgs) -> Result<(), CommandError> {
    let Target::Tdoa = args.to;
    let dirs = run_dirs(&args.data);
    if dirs.is_empty() {
        return Err(CommandError::bad_input(format!(
            "{}: no Plaza run (gt.csv, odometry.csv, ranges.csv, beacons.csv) found",
            args.data.display()
        )));
    }
    let single = dirs.len() == 1 && dirs[0] == args.data;
    for dir in &dirs {
        let data = read_run(dir).map_err(|e| CommandError::bad_input(e.to_string()))?;
        let out = match (single, dir.file_name()) {
            (false, Some(name)) => args.dir.join(name),
            _ => args.dir.clone(),
        };
        let skipped = write_run(&data, &out)?;
        eprintln!(
            "{}: {} ranges, {} increments written to {}{}",
            dir.display(),
            data.ranges.len() as u64 - skipped,
            data.odometry.len(),
            out.display(),
            if skipped > 0 {
                format!(" ({skipped} ranges to beacons not in beacons.csv left out)")
            } else {
                String::new()
            }
        );
    }
    Ok(())
}

/// Writes one run into `dir`; the number of ranges left out (their
/// beacon is not surveyed).
fn write_run(data: &PlazaRun, dir: &Path) -> Result<u64, CommandError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| CommandError::failure(format!("cannot create {}: {e}", dir.display())))?;
    let mut out = Writers::create_named(
        dir,
        &[
            "anchors.csv",
            "measurements.csv",
            "truth.csv",
            "odometry.csv",
        ],
    )?;
    out.line(0, "# written by ickon convert plaza from beacons.csv")?;
    out.line(0, "id,x_m,y_m,role")?;
    let mut beacons: Vec<_> = data.beacons.iter().collect();
    beacons.sort_by_key(|(id, _)| **id);
    for (id, p) in beacons {
        out.line(0, &format!("{id},{},{},transmitter", p[0], p[1]))?;
    }
    out.line(1, &format!("# format: {FORMAT}"))?;
    out.line(1, "# clock: plaza")?;
    out.line(1, "epoch,time_s,anchor,reference,kind,value,sigma")?;
    let mut skipped = 0;
    for (epoch, r) in data.ranges.iter().enumerate() {
        if !data.beacons.contains_key(&r.beacon) {
            skipped += 1;
            continue;
        }
        out.line(
            1,
            &format!(
                "{epoch},{},{},,range_m,{},{RANGE_SIGMA_M}",
                r.t_s, r.beacon, r.range_m
            ),
        )?;
    }
    let turn = if heading_reversed(&data.truth) == Some(true) {
        PI
    } else {
        0.0
    };
    out.line(2, "# clock: plaza")?;
    out.line(2, "time_s,x_m,y_m,heading_rad")?;
    for t in &data.truth {
        let heading = t.heading_rad + turn;
        out.line(
            2,
            &format!("{},{},{},{heading}", t.t_s, t.xy_m[0], t.xy_m[1]),
        )?;
    }
    out.line(3, "# clock: plaza")?;
    out.line(3, "time_s,dx_m,dy_m,dtheta_rad")?;
    for o in &data.odometry {
        let [dx, dy] = OdometryRow::increment_m(o.distance_m, o.dtheta_rad);
        out.line(3, &format!("{},{dx},{dy},{}", o.t_s, o.dtheta_rad))?;
    }
    out.flush()?;
    Ok(skipped)
}
