//! `ickon replay plaza`: the ground filter on a real wheeled robot (CMU
//! Plaza runs: wheel odometry and radio ranges to four beacons, with
//! truth; the README of the data's `plaza/` folder).
//!
//! The same [`TdoaEkf`] as on the MSU, driven directly: each odometry
//! increment is a prediction step (no gyro: the turn bias state is the
//! wheels' heading drift), each range a scalar update with the ranges'
//! bias and scale error estimated (`range = (1 + scale) d + bias`, both
//! starting at zero). Scored every increment against the truth interpolated at its
//! time, with dead reckoning from the same start pose beside it.
//!
//! One parameter set for every run ([`plaza_params`]); every constant is
//! the data README's or the filter's default, none is fitted to a run.

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

use clap::Args;
use ickon_fusion::estimator::history::InOrderFilter;
use ickon_fusion::estimator::tdoa_ekf::{GroundNoise, TdoaEkf, TdoaEkfParams};
use ickon_fusion::estimator::{InitialPose, PoseEstimate};

mod dataset;
mod plot;
mod report;
mod to_tdoa;

use dataset::{PlazaRun, TruthRow, read_run};
use ickon_runtime::CommandError;
use report::Consistency;
pub use report::{RunReport, Sample, Stats};
pub use to_tdoa::{ConvertPlazaArgs, run as run_convert};

/// Standard deviation of one range, metres: the data README's simple
/// filter's value (the filter's one-sided heavy tail handles the long ones).
pub const RANGE_SIGMA_M: f64 = 1.5;
/// Odometry noise, a fraction of each increment (distance and turn): the
/// data README's simple filter's value.
pub const ODOMETRY_FRACTION: f64 = 0.05;
/// Errors are counted for "after the first minute" from this time, s.
pub const SETTLE_S: f64 = 60.0;
/// Start uncertainty per axis, metres (the truth's first position is
/// given; half a metre allows for its survey).
pub const START_SIGMA_XY_M: f64 = 0.5;
/// Start heading uncertainty, degrees.
pub const START_SIGMA_THETA_DEG: f64 = 10.0;
/// Path length over which the direction of travel at the start is taken
/// from the truth, m (to tell a reversed truth heading).
pub const START_CHORD_M: f64 = 0.5;

/// Arguments of `ickon replay plaza`.
#[derive(Debug, Args)]
pub struct PlazaArgs {
    /// The data directory holding `Plaza1/` and `Plaza2/` (or one run's
    /// directory with `gt.csv`, `odometry.csv`, `ranges.csv`, `beacons.csv`).
    #[arg(long)]
    pub data: PathBuf,
    /// Print one JSON document on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// The filter's parameters on the Plaza robot: the registry defaults with
/// the robot's sensors (wheels only, 5 % of each increment, as the data
/// README's simple filter) and its start pose.
pub fn plaza_params(start: InitialPose) -> TdoaEkfParams {
    let mut params = wheel_params(Some(start), ODOMETRY_FRACTION);
    // The Plaza ranges are radio (UWB): the air does not change them.
    params.sensors = params.sensors.without_air();
    params
}

/// The filter on a wheeled robot without a gyro whose odometry errs by
/// `fraction` of each increment (distance and turn), started at `start`
/// when given (else from its first consistent measurements), its
/// receiver in the anchors' plane.
pub fn wheel_params(start: Option<InitialPose>, fraction: f64) -> TdoaEkfParams {
    let sensors = GroundNoise {
        // var = ((slip / sqrt 2) d)^2 = (fraction d)^2.
        wheel_slip_fraction: fraction * std::f64::consts::SQRT_2,
        wheel_slip_per_rad_s: 0.0,
        wheel_heading_rad_per_rad: fraction,
        wheel_heading_rad_per_m: 0.0,
        ..GroundNoise::default()
    };
    TdoaEkfParams {
        initial_pose: start,
        receiver_height_m: 0.0,
        sensors,
        use_gyro: false,
        ..TdoaEkfParams::default()
    }
}

/// Runs `ickon replay plaza` and returns the exit code.
pub fn run(args: &PlazaArgs) -> Result<(), CommandError> {
    let dirs = run_dirs(&args.data);
    if dirs.is_empty() {
        return Err(CommandError::bad_input(format!(
            "{}: no Plaza run (gt.csv, odometry.csv, ranges.csv, beacons.csv) found",
            args.data.display()
        )));
    }
    let mut reports = Vec::new();
    for dir in &dirs {
        let data = read_run(dir).map_err(|e| CommandError::bad_input(e.to_string()))?;
        let name = dir
            .file_name()
            .map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into());
        match replay_run(&name, &data) {
            Ok(r) => reports.push(r),
            Err(message) => {
                return Err(CommandError::bad_input(format!(
                    "{}: {message}",
                    dir.display()
                )));
            }
        }
    }
    if args.json {
        let doc = serde_json::json!({
            "data": args.data.display().to_string(),
            "range_sigma_m": RANGE_SIGMA_M,
            "odometry_fraction": ODOMETRY_FRACTION,
            "runs": reports,
        });
        println!("{doc}");
    } else {
        print_table(&reports);
    }
    if let Some(dir) = &args.plot {
        for r in &reports {
            if let Err(e) = plot::write(dir, r) {
                return Err(CommandError::failure(format!(
                    "cannot write plots to {}: {e}",
                    dir.display()
                )));
            }
        }
    }
    Ok(())
}

/// The run directories under `data` (or `data` itself), sorted.
fn run_dirs(data: &Path) -> Vec<PathBuf> {
    if data.join("gt.csv").is_file() {
        return vec![data.to_owned()];
    }
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(data)
        .map(|it| {
            it.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.join("gt.csv").is_file())
                .collect()
        })
        .unwrap_or_default();
    dirs.sort();
    dirs
}

/// The truth at `t_s`, linearly interpolated; `None` outside it.
fn truth_at(truth: &[TruthRow], t_s: f64) -> Option<[f64; 2]> {
    let k = truth.partition_point(|r| r.t_s <= t_s);
    if k == 0 || k >= truth.len() {
        return (k > 0 && truth[k - 1].t_s == t_s).then(|| truth[k - 1].xy_m);
    }
    let (a, b) = (truth[k - 1], truth[k]);
    let w = if b.t_s > a.t_s {
        (t_s - a.t_s) / (b.t_s - a.t_s)
    } else {
        0.0
    };
    Some(std::array::from_fn(|i| {
        a.xy_m[i] + w * (b.xy_m[i] - a.xy_m[i])
    }))
}

/// The start pose: the truth's first pose, its heading turned by pi when
/// it points against the direction of travel over the first
/// [`START_CHORD_M`] (Plaza2's truth heading is the travel direction plus
/// pi, data README).
fn start_pose(truth: &[TruthRow]) -> Option<InitialPose> {
    let first = truth.first()?;
    let reversed = heading_reversed(truth)?;
    Some(InitialPose {
        x_m: first.xy_m[0],
        y_m: first.xy_m[1],
        theta_rad: first.heading_rad + if reversed { PI } else { 0.0 },
        sigma_xy_m: START_SIGMA_XY_M,
        sigma_theta_rad: START_SIGMA_THETA_DEG.to_radians(),
    })
}

/// Whether the truth's heading points against the direction of travel
/// over the first [`START_CHORD_M`]; `None` when it never moves that far.
fn heading_reversed(truth: &[TruthRow]) -> Option<bool> {
    let first = truth.first()?;
    let far = truth
        .iter()
        .find(|r| (r.xy_m[0] - first.xy_m[0]).hypot(r.xy_m[1] - first.xy_m[1]) >= START_CHORD_M)?;
    let travel = (far.xy_m[1] - first.xy_m[1]).atan2(far.xy_m[0] - first.xy_m[0]);
    Some(ickon_fusion::angle::diff(first.heading_rad, travel).abs() > FRAC_PI_2)
}

/// Replays one run through the filter and dead reckoning.
pub fn replay_run(name: &str, data: &PlazaRun) -> Result<RunReport, String> {
    let start = start_pose(&data.truth).ok_or("the truth never moves 0.5 m")?;
    let t0 = data.truth[0].t_s;
    let mut filter = TdoaEkf::new(&plaza_params(start));
    let mut dead = (start.x_m, start.y_m, start.theta_rad);
    let (mut filter_track, mut odometry_track) = (Vec::new(), Vec::new());
    let (mut used, mut rejected) = (0u64, 0u64);
    let mut consistency = Consistency::default();
    let mut ranges = data.ranges.iter().peekable();
    let mut last_t = t0;
    for o in &data.odometry {
        while let Some(r) = ranges.next_if(|r| r.t_s <= o.t_s) {
            let Some(beacon) = data.beacons.get(&r.beacon) else {
                rejected += 1;
                continue;
            };
            if filter
                .range(r.t_s, *beacon, r.range_m, RANGE_SIGMA_M)
                .is_accepted()
            {
                used += 1;
            } else {
                rejected += 1;
            }
        }
        let dt = (o.t_s - last_t).max(0.0);
        last_t = o.t_s;
        filter.increment(o.t_s, o.distance_m, o.dtheta_rad, dt, false);
        dead = arc(dead, o.distance_m, o.dtheta_rad);
        let Some(truth) = truth_at(&data.truth, o.t_s) else {
            continue;
        };
        if let Some(PoseEstimate {
            x_m,
            y_m,
            covariance,
            ..
        }) = filter.pose()
        {
            let c = [covariance[(0, 0)], covariance[(0, 1)], covariance[(1, 1)]];
            consistency.push([x_m - truth[0], y_m - truth[1]], c);
            filter_track.push(Sample {
                t_s: o.t_s - t0,
                estimate_m: [x_m, y_m],
                truth_m: truth,
            });
        }
        odometry_track.push(Sample {
            t_s: o.t_s - t0,
            estimate_m: [dead.0, dead.1],
            truth_m: truth,
        });
    }
    let duration_s = data.truth.last().map_or(0.0, |r| r.t_s - t0);
    Ok(RunReport {
        run: name.to_owned(),
        duration_s,
        filter: stats(&filter_track),
        odometry: stats(&odometry_track),
        ranges_used: used,
        ranges_rejected: rejected,
        range_bias_m: filter.range_bias_m().unwrap_or(0.0),
        range_scale: filter.range_scale().unwrap_or(0.0),
        distance_scale: filter.distance_scale().unwrap_or(0.0),
        turn_bias_deg_s: filter.turn_bias_rad_s().unwrap_or(0.0).to_degrees(),
        reinitialisations: filter.reinitialisations().len(),
        inside_95_pct: consistency.inside_95_pct(),
        nees: consistency.nees(),
        adaptations: filter.adaptations(),
        filter_track,
        odometry_track,
    })
}

/// Dead reckoning: the arc of one increment.
fn arc((x, y, th): (f64, f64, f64), d: f64, dth: f64) -> (f64, f64, f64) {
    let mid = th + 0.5 * dth;
    (x + d * mid.cos(), y + d * mid.sin(), th + dth)
}

/// RMSE, mean, p95 and max of a track's 2D errors.
pub fn stats(track: &[Sample]) -> Stats {
    let err = |s: &Sample| (s.estimate_m[0] - s.truth_m[0]).hypot(s.estimate_m[1] - s.truth_m[1]);
    let mut e: Vec<f64> = track.iter().map(err).collect();
    let n = e.len().max(1) as f64;
    let rmse_m = (e.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    let mean_m = e.iter().sum::<f64>() / n;
    let max_after_60s_m = track
        .iter()
        .filter(|s| s.t_s >= SETTLE_S)
        .map(err)
        .fold(0.0, f64::max);
    e.sort_by(f64::total_cmp);
    let p95_m = e
        .get(((e.len() as f64 * 0.95).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(0.0);
    Stats {
        rmse_m,
        mean_m,
        p95_m,
        max_m: e.last().copied().unwrap_or(0.0),
        max_after_60s_m,
        samples: e.len(),
    }
}

fn print_table(reports: &[RunReport]) {
    println!(
        "ickon replay plaza: tdoa-ekf (ranges + wheel odometry, range bias and scale estimated) against dead reckoning"
    );
    println!(
        "| run | track | 2D RMSE m | mean m | p95 m | max m | max after 60 s m | ranges used / rejected | range bias m | range scale | inside 95 % | NEES (95 % bounds) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in reports {
        let f = &r.filter;
        println!(
            "| {} | tdoa-ekf | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {} / {} | {:.2} | {:.3} | {} | {} |",
            r.run,
            f.rmse_m,
            f.mean_m,
            f.p95_m,
            f.max_m,
            f.max_after_60s_m,
            r.ranges_used,
            r.ranges_rejected,
            r.range_bias_m,
            r.range_scale,
            r.inside_95_pct
                .map_or_else(|| "-".to_owned(), |p| format!("{p:.1}")),
            r.nees.map_or_else(
                || "-".to_owned(),
                |n| format!("{:.2} ({:.2}-{:.2})", n.mean, n.low, n.high)
            ),
        );
        let o = &r.odometry;
        println!(
            "| | odometry | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | | | | | |",
            o.rmse_m, o.mean_m, o.p95_m, o.max_m, o.max_after_60s_m
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_is_interpolated_and_not_extrapolated() {
        let truth = [
            TruthRow {
                t_s: 0.0,
                xy_m: [0.0, 0.0],
                heading_rad: 0.0,
            },
            TruthRow {
                t_s: 2.0,
                xy_m: [2.0, 4.0],
                heading_rad: 0.0,
            },
        ];
        assert_eq!(truth_at(&truth, 1.0), Some([1.0, 2.0]));
        assert_eq!(truth_at(&truth, 2.0), Some([2.0, 4.0]));
        assert_eq!(truth_at(&truth, 2.5), None);
        assert_eq!(truth_at(&truth, -1.0), None);
    }

    #[test]
    fn stats_of_a_known_track() {
        let s = |t_s: f64, e: f64| Sample {
            t_s,
            estimate_m: [e, 0.0],
            truth_m: [0.0, 0.0],
        };
        let st = stats(&[s(0.0, 1.0), s(70.0, 3.0)]);
        assert!((st.rmse_m - 5f64.sqrt()).abs() < 1e-12);
        assert!((st.mean_m - 2.0).abs() < 1e-12);
        assert_eq!((st.p95_m, st.max_m, st.max_after_60s_m), (3.0, 3.0, 3.0));
    }
}
