//! One replay: the file's streams read, every estimator run over them in
//! time order, each scored against the truth.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use ickon_fusion::estimator::RangeDifferenceSample;
use ickon_fusion::estimator::flight::{CvFilter, ImuFilter, ImuSample};
use ickon_fusion::estimator::guard::FlightVolume;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::attitude::AttitudeTrack;
use super::dataset::{self, InputError, TruthRow, UtilReader};
use super::estimators::{
    self, CvRunner, EkfRunner, ImuRunner, MEASUREMENT_SIGMA_M, Rejections, WindowRunner,
};
use super::imu_input;
use super::score::{Track, Truth};

/// A published estimate: time, position and its covariance if any.
type Estimate = (f64, [f64; 3], Option<nalgebra::Matrix3<f64>>);
use super::{EstimatorReport, UtilArgs};

/// The UWB antenna in the body frame of the UTIL drone, metres (data
/// README).
const ANTENNA_BODY_M: [f64; 3] = [-0.01245, 0.00127, 0.0908];

/// Margin of the flight volume around the anchors' box, metres: the
/// anchors stand on the floor and hang under the ceiling of the arena, so
/// the drone flies inside their box; half a metre covers a tag on the
/// floor below an anchor's stand.
const VOLUME_MARGIN_M: f64 = 0.5;

/// The vehicle has taken off once its truth is this far above its first
/// sample, metres: clear of the floor-level anchors' stands (about 0.2 m
/// high) and of the body's own height.
const TAKE_OFF_ABOVE_START_M: f64 = 0.5;
/// An estimate tracks once it is within this of the truth (the watch's
/// bound for a receiver placed elsewhere, `LostParams::disagree_m`) ...
const TRACKING_WITHIN_M: f64 = 0.5;
/// ... and stays so for this long, seconds.
const TRACKING_HOLD_S: f64 = 1.0;

/// Time of take-off: the first truth sample [`TAKE_OFF_ABOVE_START_M`]
/// above the first one.
fn take_off_s(truth: &[TruthRow]) -> Option<f64> {
    let ground_z = truth.first()?.position_m[2];
    truth
        .iter()
        .find(|r| r.position_m[2] >= ground_z + TAKE_OFF_ABOVE_START_M)
        .map(|r| r.t_s)
}

/// Everything a replay produced.
pub(crate) struct Replayed {
    pub(crate) measurements: u64,
    pub(crate) duration_s: f64,
    pub(crate) volume: FlightVolume,
    pub(crate) reports: Vec<EstimatorReport>,
    pub(crate) tracks: Vec<Track>,
}

/// The file's streams, each in time order.
#[derive(Default)]
struct Streams {
    tdoa: Vec<(u64, dataset::TdoaRow)>,
    imu: Vec<dataset::ImuRow>,
    truth: Vec<TruthRow>,
}

fn read_streams(args: &UtilArgs, reader: &mut UtilReader) -> Result<Streams, InputError> {
    let mut s = Streams::default();
    let mut first_s = None;
    let mut tdoa_rows = 0_u32;
    while let Some(row) = reader.next_row()? {
        if let Some(m) = row.tdoa {
            let first = *first_s.get_or_insert(m.t_s);
            let kept = tdoa_rows % args.thin == args.thin_phase;
            tdoa_rows = (tdoa_rows + 1) % args.thin;
            if kept && args.max_seconds.is_none_or(|max| m.t_s - first <= max) {
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
pub(crate) fn antenna(row: &TruthRow) -> TruthRow {
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
pub(super) fn replay(args: &UtilArgs) -> Result<Replayed, InputError> {
    let anchors = dataset::read_anchors(&args.anchors, args.constellation)?;
    let mut reader = UtilReader::open(&args.data)?;
    if args.imu && !reader.has_imu() {
        return Err(bad_input(
            args,
            "--imu needs the IMU columns (t_acc, acc_*, t_gyro, gyro_*)".into(),
        ));
    }
    let positions: Vec<[f64; 3]> = anchors.values().copied().collect();
    let volume = match args.bounds {
        Some(v) => v,
        None => FlightVolume::around(&positions, VOLUME_MARGIN_M)
            .map_err(|e| bad_input(args, e.to_string()))?,
    };
    let mut streams = read_streams(args, &mut reader)?;
    let imu_dropped = if args.imu {
        let (kept, dropped) = imu_input::screen(&streams.imu);
        if kept.is_empty() {
            return Err(bad_input(
                args,
                format!(
                    "--imu: the file has no usable IMU sample ({} read, {} dropped: {dropped:?})",
                    streams.imu.len(),
                    dropped.total()
                ),
            ));
        }
        streams.imu = kept;
        Some(dropped)
    } else {
        None
    };
    let mut runners = Runners::new(args, &anchors, volume)?;
    let mut runs = runners.run(&streams, &anchors, &reader, args.plot.is_some())?;
    score(&streams, &mut runs);
    let measurements = streams.tdoa.len() as u64;
    let first_s = streams.tdoa.first().map(|m| m.1.t_s);
    let duration_s = streams.tdoa.last().map_or(0.0, |m| m.1.t_s) - first_s.unwrap_or(0.0);
    let mut reports = runners.reports(&runs, measurements, duration_s, first_s);
    if let Some(t0) = take_off_s(&streams.truth) {
        for (r, track) in reports.iter_mut().zip(&runs.tracks) {
            r.tracking_after_take_off_s =
                track.tracking_after(t0, TRACKING_WITHIN_M, TRACKING_HOLD_S);
        }
    }
    if let Some(r) = reports.iter_mut().find(|r| r.name == "imu-eskf") {
        r.imu_dropped = imu_dropped;
    }
    Ok(Replayed {
        measurements,
        duration_s,
        volume,
        reports,
        tracks: runs.tracks,
    })
}

/// A complaint about the data file as a whole.
fn bad_input(args: &UtilArgs, message: String) -> InputError {
    InputError::Malformed {
        path: args.data.clone(),
        line: 1,
        message,
    }
}

/// The estimators a replay runs side by side: ours, the plain baseline,
/// the sliding window, and with `--imu` the IMU filter.
struct Runners {
    ours: CvRunner,
    baseline: EkfRunner,
    window: WindowRunner,
    imu: Option<ImuRunner>,
}

/// What the estimators produced over the flight: one track each (in the
/// order of [`Runners`]), the time each took, and the IMU filter's
/// attitude.
struct Runs {
    tracks: Vec<Track>,
    walls: Vec<Duration>,
    attitude: AttitudeTrack,
}

impl Runners {
    /// Every estimator, set up for the anchors and the flight volume.
    fn new(
        args: &UtilArgs,
        anchors: &HashMap<u32, [f64; 3]>,
        volume: FlightVolume,
    ) -> Result<Self, InputError> {
        let start_m = estimators::centroid(anchors);
        let guard = estimators::util_guard_params();
        let overrides = estimators::Overrides {
            accel_psd_m2_s3: args.accel_psd_m2_s3,
            shadow_m: args.shadow_m,
            shadow_prior_sigma_m: args.shadow_prior_sigma_m,
            excess_sigma_m: args.excess_sigma_m,
        };
        let cv_params = estimators::util_cv_params(overrides);
        let cv = CvFilter::new(cv_params).map_err(|e| bad_input(args, e.to_string()))?;
        let ours = CvRunner::new(cv, volume, guard);
        let baseline = EkfRunner::new(estimators::baseline_params(), start_m);
        let window = WindowRunner::new(start_m);
        let imu = match args.imu {
            true => {
                let params = estimators::util_imu_params(
                    ANTENNA_BODY_M,
                    args.initial_yaw_deg.to_radians(),
                    overrides,
                );
                let filter = ImuFilter::new(params).map_err(|e| bad_input(args, e.to_string()))?;
                Some(ImuRunner::new(filter, volume, guard))
            }
            false => None,
        };
        Ok(Self {
            ours,
            baseline,
            window,
            imu,
        })
    }

    /// Feeds every range difference to every estimator in time order (the
    /// IMU filter gets the IMU samples up to each first), timing each;
    /// `plot` keeps the tracks' points for a plot.
    fn run(
        &mut self,
        streams: &Streams,
        anchors: &HashMap<u32, [f64; 3]>,
        reader: &UtilReader,
        plot: bool,
    ) -> Result<Runs, InputError> {
        let n_tracks = 3 + usize::from(self.imu.is_some());
        let mut tracks: Vec<Track> = (0..n_tracks).map(|_| Track::new(plot)).collect();
        let mut walls = vec![Duration::ZERO; n_tracks];
        let mut attitude = AttitudeTrack::default();
        let mut next_imu = 0;
        for &(line, m) in &streams.tdoa {
            let sample = sample(anchors, &m, reader, line)?;
            let mut timed = |k: usize, f: &mut dyn FnMut() -> Option<Estimate>| {
                let t0 = Instant::now();
                let out = f();
                walls[k] += t0.elapsed();
                if let Some((t, p, c)) = out {
                    tracks[k].push_with(t, p, c);
                }
                out.is_some()
            };
            let ours = &mut self.ours;
            timed(0, &mut || {
                let (t, p) = ours.step(&sample)?;
                Some((t, p, Some(ours.covariance_m2())))
            });
            let baseline = &mut self.baseline;
            timed(1, &mut || {
                let (t, p) = baseline.step(&sample)?;
                Some((t, p, baseline.covariance_m2()))
            });
            let window = &mut self.window;
            timed(2, &mut || window.step(&sample).map(|(t, p)| (t, p, None)));
            if let Some(r) = &mut self.imu {
                let published = timed(3, &mut || {
                    while let Some(s) = streams.imu.get(next_imu).filter(|s| s.t_s <= m.t_s) {
                        r.filter_mut().imu(&ImuSample {
                            t_s: s.t_s,
                            accel_m_s2: s.accel_m_s2,
                            gyro_rad_s: s.gyro_rad_s,
                        });
                        next_imu += 1;
                    }
                    let (t, p) = r.step(&sample)?;
                    Some((t, p, Some(r.covariance_m2())))
                });
                if published {
                    attitude.push_estimate(m.t_s, r.filter().attitude_xyzw());
                }
            }
        }
        if let Some((t, p)) = self.window.finish() {
            tracks[2].push(t, p);
        }
        Ok(Runs {
            tracks,
            walls,
            attitude,
        })
    }

    /// Each estimator's report over `measurements` range differences and
    /// `duration_s` seconds from the first at `first_s`.
    fn reports(
        &self,
        runs: &Runs,
        measurements: u64,
        duration_s: f64,
        first_s: Option<f64>,
    ) -> Vec<EstimatorReport> {
        let (tracks, walls) = (&runs.tracks, &runs.walls);
        let (ours, baseline, window) = (&self.ours, &self.baseline, &self.window);
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
        if let Some(r) = &self.imu {
            reports.push(EstimatorReport {
                guard: Some(r.counts()),
                shadow_m: shadow(r.filter().shadow_m()),
                attitude: runs.attitude.summary(),
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
        reports
    }
}

/// Scores every track against the truth (at the antenna) and gives the
/// attitude track its true attitudes.
fn score(streams: &Streams, runs: &mut Runs) {
    let mut truth = Truth::new([0.0; 3]);
    let mut refs: Vec<&mut Track> = runs.tracks.iter_mut().collect();
    for row in &streams.truth {
        truth.push(antenna(row), &mut refs);
        if let Some(q) = row.attitude_xyzw {
            runs.attitude.push_truth(row.t_s, q);
        }
    }
    truth.finish(&mut refs);
}

/// The range difference of a TDOA row, with its anchors looked up.
fn sample(
    anchors: &HashMap<u32, [f64; 3]>,
    m: &dataset::TdoaRow,
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
        a_t_s: None,
        t_s: m.t_s,
        a_m: find(m.id_a)?,
        b_m: find(m.id_b)?,
        d_m: m.d_m,
        sigma_m: MEASUREMENT_SIGMA_M,
        clocks: None,
    })
}

/// One estimator's report from its scored track.
pub(crate) fn report(
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
        tracking_after_take_off_s: None,
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
        imu_dropped: None,
        wall_s: wall.as_secs_f64(),
    }
}
