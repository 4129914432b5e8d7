//! `ickon replay tdoa` and `ickon convert ... --to tdoa`: anyone's arrival
//! times in one documented CSV format (`docs/log-format.md`).
//!
//! - [`format`]: what the files hold and their column names;
//! - [`read`]: a file streamed line by line, every problem named by file,
//!   line and column; [`rows`]: the anchors, measurement and truth rows;
//! - [`epochs`], [`epoch`]: rows grouped into epochs, turned into range
//!   differences for the filters and into the per-epoch least-squares fix
//!   of the MSU's solver (the baseline);
//! - [`motion_rows`], [`motion`]: the optional odometry and IMU files and
//!   the filters that take them (the ground filter, dead reckoning, the
//!   IMU filter);
//! - [`offset`]: the truth clock's offset, when it runs on another clock;
//! - [`replay`]: the estimators of `ickon replay util` over the epochs,
//!   scored and printed by the same code;
//! - [`baseline`]: the `ls` of a run held in memory, for a recording's
//!   replay to print what its conversion's replay prints;
//! - [`convert`]: a UTIL flight written in the format; [`export`]: a
//!   simulated run or a recording's robot written in it;
//! - [`synth`]: a microphone network hearing a mobile emitter, generated
//!   (the example set and the measured expectations of the docs).

pub mod baseline;
pub mod convert;
mod cv_fix;
mod epoch;
mod epochs;
pub mod export;
pub mod format;
mod motion;
mod motion_rows;
mod offset;
pub mod read;
mod replay;
pub mod rows;
pub mod synth;
#[cfg(test)]
mod tests;

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use ickon_runtime::CommandError;

use crate::util::{plot, print_table};

pub use convert::{ConvertUtilArgs, run as run_convert_util};

/// Arguments of `ickon replay tdoa`.
#[derive(Debug, Args)]
pub struct TdoaArgs {
    /// The anchors file (`id,x_m,y_m[,z_m],role`).
    #[arg(long)]
    pub anchors: PathBuf,
    /// The measurements file (`epoch,time_s,anchor,reference,kind,value[,sigma]`).
    #[arg(long)]
    pub measurements: PathBuf,
    /// The truth file (`time_s,x_m,y_m[,z_m][,heading_rad]`); without it
    /// the estimates are counted, not scored.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// The odometry file (`time_s,dx_m,dy_m,dtheta_rad`, body-frame
    /// increments; 2D): adds the ground robot's filter `tdoa-ekf` and
    /// dead reckoning `odometry`.
    #[arg(long)]
    pub odometry: Option<PathBuf>,
    /// The IMU file (`time_s,ax_m_s2,ay_m_s2,az_m_s2,gx_rad_s,gy_rad_s,gz_rad_s`,
    /// body frame; 3D): adds the IMU filter `imu-eskf`.
    #[arg(long)]
    pub imu: Option<PathBuf>,
    /// Odometry error, a fraction of each increment (distance and turn),
    /// for `tdoa-ekf` with `--odometry`.
    #[arg(long, default_value_t = crate::plaza::ODOMETRY_FRACTION)]
    pub odometry_fraction: f64,
    /// Yaw of the mobile when first placed, degrees from +x (`imu-eskf`).
    #[arg(long, default_value_t = 0.0)]
    pub initial_yaw_deg: f64,
    /// Where the point the measurements concern (the antenna, the
    /// emitter) sits in the IMU's body frame, `x,y,z` metres (`imu-eskf`;
    /// default: at the IMU).
    #[arg(long, value_parser = parse_lever_arm, default_value = "0,0,0", allow_hyphen_values = true)]
    pub imu_lever_arm_m: LeverArm,
    /// Longest gap of the truth interpolated across, seconds (0.1 suits
    /// a motion capture; a slower truth needs more).
    #[arg(long, default_value_t = crate::util::score::MAX_TRUTH_GAP_S)]
    pub truth_max_gap_s: f64,
    /// The dimension the log must have (2 or 3): a check, the anchors
    /// file decides (3D when it has `z_m`).
    #[arg(long, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub dim: Option<u8>,
    /// The estimators, comma-separated, or `all`: in 3D `tdoa-ekf`,
    /// `cv-ekf`, `window-gn`, `cv-fix`, `ls` (and `imu-eskf` with
    /// `--imu`); in 2D `cv-fix`, `ls` (and `tdoa-ekf`, `odometry` with
    /// `--odometry`) (`ls`: the per-epoch least-squares fix, the baseline).
    #[arg(long, default_value = "all")]
    pub estimator: String,
    /// Propagation speed, m/s (overrides the file's
    /// `# propagation_speed_m_s:` line; needed for `toa_s`, `tdoa_s`).
    #[arg(long)]
    pub speed_m_s: Option<f64>,
    /// Standard deviation of a row without its own `sigma`, metres
    /// (default: the UWB flights' measurement RMS, rounded up).
    #[arg(long, default_value_t = 0.1)]
    pub sigma_m: f64,
    /// Acceleration density of the constant-velocity filters (`tdoa-ekf`,
    /// `cv-ekf`, `cv-fix`), m^2/s^3: how fast the mobile changes its
    /// velocity (1: about 1 m/s within a second, a flying tag).
    #[arg(long, default_value_t = cv_fix::ACCEL_PSD_M2_S3)]
    pub accel_psd_m2_s3: f64,
    /// The mobile's body shadow for `tdoa-ekf`, metres (0: no body model).
    #[arg(long, default_value_t = 0.0)]
    pub shadow_m: f64,
    /// Print one JSON document on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// A body-frame offset, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeverArm(pub [f64; 3]);

fn parse_lever_arm(s: &str) -> Result<LeverArm, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z]
            if v.iter()
                .all(|c| c.is_finite() && c.abs() <= MAX_LEVER_ARM_M) =>
        {
            Ok(LeverArm([x, y, z]))
        }
        [_, _, _] => Err(format!(
            "each component must be a number of metres within +-{MAX_LEVER_ARM_M}"
        )),
        _ => Err("three numbers `x,y,z` in metres".into()),
    }
}

/// Longest lever arm taken, metres: a body is not larger (a value in
/// millimetres is refused rather than taken).
const MAX_LEVER_ARM_M: f64 = 10.0;

/// Replays a log of the format and prints the tables.
pub fn run(args: &TdoaArgs) -> Result<(), CommandError> {
    if args.speed_m_s.is_some_and(|c| !(c.is_finite() && c > 0.0)) {
        return Err(CommandError::bad_input("--speed-m-s must be positive"));
    }
    if !(args.sigma_m.is_finite() && args.sigma_m > 0.0) {
        return Err(CommandError::bad_input("--sigma-m must be positive"));
    }
    if !(args.accel_psd_m2_s3.is_finite() && args.accel_psd_m2_s3 > 0.0) {
        return Err(CommandError::bad_input(
            "--accel-psd-m2-s3 must be positive",
        ));
    }
    if !(args.odometry_fraction.is_finite() && args.odometry_fraction > 0.0) {
        return Err(CommandError::bad_input(
            "--odometry-fraction must be positive",
        ));
    }
    if !(args.truth_max_gap_s.is_finite() && args.truth_max_gap_s > 0.0) {
        return Err(CommandError::bad_input(
            "--truth-max-gap-s must be positive",
        ));
    }
    if !args.initial_yaw_deg.is_finite() {
        return Err(CommandError::bad_input(
            "--initial-yaw-deg must be a number",
        ));
    }
    if !(args.shadow_m.is_finite() && args.shadow_m >= 0.0) {
        return Err(CommandError::bad_input("--shadow-m must not be negative"));
    }
    let started = Instant::now();
    let out = replay::replay(args).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let wall = started.elapsed();
    let file = args.measurements.display().to_string();
    let r = &out.replayed;
    if args.json {
        let doc = serde_json::json!({
            "file": file,
            "anchors": args.anchors.display().to_string(),
            "truth": args.truth.as_ref().map(|p| p.display().to_string()),
            "dim": out.dim,
            "role": out.role,
            "rows": out.rows,
            "epochs": out.epochs,
            "solved_epochs": out.solved,
            "unsolved_epochs": out.unsolved,
            "truth_offset": out.truth_offset,
            "start_from_truth": out.start_from_truth,
            "left_out": out.left_out.iter().map(|(n, why)| serde_json::json!({"name": n, "reason": why})).collect::<Vec<_>>(),
            "volume": r.volume,
            "measurements": r.measurements,
            "duration_s": r.duration_s,
            "wall_s": wall.as_secs_f64(),
            "estimators": r.reports,
        });
        println!("{doc}");
    } else {
        print_summary(&out);
        if out.has_truth {
            print_table(&file, r, out.dim, wall);
            let medians: Vec<String> = r
                .reports
                .iter()
                .filter_map(|e| Some(format!("{} {:.4}", e.name, e.summary.median_3d_m?)))
                .collect();
            println!("median error, m: {}", medians.join(", "));
        } else {
            for e in &r.reports {
                println!(
                    "{:<10} {} estimates (no truth to score them)",
                    e.name, e.estimates
                );
            }
        }
    }
    if let Some(dir) = &args.plot {
        let stem = args
            .measurements
            .file_stem()
            .map_or("replay".into(), |s| s.to_string_lossy());
        let series: Vec<&[crate::util::score::SeriesPoint]> = r
            .tracks
            .iter()
            .map(|t| t.series.as_deref().unwrap_or(&[]))
            .collect();
        let names: Vec<&str> = r.reports.iter().map(|r| r.name).collect();
        plot::write_all(dir, &stem, &names, &series).map_err(|e| {
            CommandError::failure(format!("cannot write plots to {}: {e}", dir.display()))
        })?;
    }
    Ok(())
}

fn print_summary(out: &replay::TdoaReplayed) {
    let u = &out.unsolved;
    println!(
        "{}D, {}s fixed: {} rows in {} epochs; least squares fixed {} epochs, not {} (too few arrivals {}, no fix {}, invalid {}, 2D with several references {})",
        out.dim,
        out.role.as_str(),
        out.rows,
        out.epochs,
        out.solved,
        u.total(),
        u.too_few_arrivals,
        u.no_fix,
        u.invalid,
        u.mixed_references_2d,
    );
    for (name, why) in &out.left_out {
        println!("{name} left out: {why}");
    }
    if out.start_from_truth {
        println!(
            "odometry filters: started at the truth's first pose (position +-{} m, heading +-{} deg)",
            crate::plaza::START_SIGMA_XY_M,
            crate::plaza::START_SIGMA_THETA_DEG
        );
    }
    if let Some(o) = &out.truth_offset {
        println!(
            "truth clock: measurements minus truth = {:+.4} s (median fix error {:.3} m over {} fixes)",
            o.offset_s, o.median_error_m, o.fixes
        );
    }
}
