//! One replay: the file's streams read, every estimator run over them in
//! time order, each scored against the truth.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use ickon_fusion::estimator::RangeDifferenceSample;
use ickon_fusion::estimator::flight::{CvFilter, ImuFilter, ImuSample};
use ickon_fusion::estimator::guard::FlightVolume;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::attitude::AttitudeTrack;
use super::dataset::{self, InputError, Parts, TruthRow, UtilReader};
use super::estimators::{
    self, CvRunner, EkfRunner, ImuRunner, MEASUREMENT_SIGMA_M, Rejections, WindowRunner,
};
use super::imu_input;
use super::score::{Track, Truth};
use super::truth_screen::TruthScreen;

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

/// Time of take-off: the first truth sample [`TAKE_OFF_ABOVE_START_M`]
/// above the first one, watched as the truth streams by.
#[derive(Debug, Clone, Copy, Default)]
struct TakeOff {
    ground_z_m: Option<f64>,
    at_s: Option<f64>,
}

impl TakeOff {
    fn note(&mut self, row: &TruthRow) {
        let ground = *self.ground_z_m.get_or_insert(row.position_m[2]);
        if self.at_s.is_none() && row.position_m[2] >= ground + TAKE_OFF_ABOVE_START_M {
            self.at_s = Some(row.t_s);
        }
    }
}

/// Everything a replay produced.
pub(crate) struct Replayed {
    pub(crate) measurements: u64,
    pub(crate) duration_s: f64,
    pub(crate) volume: FlightVolume,
    pub(crate) reports: Vec<EstimatorReport>,
    pub(crate) tracks: Vec<Track>,
    /// Truth samples dropped as out of the vehicle's reach
    /// ([`TruthScreen`]).
    pub(crate) truth_dropped: u64,
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

/// Truth read ahead of the newest measurement, seconds: estimates wait
/// for the truth after them before they are scored.
const TRUTH_LEAD_S: f64 = 0.5;

/// Oldest an estimate can be against the measurement just fused,
/// seconds: every estimator publishes at a measurement's time, or at the
/// mean of a window of [`estimators::WINDOW_S`] (whose start it reports).
const ESTIMATE_LAG_S: f64 = 1.0;

/// Runs every estimator over the flight and scores them, streaming: the
/// TDOA, the IMU and the truth each read by a reader of its own, nothing
/// held but the estimates waiting for their truth and the truth they need.
pub(super) fn replay(args: &UtilArgs) -> Result<Replayed, InputError> {
    let anchors = dataset::read_anchors(&args.anchors, args.constellation)?;
    if args.imu && !UtilReader::open(&args.data)?.has_imu() {
        return Err(bad_input(
            args,
            "--imu needs the IMU columns (t_acc, acc_*, t_gyro, gyro_*)".into(),
        ));
    }
    let only = |tdoa, truth, imu| Parts { tdoa, truth, imu };
    let mut reader = UtilReader::open_parts(&args.data, only(true, false, false), true)?;
    let positions: Vec<[f64; 3]> = anchors.values().copied().collect();
    let volume = match args.bounds {
        Some(v) => v,
        None => FlightVolume::around(&positions, VOLUME_MARGIN_M)
            .map_err(|e| bad_input(args, e.to_string()))?,
    };
    let mut runners = Runners::new(args, &anchors, volume)?;
    let mut imu = match args.imu {
        true => Some(ImuFeed::open(&args.data)?),
        false => None,
    };
    let mut truth = TruthFeed::open(&args.data)?;
    let n_tracks = 3 + usize::from(args.imu);
    let mut runs = Runs {
        tracks: (0..n_tracks)
            .map(|_| Track::new(args.plot.is_some()))
            .collect(),
        walls: vec![Duration::ZERO; n_tracks],
        attitude: AttitudeTrack::default(),
    };
    let (mut measurements, mut span) = (0_u64, None::<(f64, f64)>);
    let (mut tdoa_rows, mut first_row_s) = (0_u32, None);
    while let Some(row) = reader.next_row()? {
        let Some(m) = row.tdoa else { continue };
        let first_row = *first_row_s.get_or_insert(m.t_s);
        if args.max_seconds.is_some_and(|max| m.t_s - first_row > max) {
            break;
        }
        let first = span.map_or(m.t_s, |s| s.0);
        let kept = tdoa_rows % args.thin == args.thin_phase;
        tdoa_rows = (tdoa_rows + 1) % args.thin;
        if !kept {
            continue;
        }
        measurements += 1;
        span = Some((first, m.t_s));
        let sample = sample(&anchors, &m, &reader, row.line)?;
        runners.step(&sample, imu.as_mut(), &mut runs)?;
        let floor = runners.window.window_start_s().unwrap_or(m.t_s).min(m.t_s) - ESTIMATE_LAG_S;
        truth.advance(m.t_s + TRUTH_LEAD_S, floor, &mut runs)?;
    }
    if let Some((t, p)) = runners.window.finish() {
        runs.tracks[2].push(t, p);
    }
    truth.advance(f64::INFINITY, f64::NEG_INFINITY, &mut runs)?;
    truth.finish(&mut runs);
    let imu_dropped = match &imu {
        Some(feed) => Some(feed.check(args)?),
        None => None,
    };
    let first_s = span.map(|s| s.0);
    let duration_s = span.map_or(0.0, |s| s.1 - s.0);
    let mut reports = runners.reports(&runs, measurements, duration_s, first_s);
    if let Some(t0) = truth.take_off.at_s {
        for (r, track) in reports.iter_mut().zip(&runs.tracks) {
            r.tracking_after_take_off_s = track.tracking_after(t0);
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
        truth_dropped: truth.screen.dropped,
    })
}

/// The IMU stream, screened as it is read.
struct ImuFeed {
    reader: UtilReader,
    screen: imu_input::Screen,
    next: Option<dataset::ImuRow>,
    ended: bool,
}

impl ImuFeed {
    fn open(path: &std::path::Path) -> Result<Self, InputError> {
        let parts = Parts {
            tdoa: false,
            truth: false,
            imu: true,
        };
        Ok(Self {
            reader: UtilReader::open_parts(path, parts, false)?,
            screen: imu_input::Screen::default(),
            next: None,
            ended: false,
        })
    }

    /// The next kept sample stamped at or before `t_s`.
    fn next_until(&mut self, t_s: f64) -> Result<Option<dataset::ImuRow>, InputError> {
        while self.next.is_none() && !self.ended {
            match self.reader.next_row()? {
                Some(row) => {
                    if let Some(s) = row.imu {
                        self.next = self.screen.push(s);
                    }
                }
                None => {
                    self.ended = true;
                    self.next = self.screen.finish();
                }
            }
        }
        match self.next {
            Some(s) if s.t_s <= t_s => {
                self.next = None;
                Ok(Some(s))
            }
            _ => Ok(None),
        }
    }

    /// What was dropped; an error when nothing was usable.
    fn check(&self, args: &UtilArgs) -> Result<imu_input::ImuDropped, InputError> {
        let s = &self.screen;
        if s.kept == 0 && self.ended {
            return Err(bad_input(
                args,
                format!(
                    "--imu: the file has no usable IMU sample ({} read, {} dropped: {:?})",
                    s.read,
                    s.dropped.total(),
                    s.dropped
                ),
            ));
        }
        Ok(s.dropped)
    }
}

/// The truth stream, read as far as the estimates need it.
struct TruthFeed {
    reader: UtilReader,
    truth: Truth,
    next: Option<TruthRow>,
    ended: bool,
    take_off: TakeOff,
    screen: TruthScreen,
}

impl TruthFeed {
    fn open(path: &std::path::Path) -> Result<Self, InputError> {
        let parts = Parts {
            tdoa: false,
            truth: true,
            imu: false,
        };
        Ok(Self {
            reader: UtilReader::open_parts(path, parts, false)?,
            truth: Truth::new([0.0; 3]),
            next: None,
            ended: false,
            take_off: TakeOff::default(),
            screen: TruthScreen::default(),
        })
    }

    /// Scores with the truth up to `until_s`; no estimate to come is
    /// older than `floor_s`.
    fn advance(&mut self, until_s: f64, floor_s: f64, runs: &mut Runs) -> Result<(), InputError> {
        self.truth.set_floor(floor_s);
        runs.attitude.set_floor(floor_s);
        loop {
            while self.next.is_none() && !self.ended {
                match self.reader.next_row()? {
                    Some(row) => self.next = row.truth,
                    None => self.ended = true,
                }
            }
            match self.next {
                Some(row) if row.t_s <= until_s && !self.screen.keep(&row) => self.next = None,
                Some(row) if row.t_s <= until_s => {
                    self.take_off.note(&row);
                    let mut refs: Vec<&mut Track> = runs.tracks.iter_mut().collect();
                    self.truth.push(antenna(&row), &mut refs);
                    if let Some(q) = row.attitude_xyzw {
                        runs.attitude.push_truth(row.t_s, q);
                    }
                    self.next = None;
                }
                _ => return Ok(()),
            }
        }
    }

    /// The end of the truth: scores or gives up on every pending estimate.
    fn finish(&mut self, runs: &mut Runs) {
        let mut refs: Vec<&mut Track> = runs.tracks.iter_mut().collect();
        self.truth.finish(&mut refs);
        runs.attitude.finish();
    }
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

    /// Feeds one range difference to every estimator (the IMU filter
    /// gets the IMU samples up to its time first), timing each.
    fn step(
        &mut self,
        sample: &RangeDifferenceSample,
        imu: Option<&mut ImuFeed>,
        runs: &mut Runs,
    ) -> Result<(), InputError> {
        let Runs {
            tracks,
            walls,
            attitude,
        } = runs;
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
            let (t, p) = ours.step(sample)?;
            Some((t, p, Some(ours.covariance_m2())))
        });
        let baseline = &mut self.baseline;
        timed(1, &mut || {
            let (t, p) = baseline.step(sample)?;
            Some((t, p, baseline.covariance_m2()))
        });
        let window = &mut self.window;
        timed(2, &mut || window.step(sample).map(|(t, p)| (t, p, None)));
        if let (Some(r), Some(feed)) = (&mut self.imu, imu) {
            // Only the filter's time counts, not the reading of the file.
            let mut fed = Duration::ZERO;
            while let Some(s) = feed.next_until(sample.t_s)? {
                let t0 = Instant::now();
                r.filter_mut().imu(&ImuSample {
                    t_s: s.t_s,
                    accel_m_s2: s.accel_m_s2,
                    gyro_rad_s: s.gyro_rad_s,
                });
                fed += t0.elapsed();
            }
            let published = timed(3, &mut || {
                let (t, p) = r.step(sample)?;
                Some((t, p, Some(r.covariance_m2())))
            });
            walls[3] += fed;
            if published {
                attitude.push_estimate(sample.t_s, r.filter().attitude_xyzw());
            }
        }
        Ok(())
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
        speed_rel_sigma: None,
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
