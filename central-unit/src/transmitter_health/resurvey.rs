//! Where a moved transmitter went, from the fleet's fixes.
//!
//! A fix that heard a transmitter and did not use it (left out, or
//! rejected by the fix's gates) reports that arrival's residual `e`
//! against the fix's position `p` and common offset
//! ([`ickon_proto::msg::robot::Fix::unused_residuals_m`]), with the
//! transmitter taken at `s`, the position the MSU solved with. The offset
//! is fitted without the transmitter, so `m = |s - p| + e` is its measured
//! range from `p` however far it moved. Its new position `x` is the
//! least-squares solution of `|x - p_j| = m_j` over many fixes from
//! different places (Gauss-Newton from `s`, Huber-weighted so that a
//! reflection does not pull it).
//!
//! The fixes of a robot the fleet's check quarantines never reach here
//! (the caller's job, as for the health counts). A robot still unchecked
//! (a fleet too small for the check) could forge a position: each robot's
//! own residuals are measured against the joint solution, and the robot
//! that disagrees most is left out and the rest solved again, as long as
//! the robots kept outnumber those left out; else nothing is published. Only a position the fixes pin down in every direction is
//! given: the receivers' places must spread in both horizontal directions
//! and each coordinate's sigma be under [`ResurveyConfig::max_sigma_m`].
//! The neighbours' positions never enter: each transmitter is re-surveyed
//! from its own arrivals alone.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector3};

/// What a re-survey takes and asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResurveyConfig {
    /// Fixes needed before a position is given.
    pub min_fixes: usize,
    /// Fixes kept, newest last (the oldest go first).
    pub max_fixes: usize,
    /// A residual beyond this is not an arrival's, metres (as a fix's
    /// used residuals, see the survey calibration's own bound).
    pub max_residual_m: f64,
    /// One-sigma error of one measured range, metres.
    pub range_sigma_m: f64,
    /// The receivers' places must spread at least this much (one sigma)
    /// along their narrowest horizontal direction, metres.
    pub min_spread_m: f64,
    /// Every coordinate's sigma must be under this, metres.
    pub max_sigma_m: f64,
    /// A robot whose median absolute residual against the joint solution
    /// is beyond this disagrees with the fleet, metres.
    pub agree_m: f64,
}

impl Default for ResurveyConfig {
    /// 40 fixes (four seconds of one robot in range; a few dozen metres of
    /// spread ranges pin a point to millimetres), the newest 400 kept, the
    /// 1 m bound of a used residual, 1 cm per range (the calibration's
    /// floor of a range's error: receivers' spread on the robot, motion in
    /// a cycle), places spread by 0.5 m at least, every coordinate to
    /// 3 cm (a tenth of the 30 cm a forklift knocks a transmitter by), and
    /// a robot's median absolute residual within 5 cm (five times a
    /// range's sigma).
    fn default() -> Self {
        Self {
            min_fixes: 40,
            max_fixes: 400,
            max_residual_m: 1.0,
            range_sigma_m: 0.01,
            min_spread_m: 0.5,
            max_sigma_m: 0.03,
            agree_m: 0.05,
        }
    }
}

/// A transmitter's new position, as the fixes place it.
#[derive(Debug, Clone, PartialEq)]
pub struct Resurveyed {
    /// Where it is, metres.
    pub position_m: [f64; 3],
    /// One-sigma uncertainty of each coordinate, metres.
    pub sigma_m: [f64; 3],
    /// Fixes behind it.
    pub fixes: usize,
    /// Robots behind it.
    pub robots: usize,
    /// RMS of the measured ranges' residuals against it, metres.
    pub rms_m: f64,
}

/// One measured range.
#[derive(Debug, Clone)]
struct Range {
    robot: String,
    receiver_m: Vector3<f64>,
    range_m: f64,
}

/// The measured ranges to one transmitter, and where the MSUs took it.
#[derive(Debug, Clone)]
pub struct Resurvey {
    config: ResurveyConfig,
    from_m: Vector3<f64>,
    ranges: std::collections::VecDeque<Range>,
}

/// A residual beyond this many range sigmas is down-weighted (Huber).
const HUBER_SIGMAS: f64 = 2.0;
/// Gauss-Newton steps at most; it converges in three or four.
const MAX_STEPS: usize = 20;
/// Steps taken with Huber's weights alone, from where the transmitter was
/// (its residuals there are the move's, decimetres), before residuals
/// beyond [`CUT_SIGMAS`] are left out.
const HUBER_ONLY_STEPS: usize = 4;
/// A residual beyond this many range sigmas, near the solution, is an
/// arrival by a reflection (the fixes' gates reject most of them, and
/// this transmitter's are rejected whatever their path): left out.
const CUT_SIGMAS: f64 = 8.0;

impl Resurvey {
    /// Nothing measured yet of a transmitter last known at `from_m` (where
    /// the solution starts from).
    pub fn new(from_m: [f64; 3], config: ResurveyConfig) -> Self {
        Self {
            config,
            from_m: Vector3::from(from_m),
            ranges: std::collections::VecDeque::new(),
        }
    }

    /// Takes one fix's residual `residual_m` of the transmitter, by robot
    /// `robot` at `receiver_m`, solved with the transmitter at `solved_at_m`
    /// (the surveyed position and the calibration's offset the fix names).
    /// A residual or place that is not a number or beyond the bounds is
    /// ignored.
    pub fn observe(
        &mut self,
        robot: &str,
        receiver_m: [f64; 3],
        solved_at_m: [f64; 3],
        residual_m: f64,
    ) {
        let p = Vector3::from(receiver_m);
        let s = Vector3::from(solved_at_m);
        let sane = residual_m.is_finite()
            && residual_m.abs() <= self.config.max_residual_m
            && p.iter().chain(s.iter()).all(|v| v.is_finite());
        if !sane {
            return;
        }
        let range_m = (s - p).norm() + residual_m;
        if range_m <= 0.0 {
            return;
        }
        if self.ranges.len() >= self.config.max_fixes.max(1) {
            self.ranges.pop_front();
        }
        self.ranges.push_back(Range {
            robot: robot.to_string(),
            receiver_m: p,
            range_m,
        });
    }

    /// Fixes held.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// The transmitter's position, if the fixes pin it down and the
    /// robots agree on it (see the module's documentation).
    pub fn estimate(&self) -> Option<Resurveyed> {
        let mut kept: Vec<&Range> = self.ranges.iter().collect();
        let robots = per_robot_rms(&kept, &self.from_m).len();
        loop {
            let solution = self.solve(&kept)?;
            let misfits = per_robot_rms(&kept, &solution.0);
            let worst = misfits
                .iter()
                .filter(|(_, rms)| **rms > self.config.agree_m)
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map(|(robot, _)| robot.to_string());
            let Some(worst) = worst else {
                return self.accept(&kept, solution);
            };
            // The robots left must still outnumber those left out.
            if 2 * (misfits.len() - 1) <= robots {
                return None;
            }
            kept.retain(|r| r.robot != worst);
        }
    }

    /// The Gauss-Newton solution over `ranges` and its information matrix
    /// (weights over the range variance), if there are enough of them
    /// spread enough.
    fn solve(&self, ranges: &[&Range]) -> Option<(Vector3<f64>, Matrix3<f64>)> {
        if ranges.len() < self.config.min_fixes || !spread_enough(ranges, self.config.min_spread_m)
        {
            return None;
        }
        let sigma = self.config.range_sigma_m.max(1e-6);
        let mut x = self.from_m;
        let mut information = Matrix3::zeros();
        for step in 0..MAX_STEPS {
            let mut normal = Matrix3::zeros();
            let mut rhs = Vector3::zeros();
            for r in ranges {
                let d = x - r.receiver_m;
                let range = d.norm();
                if range < 1e-3 {
                    return None;
                }
                let u = d / range;
                let e = r.range_m - range;
                // Once near the solution, a residual beyond the cut is a
                // reflection's, and has no say at all.
                if step >= HUBER_ONLY_STEPS && e.abs() > CUT_SIGMAS * sigma {
                    continue;
                }
                let w = huber_weight(e, sigma) / (sigma * sigma);
                normal += w * u * u.transpose();
                rhs += w * e * u;
            }
            information = normal;
            let step = normal.cholesky()?.solve(&rhs);
            x += step;
            if step.norm() < 1e-6 {
                break;
            }
        }
        x.iter().all(|v| v.is_finite()).then_some((x, information))
    }

    /// `solution` over `ranges` as published, if every coordinate is
    /// pinned down.
    fn accept(
        &self,
        ranges: &[&Range],
        (x, information): (Vector3<f64>, Matrix3<f64>),
    ) -> Option<Resurveyed> {
        let n = ranges.len() as f64;
        let rms_m = (ranges
            .iter()
            .map(|r| (r.range_m - (x - r.receiver_m).norm()).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        // The residuals' own scale when it is larger than the assumed one:
        // their median absolute value as a sigma (1.4826 of it), so that
        // the reflections left out do not inflate it.
        let mut abs: Vec<f64> = ranges
            .iter()
            .map(|r| (r.range_m - (x - r.receiver_m).norm()).abs())
            .collect();
        abs.sort_by(f64::total_cmp);
        let robust = 1.4826 * abs[abs.len() / 2];
        let scale = (robust / self.config.range_sigma_m.max(1e-6)).max(1.0);
        let covariance = information.try_inverse()? * scale * scale;
        let sigma_m: [f64; 3] = std::array::from_fn(|i| covariance[(i, i)].max(0.0).sqrt());
        if !sigma_m
            .iter()
            .all(|s| s.is_finite() && *s <= self.config.max_sigma_m)
        {
            return None;
        }
        let robots = per_robot_rms(ranges, &x).len();
        Some(Resurveyed {
            position_m: x.into(),
            sigma_m,
            fixes: ranges.len(),
            robots,
            rms_m,
        })
    }
}

/// Huber's weight of a residual `e` for a range sigma `sigma`.
fn huber_weight(e: f64, sigma: f64) -> f64 {
    let k = HUBER_SIGMAS * sigma;
    if e.abs() <= k { 1.0 } else { k / e.abs() }
}

/// Whether the receivers' places spread at least `min_m` (one sigma) along
/// their narrowest horizontal direction.
fn spread_enough(ranges: &[&Range], min_m: f64) -> bool {
    let n = ranges.len() as f64;
    let mean = ranges
        .iter()
        .map(|r| r.receiver_m.xy())
        .sum::<nalgebra::Vector2<f64>>()
        / n;
    let scatter = ranges
        .iter()
        .map(|r| {
            let d = r.receiver_m.xy() - mean;
            d * d.transpose()
        })
        .sum::<nalgebra::Matrix2<f64>>()
        / n;
    scatter
        .symmetric_eigenvalues()
        .iter()
        .all(|&v| v >= min_m * min_m)
}

/// Each robot's median absolute residual against `x`: what most of its
/// arrivals say, whatever a few reflections do.
fn per_robot_rms<'a>(ranges: &[&'a Range], x: &Vector3<f64>) -> BTreeMap<&'a str, f64> {
    let mut residuals: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for r in ranges {
        let e = r.range_m - (x - r.receiver_m).norm();
        residuals.entry(r.robot.as_str()).or_default().push(e.abs());
    }
    residuals
        .into_iter()
        .map(|(robot, mut e)| {
            e.sort_by(f64::total_cmp);
            (robot, e[e.len() / 2])
        })
        .collect()
}

#[cfg(test)]
mod tests;
