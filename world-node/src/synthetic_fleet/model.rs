//! What a fleet of MSU agents publishes, made up without a world or an
//! estimator: each robot drives its route at the route's speed, and after
//! each cycle solves a fix from the transmitters that fired and that it
//! could hear (in line of sight, within the profile's range), with
//! residuals of the profile's timing noise as a least-squares fix leaves
//! them. Pure: time comes in as seconds since the fleet started.

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};

use ickon_proto::msg::robot::{Fix, FixQuality, PoseStatus, RobotPose, RobotSummary};
use ickon_proto::site::geometry;
use ickon_proto::site::{Route, Site};
use ickon_proto::time::Time;

/// The random stream of the fixes' noise (mixed with the run's seed).
const NOISE_STREAM: u64 = 0x7379_6e74_6865_7469;

/// The fewest transmitters a fix is solved from (position, height known,
/// and the common offset take three; one more checks them), as the MSU's
/// solver needs.
const MIN_USED: usize = 4;

/// The position standard deviation each fix and pose reports, metres: the
/// order of the simulated agents' fixes on `warehouse` (about 20 mm mean
/// error, docs/performance.md).
const REPORTED_SIGMA_M: f64 = 0.02;

/// The estimator name the made-up poses carry.
pub const ESTIMATOR: &str = "synthetic";

/// The span of a summary's velocity, seconds: an agent's is the mean over
/// its last half second of poses.
const VELOCITY_SPAN_S: f64 = 0.5;

/// One made-up robot.
#[derive(Debug, Clone)]
struct Robot {
    id: String,
    /// Its route as it drives it, from its start.
    route: Route,
    length_m: f64,
    speed_m_s: f64,
    /// `arrivals_seq` of its last fix.
    fix_seq: u64,
}

/// The whole made-up fleet.
#[derive(Debug)]
pub struct SyntheticFleet {
    robots: Vec<Robot>,
    site: Site,
    /// One arrival's timing noise as a range, metres.
    range_sigma_m: f64,
    /// How far a transmitter is heard, metres.
    max_range_m: f64,
    rng: rand_chacha::ChaCha8Rng,
}

/// Why a robot could not be made up.
#[derive(Debug, thiserror::Error)]
pub enum FleetModelError {
    /// The robot is not one of the site's.
    #[error("robot {0:?} is not in the site")]
    UnknownRobot(String),
    /// Its route has no length to drive.
    #[error("robot {0:?} has no route of any length")]
    NoRoute(String),
}

impl SyntheticFleet {
    /// The robots `ids` of `site`, heard within `max_range_m` with a
    /// timing noise of `timing_sigma_s`.
    pub fn new(
        site: &Site,
        ids: &[String],
        timing_sigma_s: f64,
        max_range_m: f64,
        seed: u64,
    ) -> Result<Self, FleetModelError> {
        let robots = ids
            .iter()
            .map(|id| {
                let spec = site
                    .robots
                    .iter()
                    .find(|r| &r.id == id)
                    .ok_or_else(|| FleetModelError::UnknownRobot(id.clone()))?;
                let route = site
                    .route(&spec.route)
                    .filter(|r| r.points.len() >= 2 && r.length_m() > 0.0)
                    .ok_or_else(|| FleetModelError::NoRoute(id.clone()))?
                    .starting_near([spec.start[0], spec.start[1]]);
                Ok(Robot {
                    id: id.clone(),
                    length_m: route.length_m(),
                    speed_m_s: route.speed_m_s,
                    route,
                    fix_seq: 0,
                })
            })
            .collect::<Result<Vec<_>, FleetModelError>>()?;
        Ok(Self {
            robots,
            site: site.clone(),
            range_sigma_m: timing_sigma_s * site.speed_of_sound_m_s,
            max_range_m,
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ NOISE_STREAM),
        })
    }

    /// How many robots.
    pub fn len(&self) -> usize {
        self.robots.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.robots.is_empty()
    }

    /// Robot `i`'s id.
    pub fn id(&self, i: usize) -> &str {
        &self.robots[i].id
    }

    /// Where robot `i` is `t_s` seconds after the start: x, y (metres) and
    /// heading (radians). A closed route comes round; an open one is
    /// driven back and forth.
    pub fn position(&self, i: usize, t_s: f64) -> [f64; 3] {
        let r = &self.robots[i];
        let travelled_m = r.speed_m_s * t_s.max(0.0);
        let (s_m, forward) = if r.route.closed {
            (travelled_m.rem_euclid(r.length_m), true)
        } else {
            let lap = travelled_m.rem_euclid(2.0 * r.length_m);
            if lap <= r.length_m {
                (lap, true)
            } else {
                (2.0 * r.length_m - lap, false)
            }
        };
        let at = |s: f64| geometry::point_at_arc_length(&r.route.points, r.route.closed, s);
        let p = at(s_m);
        const STEP_M: f64 = 0.01;
        let (a, b) = if s_m + STEP_M <= r.length_m {
            (p, at(s_m + STEP_M))
        } else {
            (at(s_m - STEP_M), p)
        };
        let mut theta = (b[1] - a[1]).atan2(b[0] - a[0]);
        if !forward {
            theta = wrap(theta + std::f64::consts::PI);
        }
        [p[0], p[1], theta]
    }

    /// Robot `i`'s pose at `t_s`, stamped `stamp`.
    pub fn pose(&self, i: usize, t_s: f64, stamp: Time) -> RobotPose {
        let [x_m, y_m, theta_rad] = self.position(i, t_s);
        let v = REPORTED_SIGMA_M * REPORTED_SIGMA_M;
        RobotPose {
            stamp,
            x_m,
            y_m,
            theta_rad,
            covariance: [v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, 1e-3],
            estimator: ESTIMATOR.to_string(),
            fix_seq: self.robots[i].fix_seq,
            status: PoseStatus::Tracking,
        }
    }

    /// Robot `i`'s summary at `t_s`, stamped `stamp`: its pose, its
    /// velocity over the last half second of its route, and `fixes` of
    /// the `fixes_solved` it solved since its previous summary.
    pub fn summary(
        &self,
        i: usize,
        t_s: f64,
        stamp: Time,
        seq: u64,
        fixes_solved: u32,
        fixes: Vec<Fix>,
    ) -> RobotSummary {
        let pose = self.pose(i, t_s, stamp);
        let span_s = VELOCITY_SPAN_S.min(t_s.max(0.0));
        let before = self.position(i, t_s - span_s);
        let (vx_m_s, vy_m_s) = if span_s > 0.0 {
            (
                (pose.x_m - before[0]) / span_s,
                (pose.y_m - before[1]) / span_s,
            )
        } else {
            (0.0, 0.0)
        };
        RobotSummary {
            seq,
            stamp,
            x_m: pose.x_m,
            y_m: pose.y_m,
            theta_rad: pose.theta_rad,
            covariance: pose.covariance,
            estimator: pose.estimator,
            fix_seq: pose.fix_seq,
            status: pose.status,
            vx_m_s,
            vy_m_s,
            velocity_span_s: span_s,
            fixes_solved,
            fixes,
        }
    }

    /// Robot `i`'s fix of a cycle at `t_s` in which the transmitters
    /// `fired` fired, solved with the survey calibration `survey_version`:
    /// `None` when it heard too few of them.
    pub fn fix(
        &mut self,
        i: usize,
        t_s: f64,
        stamp: Time,
        fired: &[u32],
        survey_version: u32,
    ) -> Option<Fix> {
        let [x_m, y_m, _] = self.position(i, t_s);
        let z_m = self.site.msu.height_m;
        let receiver = [x_m, y_m, z_m];
        let mut used = Vec::new();
        let mut toward = Vec::new();
        for &id in fired {
            let Some(tx) = self.site.transmitter(id) else {
                continue;
            };
            let d = [
                tx.position_m[0] - x_m,
                tx.position_m[1] - y_m,
                tx.position_m[2] - z_m,
            ];
            let range_m = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if range_m < 1e-3
                || range_m > self.max_range_m
                || !self.site.line_of_sight(receiver, tx.position_m)
            {
                continue;
            }
            used.push(id);
            toward.push([d[0] / range_m, d[1] / range_m]);
        }
        if used.len() < MIN_USED {
            return None;
        }
        let residuals_m = self.residuals(&toward)?;
        let r = &mut self.robots[i];
        r.fix_seq += 1;
        let v = REPORTED_SIGMA_M * REPORTED_SIGMA_M;
        Some(Fix {
            stamp,
            arrivals_seq: r.fix_seq,
            x_m,
            y_m,
            z_m,
            covariance: [v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, v],
            heading_rad: 0.0,
            heading_valid: false,
            used,
            rejected: Vec::new(),
            residuals_m,
            quality: FixQuality::Good,
            survey_version,
            unused: Vec::new(),
            unused_residuals_m: Vec::new(),
        })
    }

    /// Range residuals as a least-squares fix of position and common
    /// offset leaves them: the timing noise with what the fix's own
    /// unknowns absorb taken out (`None` for a degenerate geometry).
    fn residuals(&mut self, toward: &[[f64; 2]]) -> Option<Vec<f64>> {
        let n = toward.len();
        let a = DMatrix::from_fn(n, 3, |i, k| match k {
            0 => -toward[i][0],
            1 => -toward[i][1],
            _ => 1.0,
        });
        let ata_inv = (a.transpose() * &a).try_inverse()?;
        let projector = DMatrix::identity(n, n) - &a * ata_inv * a.transpose();
        let noise = DVector::from_fn(n, |_, _| self.range_sigma_m * gaussian(&mut self.rng));
        let left = projector * noise;
        left.iter()
            .all(|v| v.is_finite())
            .then(|| left.iter().copied().collect())
    }
}

/// A standard normal draw (Box-Muller).
fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// An angle wrapped to (-pi, pi].
fn wrap(theta: f64) -> f64 {
    let t = theta.rem_euclid(std::f64::consts::TAU);
    if t > std::f64::consts::PI {
        t - std::f64::consts::TAU
    } else {
        t
    }
}

#[cfg(test)]
#[path = "model_tests.rs"]
mod tests;
