//! Scoring estimates against the motion-capture truth while both stream
//! in: the truth is interpolated linearly at each estimate's own time, with
//! the antenna offset applied, and only the samples still needed are kept.

use std::collections::VecDeque;

use ickon_sim::score::{Nees, inside_95_ellipse, nees_2d, nees_bounds};
use nalgebra::{Matrix3, Vector3};

use super::dataset::TruthRow;
use super::error_stats::ErrorStats;

/// Truth gaps longer than this are not interpolated across (a dropout of
/// the motion capture), seconds.
pub const MAX_TRUTH_GAP_S: f64 = 0.1;
/// Spacing of the points kept for the plots, seconds.
const PLOT_STEP_S: f64 = 0.02;
/// An estimate tracks once it is within this of the truth (the watch's
/// bound for a receiver placed elsewhere, `LostParams::disagree_m`) ...
pub const TRACKING_WITHIN_M: f64 = 0.5;
/// ... and stays so for this long, seconds.
pub const TRACKING_HOLD_S: f64 = 1.0;

/// One point of a plotted series.
#[derive(Debug, Clone, Copy)]
pub struct SeriesPoint {
    /// Time, seconds.
    pub t_s: f64,
    /// The estimate, metres.
    pub estimate_m: [f64; 3],
    /// The truth (antenna), metres.
    pub truth_m: [f64; 3],
}

/// The scored errors of one estimator.
#[derive(Debug, Clone, Default)]
pub struct Track {
    /// `(time, estimate, its covariance when the estimator has one)`.
    pending: VecDeque<(f64, [f64; 3], Option<Matrix3<f64>>)>,
    /// Time of the newest estimate queued: later ones are not older.
    newest_s: Option<f64>,
    /// Time of the first estimate.
    first_s: Option<f64>,
    /// 3D errors of the scored estimates, metres.
    errors_3d_m: ErrorStats,
    /// Sum of the NEES of the scored estimates that came with a
    /// covariance, their number, and how many lay inside the 95 %
    /// ellipsoid.
    nees_sum: f64,
    nees_n: u64,
    nees_inside: u64,
    /// Runs of consecutive scored estimates within [`TRACKING_WITHIN_M`]
    /// lasting at least [`TRACKING_HOLD_S`], `(first, last)` times: a few
    /// per flight, so that when the tracking began is known without
    /// keeping every error.
    tracking_runs: Vec<(f64, f64)>,
    /// The run going on, if the last scored estimate was within the bound.
    tracking_run: Option<(f64, f64)>,
    /// Scored estimates without a usable covariance.
    without_covariance: u64,
    /// Whether the positions are planar (a ground robot): the consistency
    /// test then takes the horizontal error and its 2x2 covariance, not a
    /// height both sides hold at the floor's.
    planar: bool,
    sum2_xy: f64,
    /// Estimates with no truth around them (before, after, or in a gap).
    pub unscored: u64,
    /// Points for the plots, when asked for.
    pub series: Option<Vec<SeriesPoint>>,
}

/// The summary of a [`Track`]: every error statistic is `None` (`null` in
/// JSON) when no estimate was scored, never a zero that reads as perfect.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Estimates scored.
    pub scored: u64,
    /// Root mean square of the 3D error, metres.
    pub rmse_3d_m: Option<f64>,
    /// Root mean square of the horizontal error, metres.
    pub rmse_xy_m: Option<f64>,
    /// Mean 3D error, metres.
    pub mean_3d_m: Option<f64>,
    /// Median 3D error, metres.
    pub median_3d_m: Option<f64>,
    /// 95th percentile of the 3D error, metres.
    pub p95_3d_m: Option<f64>,
    /// Largest 3D error, metres.
    pub max_3d_m: Option<f64>,
    /// Share of the scored estimates whose truth lies inside the 95 %
    /// ellipsoid (the ellipse, for a planar track) of the covariance the
    /// estimator published, percent (95 for an honest covariance); `None`
    /// unless every one came with one.
    pub inside_95_pct: Option<f64>,
    /// Bar-Shalom's test of that covariance: the average NEES (3 for an
    /// honest covariance, 2 for a planar track's) with its 95 % bounds;
    /// `None` as above.
    pub nees: Option<Nees>,
}

impl Track {
    /// A track, keeping plot points when `plot` is set.
    pub fn new(plot: bool) -> Self {
        Self {
            series: plot.then(Vec::new),
            ..Self::default()
        }
    }

    /// The same track scoring the covariance in the plane (2D logs).
    pub fn planar(mut self) -> Self {
        self.planar = true;
        self
    }

    /// Queues an estimate (times non-decreasing).
    pub fn push(&mut self, t_s: f64, estimate_m: [f64; 3]) {
        self.push_with(t_s, estimate_m, None);
    }

    /// Queues an estimate with the covariance its estimator published
    /// (m^2; `None`: it has none), for the consistency test.
    pub fn push_with(
        &mut self,
        t_s: f64,
        estimate_m: [f64; 3],
        covariance_m2: Option<Matrix3<f64>>,
    ) {
        self.pending.push_back((t_s, estimate_m, covariance_m2));
        self.newest_s = Some(t_s);
        self.first_s.get_or_insert(t_s);
    }

    /// Time of the first estimate, seconds.
    pub fn first_s(&self) -> Option<f64> {
        self.first_s
    }

    /// No estimate to come is older than this, given the caller's promise
    /// `floor_s` (minus infinity before the first estimate without one).
    fn needs_truth_from_s(&self, floor_s: f64) -> f64 {
        match self.pending.front() {
            Some(e) => e.0,
            None => self.newest_s.unwrap_or(f64::NEG_INFINITY).max(floor_s),
        }
    }

    /// Scores what the truth now covers; with `ended`, gives up on the rest.
    fn resolve(&mut self, truth: &VecDeque<TruthRow>, ended: bool, max_gap_s: f64) {
        let newest = truth.back().map_or(f64::NEG_INFINITY, |r| r.t_s);
        while let Some(&(t, est, cov)) = self.pending.front() {
            if t > newest && !ended {
                break;
            }
            self.pending.pop_front();
            match interpolate(truth, t, max_gap_s) {
                Some(truth_m) => self.score(t, est, cov, truth_m),
                None => self.unscored += 1,
            }
        }
    }

    fn score(&mut self, t_s: f64, est: [f64; 3], cov: Option<Matrix3<f64>>, truth_m: [f64; 3]) {
        let d: [f64; 3] = std::array::from_fn(|k| est[k] - truth_m[k]);
        let consistency = cov.and_then(|c| {
            if self.planar {
                let (e, c) = ([d[0], d[1]], [c[(0, 0)], c[(0, 1)], c[(1, 1)]]);
                Some((nees_2d(e, c)?, inside_95_ellipse(e, c)?))
            } else {
                let v = nees_3d(Vector3::from(d), &c)?;
                Some((v, v <= CHI2_3D_95))
            }
        });
        match consistency {
            Some((v, inside)) => {
                self.nees_sum += v;
                self.nees_n += 1;
                self.nees_inside += u64::from(inside);
            }
            None => self.without_covariance += 1,
        }
        let xy2 = d[0] * d[0] + d[1] * d[1];
        let error_m = (xy2 + d[2] * d[2]).sqrt();
        self.errors_3d_m.push(error_m);
        self.note_tracking(t_s, error_m);
        self.sum2_xy += xy2;
        if let Some(series) = &mut self.series
            && series.last().is_none_or(|p| t_s - p.t_s >= PLOT_STEP_S)
        {
            series.push(SeriesPoint {
                t_s,
                estimate_m: est,
                truth_m,
            });
        }
    }

    /// Extends or ends the run of estimates within the tracking bound.
    fn note_tracking(&mut self, t_s: f64, error_m: f64) {
        if error_m <= TRACKING_WITHIN_M {
            let run = self.tracking_run.get_or_insert((t_s, t_s));
            run.1 = t_s;
        } else if let Some(run) = self.tracking_run.take()
            && run.1 - run.0 >= TRACKING_HOLD_S
        {
            self.tracking_runs.push(run);
        }
    }

    /// Seconds from `from_s` to the first scored estimate from which the
    /// error stays within [`TRACKING_WITHIN_M`] for [`TRACKING_HOLD_S`]
    /// (each estimate of that stretch scored); `None` when that never
    /// happens. When `from_s` falls inside such a stretch, the stretch is
    /// taken to start at `from_s` (exact to within one estimate's spacing).
    pub fn tracking_after(&self, from_s: f64) -> Option<f64> {
        let ongoing = self
            .tracking_run
            .filter(|run| run.1 - run.0 >= TRACKING_HOLD_S);
        self.tracking_runs
            .iter()
            .chain(ongoing.iter())
            .filter(|run| run.1 >= from_s)
            .find_map(|&(first, last)| {
                let start = first.max(from_s);
                (last - start >= TRACKING_HOLD_S).then_some(start - from_s)
            })
    }

    /// The error statistics (none when nothing was scored).
    pub fn summary(&self) -> Summary {
        let n = self.errors_3d_m.len();
        if n == 0 {
            return Summary {
                scored: 0,
                rmse_3d_m: None,
                rmse_xy_m: None,
                mean_3d_m: None,
                median_3d_m: None,
                p95_3d_m: None,
                max_3d_m: None,
                inside_95_pct: None,
                nees: None,
            };
        }
        let nf = n as f64;
        // Nearest rank for the 95th percentile; the middle pair's mean for
        // an even count's median.
        let p95 = ((0.95 * nf).ceil() as u64).clamp(1, n) - 1;
        let mid = [(n - 1) / 2, n / 2];
        let at = self.errors_3d_m.at_ranks(&[mid[0], mid[1], p95]);
        let (sum, sum2) = self.errors_3d_m.sums();
        let with_covariance = self.without_covariance == 0 && self.nees_n > 0;
        Summary {
            scored: n,
            rmse_3d_m: Some((sum2 / nf).sqrt()),
            rmse_xy_m: Some((self.sum2_xy / nf).sqrt()),
            mean_3d_m: Some(sum / nf),
            median_3d_m: Some(0.5 * (at[0] + at[1])),
            p95_3d_m: Some(at[2]),
            max_3d_m: Some(self.errors_3d_m.max()),
            inside_95_pct: (self.without_covariance == 0)
                .then(|| 100.0 * self.nees_inside as f64 / nf),
            nees: with_covariance.then(|| {
                let samples = self.nees_n as usize;
                let (low, high) = nees_bounds(if self.planar { 2 } else { 3 }, samples);
                Nees {
                    mean: self.nees_sum / self.nees_n as f64,
                    low,
                    high,
                    samples,
                }
            }),
        }
    }
}

/// The 95 % quantile of the chi-square distribution with 3 degrees of
/// freedom: the 95 % ellipsoid of a 3D covariance.
const CHI2_3D_95: f64 = 7.814_727_903_251_178;

/// `e' C^-1 e`; `None` when `c` is not a covariance (not positive
/// definite, or not numbers).
fn nees_3d(e: Vector3<f64>, c: &Matrix3<f64>) -> Option<f64> {
    let chol = nalgebra::Cholesky::new(*c)?;
    let v = e.dot(&chol.solve(&e));
    v.is_finite().then_some(v)
}

/// The truth stream, shared by the tracks of every estimator.
#[derive(Debug, Clone)]
pub struct Truth {
    /// Kept samples, antenna positions.
    samples: VecDeque<TruthRow>,
    /// Added to the body centre to get the antenna, metres.
    antenna_offset_m: [f64; 3],
    /// Longest gap interpolated across, seconds.
    max_gap_s: f64,
    /// No estimate to come is older than this (the caller's promise).
    floor_s: f64,
}

impl Truth {
    /// An empty stream; `antenna_offset_m` is added to every pose.
    pub fn new(antenna_offset_m: [f64; 3]) -> Self {
        Self {
            samples: VecDeque::new(),
            antenna_offset_m,
            max_gap_s: MAX_TRUTH_GAP_S,
            floor_s: f64::NEG_INFINITY,
        }
    }

    /// Promises that no estimate to come, of any track, is older than
    /// `t_s`: the truth before it is forgotten even for a track that has
    /// published nothing yet.
    pub fn set_floor(&mut self, t_s: f64) {
        self.floor_s = self.floor_s.max(t_s);
    }

    /// The same, interpolating across gaps up to `max_gap_s` (a truth
    /// sampled more slowly than a motion capture's).
    pub fn with_max_gap_s(mut self, max_gap_s: f64) -> Self {
        self.max_gap_s = max_gap_s;
        self
    }

    /// Adds a pose, scores what it covers and forgets what is not needed.
    pub fn push(&mut self, row: TruthRow, tracks: &mut [&mut Track]) {
        let p = row.position_m;
        // Of a run of samples at one time, only the first and the last can
        // be interpolated from: a clock that stops holds two, not all.
        let n = self.samples.len();
        if n >= 2 && self.samples[n - 2].t_s == row.t_s && self.samples[n - 1].t_s == row.t_s {
            self.samples.pop_back();
        }
        self.samples.push_back(TruthRow {
            t_s: row.t_s,
            position_m: std::array::from_fn(|k| p[k] + self.antenna_offset_m[k]),
            attitude_xyzw: row.attitude_xyzw,
        });
        for track in tracks.iter_mut() {
            track.resolve(&self.samples, false, self.max_gap_s);
        }
        // Keep the last sample at or before the oldest estimate to come.
        let horizon = tracks
            .iter()
            .map(|t| t.needs_truth_from_s(self.floor_s))
            .fold(f64::INFINITY, f64::min);
        while self.samples.len() > 2 && self.samples[1].t_s <= horizon {
            self.samples.pop_front();
        }
    }

    /// The end of the file: scores or gives up on every pending estimate.
    pub fn finish(&self, tracks: &mut [&mut Track]) {
        for track in tracks.iter_mut() {
            track.resolve(&self.samples, true, self.max_gap_s);
        }
    }
}

fn interpolate(truth: &VecDeque<TruthRow>, t_s: f64, max_gap_s: f64) -> Option<[f64; 3]> {
    let i = truth.partition_point(|r| r.t_s <= t_s);
    if i == 0 {
        return None;
    }
    let r0 = truth[i - 1];
    if r0.t_s == t_s {
        return Some(r0.position_m);
    }
    let r1 = truth.get(i)?;
    let dt = r1.t_s - r0.t_s;
    if dt > max_gap_s {
        return None;
    }
    let w = (t_s - r0.t_s) / dt;
    Some(std::array::from_fn(|k| {
        r0.position_m[k] + w * (r1.position_m[k] - r0.position_m[k])
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t_s: f64, x: f64) -> TruthRow {
        TruthRow {
            t_s,
            position_m: [x, 0.0, 1.0],
            attitude_xyzw: None,
        }
    }

    #[test]
    fn tracking_starts_where_the_error_stays_small_for_the_hold() {
        let mut track = Track::new(false);
        // 1.5 m off until 1.0 s, then 0.1 m off until 3 s, one spike at
        // 1.3 s.
        for k in 0..=60 {
            let t = f64::from(k) * 0.05;
            let x = if t < 1.0 || k == 26 { 1.5 } else { 0.1 };
            track.score(t, [x, 0.0, 1.0], None, [0.0, 0.0, 1.0]);
        }
        let after = track.tracking_after(0.5).unwrap();
        assert!((after - (1.35 - 0.5)).abs() < 1e-9, "{after}");
        // From inside the stretch: at once; after its end: never.
        assert_eq!(track.tracking_after(1.5), Some(0.0));
        assert_eq!(track.tracking_after(2.5), None);
    }

    #[test]
    fn estimates_are_scored_against_the_interpolated_antenna_whichever_stream_leads() {
        let mut truth = Truth::new([0.0, 0.0, 0.1]);
        let mut track = Track::new(false);
        truth.push(row(0.0, 0.0), &mut [&mut track]);
        // Ahead of the truth: waits.
        track.push(0.05, [0.5, 0.0, 1.1]);
        track.push(0.15, [1.5, 0.0, 1.1]);
        truth.push(row(0.1, 1.0), &mut [&mut track]);
        assert_eq!(track.summary().scored, 1);
        truth.push(row(0.2, 2.0), &mut [&mut track]);
        // After the last truth: not scored.
        track.push(0.3, [3.0, 0.0, 1.1]);
        truth.finish(&mut [&mut track]);
        let s = track.summary();
        assert_eq!((s.scored, track.unscored), (2, 1));
        assert!(s.rmse_3d_m.is_some_and(|e| e < 1e-12), "{s:?}");
    }

    #[test]
    fn a_truth_whose_clock_stops_holds_two_samples_and_scores_the_last() {
        let mut truth = Truth::new([0.0; 3]);
        let mut track = Track::new(false);
        track.push(1.0, [5.0, 0.0, 1.0]);
        for k in 0..1000 {
            truth.push(row(1.0, f64::from(k)), &mut [&mut track]);
        }
        assert!(truth.samples.len() <= 2, "{}", truth.samples.len());
        track.push(1.0, [999.0, 0.0, 1.0]);
        truth.finish(&mut [&mut track]);
        // The first estimate scored at the first sample (x 0), the second
        // at the last (x 999).
        assert_eq!(track.summary().max_3d_m, Some(5.0));
    }

    #[test]
    fn statistics_match_hand_computation() {
        let mut truth = Truth::new([0.0; 3]);
        let mut track = Track::new(false);
        for k in 0..=20 {
            truth.push(row(f64::from(k) * 0.01, 0.0), &mut [&mut track]);
        }
        // Errors 3, 4 (xy) and 0.
        track.push(0.01, [3.0, 0.0, 1.0]);
        track.push(0.02, [0.0, 4.0, 1.0]);
        track.push(0.03, [0.0, 0.0, 1.0]);
        truth.finish(&mut [&mut track]);
        let s = track.summary();
        assert!((s.rmse_3d_m.unwrap() - (25.0_f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((s.mean_3d_m.unwrap() - 7.0 / 3.0).abs() < 1e-12);
        assert_eq!((s.p95_3d_m, s.max_3d_m), (Some(4.0), Some(4.0)));
    }

    #[test]
    fn the_covariance_is_tested_only_when_every_estimate_has_one() {
        let mut truth = Truth::new([0.0; 3]);
        let mut honest = Track::new(false);
        let mut tight = Track::new(false);
        let mut partial = Track::new(false);
        // Errors of 1 m along x.
        for k in 1..=4 {
            let t = f64::from(k) * 0.01;
            honest.push_with(t, [1.0, 0.0, 1.0], Some(Matrix3::identity()));
            tight.push_with(t, [1.0, 0.0, 1.0], Some(Matrix3::identity() * 0.01));
            let c = (k != 2).then(Matrix3::identity);
            partial.push_with(t, [1.0, 0.0, 1.0], c);
        }
        for k in 0..=20 {
            truth.push(
                row(f64::from(k) * 0.01, 0.0),
                &mut [&mut honest, &mut tight, &mut partial],
            );
        }
        truth.finish(&mut [&mut honest, &mut tight, &mut partial]);
        let s = honest.summary();
        assert_eq!(s.inside_95_pct, Some(100.0));
        assert!((s.nees.unwrap().mean - 1.0).abs() < 1e-12);
        let s = tight.summary();
        assert_eq!(s.inside_95_pct, Some(0.0));
        assert!((s.nees.unwrap().mean - 100.0).abs() < 1e-9);
        assert_eq!(s.nees.unwrap().samples, 4);
        let s = partial.summary();
        assert_eq!((s.scored, s.inside_95_pct, s.nees), (4, None, None));
        // A covariance that is not one (not positive definite) counts as none.
        assert!(nees_3d(Vector3::x(), &Matrix3::zeros()).is_none());
    }

    #[test]
    fn a_track_with_nothing_scored_has_no_error_statistics() {
        let mut truth = Truth::new([0.0; 3]);
        let mut track = Track::new(false);
        truth.push(row(0.0, 0.0), &mut [&mut track]);
        // Before the truth begins: not scored.
        track.push(-1.0, [0.0, 0.0, 1.0]);
        truth.finish(&mut [&mut track]);
        let s = track.summary();
        assert_eq!((s.scored, track.unscored), (0, 1));
        let json = serde_json::to_value(s).unwrap();
        for key in [
            "rmse_3d_m",
            "rmse_xy_m",
            "mean_3d_m",
            "p95_3d_m",
            "max_3d_m",
        ] {
            assert!(json[key].is_null(), "{key}: {json}");
        }
    }
}
