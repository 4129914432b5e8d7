//! `ickon replay`: recorded measurements through the positioning stack.
//!
//! `ickon replay util` reads a UTIL flight ([`util_csv`]) as a stream, feeds
//! every TDOA to each estimator ([`estimators`]), scores each estimate
//! against the truth interpolated at its time with the antenna offset
//! ([`score`]), and prints a table (or one JSON document) and optionally
//! PNG plots ([`plot`]). A bad file is reported with its name and line and
//! exit code 2.

mod estimators;
mod plaza;
mod plaza_csv;
mod plaza_plot;
mod plot;
mod score;
mod util_csv;

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};
use ickon_fusion::estimator::RangeDifferenceSample;

use crate::cli::{EXIT_BAD_INPUT, EXIT_FAILURE};
use estimators::{EkfRunner, MEASUREMENT_SIGMA_M, Rejections, WindowRunner};
use score::{Summary, Track, Truth};
use util_csv::{InputError, UtilReader};

/// The UWB antenna in the body frame of the UTIL drone, metres; the
/// extracts have no orientation, so only its height (+0.0908 m, nearly
/// all of it) is applied to the body centre.
const ANTENNA_OFFSET_M: [f64; 3] = [0.0, 0.0, 0.0908];

/// Recorded data sets `ickon replay` understands.
#[derive(Debug, Subcommand)]
pub enum ReplaySource {
    /// UTIL UWB TDOA flights with motion-capture truth.
    Util(UtilArgs),
    /// CMU Plaza runs: a wheeled robot's odometry and radio ranges, with truth.
    Plaza(plaza::PlazaArgs),
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
    /// Replay only the first this many seconds of measurements (the truth
    /// is read as far as it is needed to score them).
    #[arg(long)]
    pub max_seconds: Option<f64>,
}

/// The result of one estimator on one flight.
#[derive(Debug, serde::Serialize)]
struct EstimatorReport {
    name: &'static str,
    #[serde(flatten)]
    summary: Summary,
    estimates: u64,
    unscored: u64,
    output_rate_hz: f64,
    rejected_pct: f64,
    rejected: Rejections,
    recoveries: u64,
    wall_s: f64,
}

/// Runs a replay and returns the exit code.
pub fn run(source: ReplaySource) -> ExitCode {
    match source {
        ReplaySource::Util(args) => util(&args),
        ReplaySource::Plaza(args) => plaza::run(&args),
    }
}

fn util(args: &UtilArgs) -> ExitCode {
    if args.max_seconds.is_some_and(|s| s.is_nan() || s <= 0.0) {
        eprintln!("error: --max-seconds must be positive");
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let started = Instant::now();
    let (measurements, duration_s, ekf, window, tracks) = match replay(args) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    let wall = started.elapsed();
    let reports = [
        report(
            "tdoa-ekf",
            &tracks[0],
            measurements,
            duration_s,
            ekf.0.rejections,
            ekf.0.recoveries(),
            ekf.1,
        ),
        report(
            "window-gn",
            &tracks[1],
            measurements,
            duration_s,
            window.0.rejections,
            0,
            window.1,
        ),
    ];
    let file = args.data.display().to_string();
    if args.json {
        let doc = serde_json::json!({
            "file": file,
            "anchors": args.anchors.display().to_string(),
            "constellation": args.constellation,
            "measurements": measurements,
            "duration_s": duration_s,
            "wall_s": wall.as_secs_f64(),
            "estimators": reports,
        });
        println!("{doc}");
    } else {
        print_table(
            &file,
            args.constellation,
            measurements,
            duration_s,
            wall,
            &reports,
        );
    }
    if let Some(dir) = &args.plot {
        let stem = args
            .data
            .file_stem()
            .map_or("replay".into(), |s| s.to_string_lossy());
        let series: Vec<&[score::SeriesPoint]> = tracks
            .iter()
            .map(|t| t.series.as_deref().unwrap_or(&[]))
            .collect();
        let names: Vec<&str> = reports.iter().map(|r| r.name).collect();
        if let Err(e) = plot::write_all(dir, &stem, &names, &series) {
            eprintln!("error: cannot write plots to {}: {e}", dir.display());
            return ExitCode::from(EXIT_FAILURE);
        }
    }
    ExitCode::SUCCESS
}

type Replayed = (
    u64,
    f64,
    (EkfRunner, Duration),
    (WindowRunner, Duration),
    [Track; 2],
);

/// Streams the flight through both estimators and the scoring.
fn replay(args: &UtilArgs) -> Result<Replayed, InputError> {
    let anchors = util_csv::read_anchors(&args.anchors, args.constellation)?;
    let mut reader = UtilReader::open(&args.data)?;
    let start_m = estimators::centroid(&anchors);
    let mut ekf = (
        EkfRunner::new(estimators::util_ekf_params(), start_m),
        Duration::ZERO,
    );
    let mut window = (WindowRunner::new(start_m), Duration::ZERO);
    let plot = args.plot.is_some();
    let mut tracks = [Track::new(plot), Track::new(plot)];
    let mut truth = Truth::new(ANTENNA_OFFSET_M);
    let (mut measurements, mut first_s, mut last_s) = (0_u64, None, 0.0);
    let mut measuring = true;
    while let Some(row) = reader.next_row()? {
        if let Some(m) = row.tdoa.filter(|_| measuring) {
            let first = *first_s.get_or_insert(m.t_s);
            if args.max_seconds.is_some_and(|s| m.t_s - first > s) {
                measuring = false;
            } else {
                let sample = sample(&anchors, &m, &reader, row.line)?;
                measurements += 1;
                last_s = m.t_s;
                let t0 = Instant::now();
                if let Some((t, p)) = ekf.0.step(&sample) {
                    tracks[0].push(t, p);
                }
                let t1 = Instant::now();
                if let Some((t, p)) = window.0.step(&sample) {
                    tracks[1].push(t, p);
                }
                ekf.1 += t1 - t0;
                window.1 += t1.elapsed();
            }
        }
        if let Some(t) = row.truth {
            let [a, b] = &mut tracks;
            truth.push(t, &mut [a, b]);
            // With a prefix replayed, stop once the truth covers it.
            if !measuring && t.t_s > last_s {
                break;
            }
        }
    }
    if let Some((t, p)) = window.0.finish() {
        tracks[1].push(t, p);
    }
    let [a, b] = &mut tracks;
    truth.finish(&mut [a, b]);
    let duration_s = first_s.map_or(0.0, |f| last_s - f);
    Ok((measurements, duration_s, ekf, window, tracks))
}

/// The range difference of a TDOA row, with its anchors looked up.
fn sample(
    anchors: &HashMap<u32, [f64; 3]>,
    m: &util_csv::TdoaRow,
    reader: &UtilReader,
    line: u64,
) -> Result<RangeDifferenceSample, InputError> {
    let find = |id: u32| {
        anchors
            .get(&id)
            .copied()
            .ok_or_else(|| InputError::Malformed {
                path: reader.path().to_owned(),
                line,
                message: format!("anchor {id} is not in the anchor file for this constellation"),
            })
    };
    Ok(RangeDifferenceSample {
        t_s: m.t_s,
        a_m: find(m.id_a)?,
        b_m: find(m.id_b)?,
        d_m: m.d_m,
        sigma_m: MEASUREMENT_SIGMA_M,
    })
}

fn report(
    name: &'static str,
    track: &Track,
    measurements: u64,
    duration_s: f64,
    rejected: Rejections,
    recoveries: u64,
    wall: Duration,
) -> EstimatorReport {
    let summary = track.summary();
    let estimates = summary.scored + track.unscored;
    EstimatorReport {
        name,
        summary,
        estimates,
        unscored: track.unscored,
        output_rate_hz: if duration_s > 0.0 {
            estimates as f64 / duration_s
        } else {
            0.0
        },
        rejected_pct: 100.0 * rejected.total() as f64 / measurements.max(1) as f64,
        rejected,
        recoveries,
        wall_s: wall.as_secs_f64(),
    }
}

fn print_table(
    file: &str,
    constellation: u32,
    measurements: u64,
    duration_s: f64,
    wall: Duration,
    reports: &[EstimatorReport],
) {
    println!(
        "{file} (constellation {constellation}): {measurements} measurements over {duration_s:.1} s, replayed in {:.2} s",
        wall.as_secs_f64()
    );
    println!(
        "estimator  rmse_3d_m rmse_xy_m mean_3d_m  p95_3d_m  max_3d_m rejected_%  rate_hz  scored"
    );
    for r in reports {
        let s = &r.summary;
        println!(
            "{:<10} {:9.4} {:9.4} {:9.4} {:9.4} {:9.4} {:10.2} {:8.1} {:7}",
            r.name,
            s.rmse_3d_m,
            s.rmse_xy_m,
            s.mean_3d_m,
            s.p95_3d_m,
            s.max_3d_m,
            r.rejected_pct,
            r.output_rate_hz,
            s.scored
        );
    }
}
