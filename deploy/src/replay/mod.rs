//! `ickon replay`: recorded measurements through the positioning stack.
//!
//! `ickon replay util` reads a UTIL flight ([`util_csv`]: its TDOA, truth
//! and, in the 27-column layout, IMU streams), feeds every TDOA in time
//! order to each estimator ([`estimators`]; the IMU samples up to its time
//! first, to `imu-eskf`), scores each published estimate against the truth
//! interpolated at its time with the antenna lever arm ([`score`], and the
//! attitude: [`attitude`]), and prints a table (or one JSON document) and
//! optionally PNG plots ([`plot`]). A bad file is reported with its name
//! and line and exit code 2.

mod attitude;
mod estimators;
mod plot;
mod score;
mod util_csv;

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};
use ickon_fusion::estimator::RangeDifferenceSample;
use ickon_fusion::estimator::flight::{CvFilter, ImuFilter, ImuSample};
use ickon_fusion::estimator::guard::{FlightVolume, GuardCounts};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::cli::{EXIT_BAD_INPUT, EXIT_FAILURE};
use attitude::{AttitudeSummary, AttitudeTrack};
use estimators::{CvRunner, EkfRunner, ImuRunner, MEASUREMENT_SIGMA_M, Rejections, WindowRunner};
use score::{Summary, Track, Truth};
use util_csv::{InputError, TruthRow, UtilReader};

/// The UWB antenna in the body frame of the UTIL drone, metres (data
/// README).
const ANTENNA_BODY_M: [f64; 3] = [-0.01245, 0.00127, 0.0908];

/// Margin of the flight volume around the anchors' box, metres: the
/// anchors stand on the floor and hang under the ceiling of the arena, so
/// the drone flies inside their box; half a metre covers a tag on the
/// floor below an anchor's stand.
const VOLUME_MARGIN_M: f64 = 0.5;

/// Recorded data sets `ickon replay` understands.
#[derive(Debug, Subcommand)]
pub enum ReplaySource {
    /// UTIL UWB TDOA flights with motion-capture truth.
    Util(UtilArgs),
}

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
    /// Print one JSON document on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Replay only the first this many seconds of measurements.
    #[arg(long)]
    pub max_seconds: Option<f64>,
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
struct EstimatorReport {
    name: &'static str,
    #[serde(flatten)]
    summary: Summary,
    estimates: u64,
    unscored: u64,
    /// Seconds from the first measurement to the first published estimate.
    output_began_s: Option<f64>,
    /// Share of the measurements after which an estimate was published.
    published_pct: f64,
    output_rate_hz: f64,
    rejected_pct: f64,
    rejected: Rejections,
    recoveries: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    guard: Option<GuardCounts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    shadow_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    attitude: Option<AttitudeSummary>,
    wall_s: f64,
}

/// Runs a replay and returns the exit code.
pub fn run(source: ReplaySource) -> ExitCode {
    match source {
        ReplaySource::Util(args) => util(&args),
    }
}

fn util(args: &UtilArgs) -> ExitCode {
    if args.max_seconds.is_some_and(|s| s.is_nan() || s <= 0.0) {
        eprintln!("error: --max-seconds must be positive");
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let started = Instant::now();
    let replayed = match replay(args) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
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
            "wall_s": wall.as_secs_f64(),
            "estimators": r.reports,
        });
        println!("{doc}");
    } else {
        print_table(&file, r, wall);
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
        if let Err(e) = plot::write_all(dir, &stem, &names, &series) {
            eprintln!("error: cannot write plots to {}: {e}", dir.display());
            return ExitCode::from(EXIT_FAILURE);
        }
    }
    ExitCode::SUCCESS
}

/// Everything a replay produced.
struct Replayed {
    measurements: u64,
    duration_s: f64,
    volume: FlightVolume,
    reports: Vec<EstimatorReport>,
    tracks: Vec<Track>,
}

/// The file's streams, each in time order.
#[derive(Default)]
struct Streams {
    tdoa: Vec<(u64, util_csv::TdoaRow)>,
    imu: Vec<util_csv::ImuRow>,
    truth: Vec<TruthRow>,
}

fn read_streams(args: &UtilArgs, reader: &mut UtilReader) -> Result<Streams, InputError> {
    let mut s = Streams::default();
    let mut first_s = None;
    while let Some(row) = reader.next_row()? {
        if let Some(m) = row.tdoa {
            let first = *first_s.get_or_insert(m.t_s);
            if args.max_seconds.is_none_or(|max| m.t_s - first <= max) {
                s.tdoa.push((row.line, m));
            }
        }
        s.imu.extend(row.imu);
        s.truth.extend(row.truth);
    }
    Ok(s)
}

/// The antenna's true position: with the orientation, the whole lever
/// arm; without, its height only (nearly all of it).
fn antenna(row: &TruthRow) -> TruthRow {
    let p = Vector3::from(row.position_m);
    let offset = match row.attitude_xyzw {
        Some(q) => {
            UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
                * Vector3::from(ANTENNA_BODY_M)
        }
        None => Vector3::new(0.0, 0.0, ANTENNA_BODY_M[2]),
    };
    TruthRow {
        position_m: (p + offset).into(),
        ..*row
    }
}

/// Runs every estimator over the flight and scores them.
fn replay(args: &UtilArgs) -> Result<Replayed, InputError> {
    let anchors = util_csv::read_anchors(&args.anchors, args.constellation)?;
    let mut reader = UtilReader::open(&args.data)?;
    let bad_input = |message: String| InputError::Malformed {
        path: args.data.clone(),
        line: 1,
        message,
    };
    if args.imu && !reader.has_imu() {
        return Err(bad_input(
            "--imu needs the IMU columns (t_acc, acc_*, t_gyro, gyro_*)".into(),
        ));
    }
    let positions: Vec<[f64; 3]> = anchors.values().copied().collect();
    let volume = match args.bounds {
        Some(v) => v,
        None => FlightVolume::around(&positions, VOLUME_MARGIN_M)
            .map_err(|e| bad_input(e.to_string()))?,
    };
    let streams = read_streams(args, &mut reader)?;
    let start_m = estimators::centroid(&anchors);
    let guard = estimators::util_guard_params();
    let overrides = estimators::Overrides {
        accel_psd_m2_s3: args.accel_psd_m2_s3,
        shadow_m: args.shadow_m,
        shadow_prior_sigma_m: args.shadow_prior_sigma_m,
    };
    let cv_params = estimators::util_cv_params(overrides);
    let cv = CvFilter::new(cv_params).map_err(|e| bad_input(e.to_string()))?;
    let mut ours = CvRunner::new(cv, volume, guard);
    let mut baseline = EkfRunner::new(estimators::baseline_params(), start_m);
    let mut window = WindowRunner::new(start_m);
    let mut imu = match args.imu {
        true => {
            let params = estimators::util_imu_params(
                ANTENNA_BODY_M,
                args.initial_yaw_deg.to_radians(),
                overrides,
            );
            let filter = ImuFilter::new(params).map_err(|e| bad_input(e.to_string()))?;
            Some(ImuRunner::new(filter, volume, guard))
        }
        false => None,
    };
    let n_tracks = 3 + usize::from(imu.is_some());
    let plot = args.plot.is_some();
    let mut tracks: Vec<Track> = (0..n_tracks).map(|_| Track::new(plot)).collect();
    let mut walls = vec![Duration::ZERO; n_tracks];
    let mut attitude = AttitudeTrack::default();
    let mut next_imu = 0;
    for &(line, m) in &streams.tdoa {
        let sample = sample(&anchors, &m, &reader, line)?;
        let mut timed = |k: usize, f: &mut dyn FnMut() -> Option<(f64, [f64; 3])>| {
            let t0 = Instant::now();
            let out = f();
            walls[k] += t0.elapsed();
            if let Some((t, p)) = out {
                tracks[k].push(t, p);
            }
            out.is_some()
        };
        timed(0, &mut || ours.step(&sample));
        timed(1, &mut || baseline.step(&sample));
        timed(2, &mut || window.step(&sample));
        if let Some(r) = &mut imu {
            let published = timed(3, &mut || {
                while let Some(s) = streams.imu.get(next_imu).filter(|s| s.t_s <= m.t_s) {
                    r.filter_mut().imu(&ImuSample {
                        t_s: s.t_s,
                        accel_m_s2: s.accel_m_s2,
                        gyro_rad_s: s.gyro_rad_s,
                    });
                    next_imu += 1;
                }
                r.step(&sample)
            });
            if published {
                attitude.push_estimate(m.t_s, r.filter().attitude_xyzw());
            }
        }
    }
    if let Some((t, p)) = window.finish() {
        tracks[2].push(t, p);
    }
    let mut truth = Truth::new([0.0; 3]);
    {
        let mut refs: Vec<&mut Track> = tracks.iter_mut().collect();
        for row in &streams.truth {
            truth.push(antenna(row), &mut refs);
            if let Some(q) = row.attitude_xyzw {
                attitude.push_truth(row.t_s, q);
            }
        }
        truth.finish(&mut refs);
    }
    let measurements = streams.tdoa.len() as u64;
    let first_s = streams.tdoa.first().map(|m| m.1.t_s);
    let duration_s = streams.tdoa.last().map_or(0.0, |m| m.1.t_s) - first_s.unwrap_or(0.0);
    let began = |t: Option<f64>| t.zip(first_s).map(|(t, f)| t - f);
    let shadow = |s: (f64, f64)| Some(s.0);
    let mut reports = vec![
        EstimatorReport {
            guard: Some(ours.counts()),
            shadow_m: shadow(ours.filter().shadow_m()),
            ..report(
                "tdoa-ekf",
                &tracks[0],
                measurements,
                duration_s,
                ours.rejections,
                walls[0],
            )
        },
        EstimatorReport {
            recoveries: baseline.recoveries(),
            output_began_s: Some(0.0),
            ..report(
                "cv-ekf",
                &tracks[1],
                measurements,
                duration_s,
                baseline.rejections,
                walls[1],
            )
        },
        EstimatorReport {
            output_began_s: began(tracks[2].first_s()),
            ..report(
                "window-gn",
                &tracks[2],
                measurements,
                duration_s,
                window.rejections,
                walls[2],
            )
        },
    ];
    reports[0].output_began_s = began(ours.first_published_s);
    if let Some(r) = &imu {
        reports.push(EstimatorReport {
            guard: Some(r.counts()),
            shadow_m: shadow(r.filter().shadow_m()),
            attitude: attitude.summary(),
            output_began_s: began(r.first_published_s),
            ..report(
                "imu-eskf",
                &tracks[3],
                measurements,
                duration_s,
                r.rejections,
                walls[3],
            )
        });
    }
    Ok(Replayed {
        measurements,
        duration_s,
        volume,
        reports,
        tracks,
    })
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
    wall: Duration,
) -> EstimatorReport {
    let summary = track.summary();
    let estimates = summary.scored + track.unscored;
    EstimatorReport {
        name,
        summary,
        estimates,
        unscored: track.unscored,
        output_began_s: None,
        published_pct: 100.0 * estimates as f64 / measurements.max(1) as f64,
        output_rate_hz: if duration_s > 0.0 {
            estimates as f64 / duration_s
        } else {
            0.0
        },
        rejected_pct: 100.0 * rejected.total() as f64 / measurements.max(1) as f64,
        rejected,
        recoveries: 0,
        guard: None,
        shadow_m: None,
        attitude: None,
        wall_s: wall.as_secs_f64(),
    }
}

fn print_table(file: &str, r: &Replayed, wall: Duration) {
    println!(
        "{file}: {} measurements over {:.1} s, replayed in {:.2} s",
        r.measurements,
        r.duration_s,
        wall.as_secs_f64()
    );
    println!(
        "estimator  rmse_3d_m rmse_xy_m mean_3d_m  p95_3d_m  max_3d_m rejected_%  rate_hz began_s published_%"
    );
    for e in &r.reports {
        let s = &e.summary;
        println!(
            "{:<10} {:9.4} {:9.4} {:9.4} {:9.4} {:9.4} {:10.2} {:8.1} {:7.2} {:11.1}",
            e.name,
            s.rmse_3d_m,
            s.rmse_xy_m,
            s.mean_3d_m,
            s.p95_3d_m,
            s.max_3d_m,
            e.rejected_pct,
            e.output_rate_hz,
            e.output_began_s.unwrap_or(f64::NAN),
            e.published_pct,
        );
        if let Some(a) = &e.attitude {
            println!(
                "{:<10} attitude rmse {:.2} deg (tilt {:.2}, yaw {:.2}), max {:.2} deg",
                "", a.rmse_deg, a.tilt_rmse_deg, a.yaw_rmse_deg, a.max_deg
            );
        }
    }
}
