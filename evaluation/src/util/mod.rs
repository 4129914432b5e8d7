//! `ickon replay util`: real UTIL flights through the 3D estimators.
//!
//! It reads a UTIL flight ([`dataset`]: its TDOA, truth
//! and, in the 27-column layout, IMU streams), feeds every TDOA in time
//! order to each estimator ([`estimators`]; the IMU samples up to its time
//! first, to `imu-eskf`), scores each published estimate against the truth
//! interpolated at its time with the antenna lever arm ([`score`], and the
//! attitude: [`attitude`]), and prints a table (or one JSON document) and
//! optionally PNG plots ([`plot`]). A bad file is reported with its name
//! and line and exit code 2.

pub(crate) mod attitude;
pub(crate) mod dataset;
mod error_stats;
pub(crate) mod estimators;
pub(crate) mod imu_input;
mod line_limit;
pub(crate) mod plot;
pub(crate) mod run;
pub(crate) mod score;
mod truth_screen;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Args;
use ickon_fusion::estimator::guard::{FlightVolume, GuardCounts};

use attitude::AttitudeSummary;
use estimators::Rejections;
use ickon_runtime::CommandError;
use run::{Replayed, replay};
use score::Summary;

/// Arguments of `ickon replay util`.
#[derive(Debug, Args)]
pub struct UtilArgs {
    /// The measurement CSV: the extracts' 8 columns
    /// (`idA,idB,tdoa_meas,t_tdoa,pose_x,pose_y,pose_z,t_pose`) or the
    /// 27-column layout with the IMU and the truth orientation.
    #[arg(long)]
    pub data: PathBuf,
    /// The anchor CSV (`constellation,anchor_id,x,y,z`, or
    /// `anchor_id,x_m,y_m,z_m,...` for one layout).
    #[arg(long)]
    pub anchors: PathBuf,
    /// Which anchor constellation the flight used (anchor files with a
    /// `constellation` column).
    #[arg(long)]
    pub constellation: Option<u32>,
    /// Also run the IMU error-state filter (`imu-eskf`); the file must
    /// have the IMU columns.
    #[arg(long)]
    pub imu: bool,
    /// The flight volume `xmin,ymin,zmin,xmax,ymax,zmax` in metres
    /// (default: the anchors' box grown by 0.5 m).
    #[arg(long, value_parser = parse_bounds)]
    pub bounds: Option<FlightVolume>,
    /// Yaw of the vehicle when first placed, degrees from +x (for
    /// `imu-eskf`; UTIL flights start facing +x).
    #[arg(long, default_value_t = 0.0)]
    pub initial_yaw_deg: f64,
    /// Override of `tdoa-ekf`'s acceleration density, m^2/s^3 (for
    /// parameter studies).
    #[arg(long)]
    pub accel_psd_m2_s3: Option<f64>,
    /// Override of the body shadow, metres (default: 0.0908, the
    /// antenna's height above the body centre; 0: no body model).
    #[arg(long)]
    pub shadow_m: Option<f64>,
    /// Estimate the body shadow online with this prior standard deviation
    /// around `--shadow-m`, metres (default 0: held).
    #[arg(long)]
    pub shadow_prior_sigma_m: Option<f64>,
    /// Override of the standard deviation of each anchor's excess path,
    /// metres, for `tdoa-ekf` and `imu-eskf` (default: 0.1, a reflection
    /// off the arena's floor and furniture; 0: no excess-path states).
    #[arg(long)]
    pub excess_sigma_m: Option<f64>,
    /// Print one JSON document on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Replay only the first this many seconds of measurements.
    #[arg(long)]
    pub max_seconds: Option<f64>,
    /// Keep one range difference in this many (the flight at a lower
    /// measurement rate; with `--thin-phase`, several nearly independent
    /// replays of one flight, to tell a filter's real gain from the luck
    /// of a few lost-and-re-placed moments).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub thin: u32,
    /// Which one of every `--thin` range differences is kept, from 0.
    #[arg(long, default_value_t = 0)]
    pub thin_phase: u32,
}

fn parse_bounds(s: &str) -> Result<FlightVolume, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    let [x0, y0, z0, x1, y1, z1] = v[..] else {
        return Err("expected six numbers: xmin,ymin,zmin,xmax,ymax,zmax".into());
    };
    FlightVolume::new([x0, y0, z0], [x1, y1, z1]).map_err(|e| e.to_string())
}

/// The result of one estimator on one flight.
#[derive(Debug, serde::Serialize)]
pub(crate) struct EstimatorReport {
    pub(crate) name: &'static str,
    #[serde(flatten)]
    pub(crate) summary: Summary,
    pub(crate) estimates: u64,
    pub(crate) unscored: u64,
    /// Seconds from the first measurement to the first published estimate.
    pub(crate) output_began_s: Option<f64>,
    /// Share of the measurements after which an estimate was published.
    pub(crate) published_pct: f64,
    /// Seconds from take-off (the truth 0.5 m above its start) until the
    /// estimate is within 0.5 m of the truth and stays there for 1 s;
    /// `null` when it never is (or the truth never takes off).
    pub(crate) tracking_after_take_off_s: Option<f64>,
    pub(crate) output_rate_hz: f64,
    pub(crate) rejected_pct: f64,
    pub(crate) rejected: Rejections,
    pub(crate) recoveries: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) guard: Option<GuardCounts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) shadow_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) attitude: Option<AttitudeSummary>,
    /// IMU samples not integrated, by reason (the IMU filter only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) imu_dropped: Option<imu_input::ImuDropped>,
    pub(crate) wall_s: f64,
}

/// Replays one flight through every estimator and prints the result.
pub fn run(args: &UtilArgs) -> Result<(), CommandError> {
    if args.max_seconds.is_some_and(|s| s.is_nan() || s <= 0.0) {
        return Err(CommandError::bad_input("--max-seconds must be positive"));
    }
    if args.thin_phase >= args.thin {
        return Err(CommandError::bad_input(format!(
            "--thin-phase must be below --thin ({})",
            args.thin
        )));
    }
    let started = Instant::now();
    let replayed = replay(args).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let wall = started.elapsed();
    let file = args.data.display().to_string();
    let r = &replayed;
    if args.json {
        let doc = serde_json::json!({
            "file": file,
            "anchors": args.anchors.display().to_string(),
            "constellation": args.constellation,
            "volume": r.volume,
            "measurements": r.measurements,
            "duration_s": r.duration_s,
            "truth_dropped": r.truth_dropped,
            "wall_s": wall.as_secs_f64(),
            "estimators": r.reports,
        });
        println!("{doc}");
    } else {
        print_table(&file, r, 3, wall);
    }
    if let Some(dir) = &args.plot {
        let stem = args
            .data
            .file_stem()
            .map_or("replay".into(), |s| s.to_string_lossy());
        let series: Vec<&[score::SeriesPoint]> = r
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

/// The replay's table; `dim` is the positions' (2 for a ground robot's
/// planar track, whose covariance is judged by its ellipse).
pub(crate) fn print_table(file: &str, r: &Replayed, dim: usize, wall: Duration) {
    println!(
        "{file}: {} measurements over {:.1} s, replayed in {:.2} s",
        r.measurements,
        r.duration_s,
        wall.as_secs_f64()
    );
    if r.truth_dropped > 0 {
        println!(
            "truth: {} motion-capture samples dropped as out of the vehicle's reach",
            r.truth_dropped
        );
    }
    println!(
        "estimator  rmse_3d_m rmse_xy_m mean_3d_m  p95_3d_m  max_3d_m rejected_%  rate_hz began_s published_%"
    );
    for e in &r.reports {
        if let Some(d) = e.imu_dropped.filter(|d| d.total() > 0) {
            println!(
                "{:<10} IMU samples dropped: {} not finite, {} saturated, {} out of order, {} from the future",
                e.name, d.non_finite, d.saturated, d.out_of_order, d.future
            );
        }
        let s = &e.summary;
        let (Some(rmse_3d_m), Some(rmse_xy_m), Some(mean_3d_m), Some(p95_3d_m), Some(max_3d_m)) = (
            s.rmse_3d_m,
            s.rmse_xy_m,
            s.mean_3d_m,
            s.p95_3d_m,
            s.max_3d_m,
        ) else {
            // No estimate to score: say so rather than print zero errors.
            println!(
                "{:<10} published no estimate ({:.2} % of the measurements rejected)",
                e.name, e.rejected_pct
            );
            continue;
        };
        println!(
            "{:<10} {:9.4} {:9.4} {:9.4} {:9.4} {:9.4} {:10.2} {:8.1} {:7.2} {:11.1}",
            e.name,
            rmse_3d_m,
            rmse_xy_m,
            mean_3d_m,
            p95_3d_m,
            max_3d_m,
            e.rejected_pct,
            e.output_rate_hz,
            e.output_began_s.unwrap_or(0.0),
            e.published_pct,
        );
        if let (Some(inside), Some(n)) = (s.inside_95_pct, &s.nees) {
            let shape = if dim == 2 { "ellipse" } else { "ellipsoid" };
            println!(
                "{:<10} covariance: truth inside its 95 % {shape} {:.1} %, NEES {:.2} ({dim} if honest; {:.2}-{:.2} for {} points)",
                "", inside, n.mean, n.low, n.high, n.samples
            );
        }
        if let Some(a) = &e.attitude {
            println!(
                "{:<10} attitude rmse {:.2} deg (tilt {:.2}, yaw {:.2}), max {:.2} deg",
                "", a.rmse_deg, a.tilt_rmse_deg, a.yaw_rmse_deg, a.max_deg
            );
        }
    }
}
