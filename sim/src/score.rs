//! Scoring as in the papers (docs/architecture.md): at each reference point, the
//! Euclidean error between the estimate and the truth; per tour the mean,
//! standard deviation and shares under 30/60/100 mm (the ICKON paper's Tables 1-2),
//! RMSE, and the heading error (the iGPS paper's Table 1); raw fixes on their own.

use serde::Serialize;

use crate::engine::{FixRecord, RunOutput};

/// One row of the table: a tour, or the mean row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Row {
    /// Tour number, from 1 (absent on the mean row).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tour: Option<u32>,
    /// Mean position error, mm.
    pub mean_mm: f64,
    /// Standard deviation of the position error, mm.
    pub std_mm: f64,
    /// Share of reference points under 30 mm, percent.
    pub under_30: f64,
    /// Share under 60 mm, percent.
    pub under_60: f64,
    /// Share under 100 mm, percent.
    pub under_100: f64,
    /// Root mean square position error, mm.
    pub rmse_mm: f64,
    /// Mean absolute heading error, degrees.
    pub heading_mean_deg: f64,
    /// Standard deviation of the signed heading error, degrees.
    pub heading_std_deg: f64,
    /// Largest absolute heading error, degrees.
    pub heading_max_deg: f64,
}

/// The score of one estimator on one route.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Score {
    /// Estimator name.
    pub estimator: String,
    /// Route name.
    pub route: String,
    /// Per tour.
    pub tours: Vec<Row>,
    /// Mean row: the mean of the tour rows (as in the ICKON paper), RMSE and heading over all points.
    pub mean: Row,
    /// Raw fixes against the truth at their own time, mm (`msu-raw` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_mean_mm: Option<f64>,
    /// RMSE of the raw fixes, mm (`msu-raw` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_rmse_mm: Option<f64>,
    /// Standard deviation of the receiver-id heading of each fix against the
    /// truth at the fix's own time, degrees (`msu-raw` only): the "absolute
    /// heading alone" of the iGPS paper's Table 1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_heading_std_deg: Option<f64>,
    /// Largest absolute receiver-id heading error of a fix, degrees (`msu-raw` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_heading_max_deg: Option<f64>,
    /// Fixes per second of simulated time (`msu-raw` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_rate_hz: Option<f64>,
    /// Mean time from a fix's measurement to its availability, ms (`msu-raw` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_latency_ms: Option<f64>,
    /// Mean error over the mean CRLB of the raw fixes (`msu-raw` and fix-fed estimators).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crlb_ratio: Option<f64>,
    /// Mean CRLB of the raw fixes, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crlb_mm: Option<f64>,
    /// Share of the scored points whose true position lies inside the 95 %
    /// ellipse of the covariance the estimator published, percent: 95 for
    /// an honest covariance, less for an overconfident one, more for a
    /// timid one. `None` when the estimator published no usable covariance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inside_95_pct: Option<f64>,
    /// The average normalised estimation error squared of the scored points
    /// (`e' P^-1 e` of the 2D position) and its two-sided 95 % bounds for
    /// that many samples ([`nees_bounds`]): inside them, the covariance is
    /// consistent with the errors. `None` as for `inside_95_pct`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nees: Option<Nees>,
}

/// Bar-Shalom's consistency test of a covariance: the average NEES of `n`
/// points and the interval it falls in 95 % of the time when the errors are
/// zero-mean Gaussians with that covariance, independent from point to
/// point (reference points are seconds apart; a filter's errors are
/// correlated over its time constant, so the interval is narrower than the
/// truth's and a value just outside it says less than it seems).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Nees {
    /// Average NEES (2 for an honest 2D covariance).
    pub mean: f64,
    /// Lower 95 % bound: `chi2(2.5 %, 2n) / n`.
    pub low: f64,
    /// Upper 95 % bound: `chi2(97.5 %, 2n) / n`.
    pub high: f64,
    /// Points averaged.
    pub samples: usize,
}

impl Nees {
    /// The test of the 2D NEES values `values`; `None` when there are none.
    pub fn of(values: &[f64]) -> Option<Self> {
        Self::of_dim(values, 2)
    }

    /// The test of NEES values of `dim`-dimensional errors (an honest
    /// covariance averages `dim`); `None` when there are none.
    pub fn of_dim(values: &[f64], dim: usize) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let n = values.len();
        let (low, high) = nees_bounds(dim, n);
        Some(Self {
            mean: values.iter().sum::<f64>() / n as f64,
            low,
            high,
            samples: n,
        })
    }

    /// Whether the average lies within its bounds.
    pub fn consistent(&self) -> bool {
        (self.low..=self.high).contains(&self.mean)
    }
}

/// The two-sided 95 % bounds of the average NEES of `samples` independent
/// `dim`-dimensional errors: the chi-square quantiles with `dim * samples`
/// degrees of freedom over `samples`, by the Wilson-Hilferty cube-root
/// approximation (relative error under 1e-3 from 10 degrees of freedom up).
pub fn nees_bounds(dim: usize, samples: usize) -> (f64, f64) {
    let k = (dim * samples.max(1)) as f64;
    let z = 1.959_963_984_540_054;
    let quantile = |z: f64| {
        let a = 2.0 / (9.0 * k);
        k * (1.0 - a + z * a.sqrt()).max(0.0).powi(3)
    };
    let n = samples.max(1) as f64;
    (quantile(-z) / n, quantile(z) / n)
}

/// The NEES `e' C^-1 e` of the error `e` (metres) under the covariance
/// `xx, xy, yy` (m^2); `None` when it is not positive definite.
pub fn nees_2d(e: [f64; 2], c: [f64; 3]) -> Option<f64> {
    let [xx, xy, yy] = c;
    let det = xx * yy - xy * xy;
    if !(xx > 0.0 && det > 0.0 && det.is_finite()) {
        return None;
    }
    Some((yy * e[0] * e[0] - 2.0 * xy * e[0] * e[1] + xx * e[1] * e[1]) / det)
}

/// The chi-square quantile of 95 % with two degrees of freedom:
/// `-2 ln 0.05`.
const CHI2_2D_95: f64 = 5.991_464_547_107_979;

/// Whether the error `e` (metres) lies inside the 95 % ellipse of the
/// covariance `xx, xy, yy` (m^2); `None` when it is not positive definite.
pub fn inside_95_ellipse(e: [f64; 2], c: [f64; 3]) -> Option<bool> {
    nees_2d(e, c).map(|d2| d2 <= CHI2_2D_95)
}

/// The row of one tour (or of any set of scored points): position errors
/// in metres and signed heading errors in radians; `ickon replay mcap`
/// scores a recording with it too.
pub fn row(tour: Option<u32>, pos_m: &[f64], head_rad: &[f64]) -> Row {
    let n = pos_m.len().max(1) as f64;
    let mean = pos_m.iter().sum::<f64>() / n;
    let var = pos_m.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
    let share = |lim: f64| 100.0 * pos_m.iter().filter(|e| **e < lim).count() as f64 / n;
    let nh = head_rad.len().max(1) as f64;
    let hmean = head_rad.iter().sum::<f64>() / nh;
    Row {
        tour,
        mean_mm: 1e3 * mean,
        std_mm: 1e3 * var.sqrt(),
        under_30: share(0.03),
        under_60: share(0.06),
        under_100: share(0.1),
        rmse_mm: 1e3 * (pos_m.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
        heading_mean_deg: (head_rad.iter().map(|h| h.abs()).sum::<f64>() / nh).to_degrees(),
        heading_std_deg: (head_rad.iter().map(|h| (h - hmean).powi(2)).sum::<f64>() / nh)
            .sqrt()
            .to_degrees(),
        heading_max_deg: head_rad
            .iter()
            .fold(0.0f64, |m, h| m.max(h.abs()))
            .to_degrees(),
    }
}

/// The 2D position CRLB (horizontal RMS, metres) of a fix from these
/// transmitters at `p_m` with range noise `sigma_range_m`
/// ([`ickon_fusion::tdoa::crlb`], the MSU height known); `None` when the
/// geometry gives no bound.
pub fn crlb_2d_m(tx_m: &[[f64; 3]], p_m: [f64; 3], sigma_range_m: f64) -> Option<f64> {
    use ickon_fusion::tdoa;
    let tx: Vec<nalgebra::Vector3<f64>> = tx_m.iter().map(|t| (*t).into()).collect();
    let mode = tdoa::Mode::TwoD { height_m: p_m[2] };
    tdoa::crlb(&tx, p_m.into(), sigma_range_m, mode)
        .ok()
        .map(|b| b.horizontal_rms_m)
        .filter(|v| v.is_finite())
}

fn fix_errors(fixes: &[FixRecord]) -> Vec<f64> {
    fixes
        .iter()
        .map(|f| (f.fix.x_m - f.truth.x_m).hypot(f.fix.y_m - f.truth.y_m))
        .collect()
}

fn fix_heading_errors(fixes: &[FixRecord]) -> Vec<f64> {
    fixes
        .iter()
        .filter(|f| f.fix.heading_valid)
        .map(|f| ickon_fusion::angle::diff(f.fix.heading_rad, f.truth.theta_rad))
        .collect()
}

/// Scores every estimator of a run.
pub fn score(out: &RunOutput, speed_of_sound_m_s: f64, height_m: f64) -> Vec<Score> {
    let fix_err = fix_errors(&out.fixes);
    let fix_head = fix_heading_errors(&out.fixes);
    let fix_head_row = (!fix_head.is_empty()).then(|| row(None, &[], &fix_head));
    let crlbs: Vec<f64> = out
        .fixes
        .iter()
        .filter_map(|f| {
            crlb_2d_m(
                &f.used_tx_m,
                [f.truth.x_m, f.truth.y_m, height_m],
                out.timing_sigma_s * speed_of_sound_m_s,
            )
        })
        .collect();
    let mean_crlb = (!crlbs.is_empty()).then(|| crlbs.iter().sum::<f64>() / crlbs.len() as f64);
    let fix_mean =
        (!fix_err.is_empty()).then(|| fix_err.iter().sum::<f64>() / fix_err.len() as f64);
    out.config
        .estimators
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let mut all_pos = Vec::new();
            let mut all_head = Vec::new();
            let mut nees: Vec<Option<f64>> = Vec::new();
            let mut tours = Vec::new();
            for tour in 1..=out.config.tours {
                let mut pos = Vec::new();
                let mut head = Vec::new();
                for r in out.refs.iter().filter(|r| r.tour == tour) {
                    // Before initialisation an estimator has no answer: count it as
                    // far off as its first answer would be unknown, i.e. skip it.
                    if let Some(e) = r.estimates[k] {
                        pos.push((e[0] - r.truth.x_m).hypot(e[1] - r.truth.y_m));
                        head.push(ickon_fusion::angle::diff(e[2], r.truth.theta_rad));
                        let c = r.covariances.get(k).copied().flatten();
                        nees.push(
                            c.and_then(|c| nees_2d([e[0] - r.truth.x_m, e[1] - r.truth.y_m], c)),
                        );
                    }
                }
                tours.push(row(Some(tour), &pos, &head));
                all_pos.extend(pos);
                all_head.extend(head);
            }
            let nt = tours.len().max(1) as f64;
            let avg = |f: fn(&Row) -> f64| tours.iter().map(f).sum::<f64>() / nt;
            let overall = row(None, &all_pos, &all_head);
            let mean = Row {
                tour: None,
                mean_mm: avg(|r| r.mean_mm),
                std_mm: avg(|r| r.std_mm),
                under_30: avg(|r| r.under_30),
                under_60: avg(|r| r.under_60),
                under_100: avg(|r| r.under_100),
                ..overall
            };
            // Only when every scored point had a covariance: a share over
            // some of them would hide the rest.
            let (inside_95_pct, nees) = consistency(&nees);
            let raw = name == "msu-raw";
            let uses_fixes = !matches!(name.as_str(), "odometry" | "cda");
            Score {
                estimator: name.clone(),
                route: out.config.route.clone(),
                tours,
                mean,
                fix_mean_mm: if raw { fix_mean.map(|v| v * 1e3) } else { None },
                fix_rmse_mm: if raw && !fix_err.is_empty() {
                    Some(
                        1e3 * (fix_err.iter().map(|e| e * e).sum::<f64>() / fix_err.len() as f64)
                            .sqrt(),
                    )
                } else {
                    None
                },
                fix_heading_std_deg: fix_head_row.filter(|_| raw).map(|r| r.heading_std_deg),
                fix_heading_max_deg: fix_head_row.filter(|_| raw).map(|r| r.heading_max_deg),
                fix_rate_hz: (raw && out.virtual_s > 0.0)
                    .then(|| out.fixes.len() as f64 / out.virtual_s),
                fix_latency_ms: (raw && !out.fixes.is_empty()).then(|| {
                    1e3 * out
                        .fixes
                        .iter()
                        .map(|f| f.available_s - f.truth.t_s)
                        .sum::<f64>()
                        / out.fixes.len() as f64
                }),
                crlb_ratio: if uses_fixes {
                    mean_crlb.map(|c| mean.mean_mm * 1e-3 / c.max(1e-12))
                } else {
                    None
                },
                crlb_mm: if uses_fixes {
                    mean_crlb.map(|c| c * 1e3)
                } else {
                    None
                },
                inside_95_pct,
                nees,
            }
        })
        .collect()
}

/// The share inside the 95 % ellipse and the NEES test of points' NEES
/// values, only when every scored point had a covariance: a share over
/// some of them would hide the rest.
pub fn consistency(nees: &[Option<f64>]) -> (Option<f64>, Option<Nees>) {
    if nees.is_empty() || !nees.iter().all(Option::is_some) {
        return (None, None);
    }
    let values: Vec<f64> = nees.iter().flatten().copied().collect();
    let inside = values.iter().filter(|d2| **d2 <= CHI2_2D_95).count();
    (
        Some(100.0 * inside as f64 / values.len() as f64),
        Nees::of(&values),
    )
}

/// How well the speed of sound the MSU used matched the air over a run
/// ([`crate::engine::AirSample`]), in percent of the true path average.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AirScore {
    /// Mean absolute error of the speed used, percent.
    pub used_mean_pct: f64,
    /// Mean absolute error of the speed used over the first minute (while
    /// the calibration starts), percent.
    pub first_minute_mean_pct: f64,
    /// Largest absolute error of the speed used after the first minute
    /// (the calibration's start), percent; `None` for a run of a minute
    /// or less.
    pub used_max_pct: Option<f64>,
    /// Mean absolute error of the site file's speed, percent: what the
    /// MSU would have made of the air without learning it.
    pub site_mean_pct: f64,
    /// Slowest and fastest true path average seen, m/s.
    pub true_range_m_s: [f64; 2],
}

impl AirScore {
    /// The score of `samples` on a site whose speed is `site_m_s`; `None`
    /// when no sample had a transmitter near.
    pub fn of(samples: &[crate::engine::AirSample], site_m_s: f64) -> Option<Self> {
        let known: Vec<(f64, f64, f64)> = samples
            .iter()
            .filter_map(|a| a.true_m_s.map(|t| (a.t_s, t, a.used_m_s)))
            .collect();
        if known.is_empty() {
            return None;
        }
        let n = known.len() as f64;
        let pct = |v: f64, t: f64| 100.0 * (v / t - 1.0).abs();
        Some(Self {
            used_mean_pct: known.iter().map(|&(_, t, u)| pct(u, t)).sum::<f64>() / n,
            first_minute_mean_pct: {
                let first: Vec<f64> = known
                    .iter()
                    .filter(|(s, _, _)| *s < 60.0)
                    .map(|&(_, t, u)| pct(u, t))
                    .collect();
                first.iter().sum::<f64>() / first.len().max(1) as f64
            },
            used_max_pct: known
                .iter()
                .filter(|(s, _, _)| *s >= 60.0)
                .map(|&(_, t, u)| pct(u, t))
                .reduce(f64::max),
            site_mean_pct: known.iter().map(|&(_, t, _)| pct(site_m_s, t)).sum::<f64>() / n,
            true_range_m_s: known.iter().fold([f64::INFINITY, 0.0], |r, &(_, t, _)| {
                [r[0].min(t), r[1].max(t)]
            }),
        })
    }
}
