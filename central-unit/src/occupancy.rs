//! Occupancy-aware firing: each cycle, only the transmitters a
//! robot can hear from somewhere it may be.
//!
//! A robot's **uncertainty region** is a disc: radius `sigma_k` times the
//! largest standard deviation of its position covariance, plus the margin,
//! plus how far it may get from the disc's centre by the end of the next
//! cycle. Without a velocity the centre is its last pose and the allowance
//! is its top speed (`max_speed_m_s`) times the pose's age and one more
//! cycle. With the mean velocity of its last poses
//! ([`crate::velocity`]) the centre is where that velocity takes it by
//! the middle of the next cycle, and the allowance is what a robot whose
//! acceleration (turns included) stays under `max_accel_m_s2` can stray
//! from it, plus the velocity's own uncertainty; the smaller of the two
//! discs is taken (both hold the robot). A transmitter fires when it is
//! within `fire_range_m` and in line of sight of a floor sample point of the
//! disc ([`firing_plan`]); a disc too small to hold a sample point takes the
//! nearest one.
//!
//! A robot that is **new** (alive, no pose yet) makes the whole schedule
//! fire: nothing is known of where it is. A **stale** robot (no pose for
//! `stale_after`) or a **lost** one (position sigma over `lost_sigma_m`)
//! gets a full sweep of its area: every transmitter within
//! `sweep_radius_m` of its last pose. When no robot is known, or the set
//! comes out empty, everything fires (the site does what it did before).
//!
//! Pure: the central unit's core calls it with the robots it tracks and
//! `now`; the result is a list of transmitter indices of the
//! [`SpacingTable`], packed by the table into the cycle.

use ickon_proto::msg::robot::RobotPose;
use ickon_proto::time::{Duration, Time};

use crate::audibility::GRID_M;
use crate::selection::{FiringHistory, Need, NeedsConfig, choose};
use crate::spacing::{NeedMatrix, Packing, Reverb, SpacingTable};
use crate::velocity::Velocity;

/// How the central unit picks the transmitters of a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FiringConfig {
    /// Fire only where robots are (`false`: every transmitter every cycle).
    pub occupancy: bool,
    /// A transmitter fires when it is this close to a robot's region, metres.
    /// 8.5 m: under the 10 m at which `paper`'s MSU still detects a burst,
    /// and on `warehouse` still 7-8 transmitters per robot (measured: 11 m
    /// gave 7.7 fixes/s for one robot, 10 m 8.6, 8.5 m 10.3, errors 17 /
    /// 10 / 14 mm).
    pub fire_range_m: f64,
    /// Standard deviations of the position covariance in the region's radius.
    pub sigma_k: f64,
    /// Added to every region's radius, metres: what the region needs beyond
    /// the robot's own uncertainty and motion.
    pub margin_m: f64,
    /// Fastest a robot drives, m/s: the region grows with the pose's age.
    pub max_speed_m_s: f64,
    /// Largest acceleration of a robot, turns included, m/s^2: how far it
    /// may stray from the course its last poses predict.
    pub max_accel_m_s2: f64,
    /// A robot without a pose for this long is stale.
    pub stale_after: Duration,
    /// A robot whose position sigma exceeds this is lost, metres.
    pub lost_sigma_m: f64,
    /// Radius of the full sweep around a stale or lost robot, metres.
    pub sweep_radius_m: f64,
    /// Fire for what each tracked robot needs ([`crate::selection`]);
    /// `None`: everything within `fire_range_m` of its region.
    pub needs: Option<NeedsConfig>,
    /// Space the plan's bursts by the room's reverberation at the points
    /// robots may be on ([`SpacingTable::needs_among`]); `None`: by the
    /// site's guard time everywhere.
    pub reverb: Option<Reverb>,
}

impl Default for FiringConfig {
    /// Every transmitter fires (`--firing all`); the other
    /// values are those `--firing occupancy` uses.
    fn default() -> Self {
        Self {
            occupancy: false,
            fire_range_m: 8.5,
            sigma_k: 3.0,
            // Half a diagonal of the floor grid (0.18 m: a robot between
            // sample points), and 0.12 m for the pose's delivery (80 ms,
            // the p99 of a live 64-robot run, at 1.5 m/s).
            margin_m: 0.3,
            max_speed_m_s: 1.5,
            // A Pioneer 3-DX (the simulated drive) at its top 1.2 m/s turning
            // at its top 1.2 rad/s: 1.44 m/s^2 sideways; it brakes and
            // speeds up at 0.5 m/s^2.
            max_accel_m_s2: 1.5,
            // Three summaries missing in a row (one every 500 ms), as
            // `crate::health::POSE_STALE_AFTER`.
            stale_after: Duration::from_millis(1_600),
            lost_sigma_m: 1.0,
            sweep_radius_m: 15.0,
            needs: None,
            reverb: None,
        }
    }
}

/// What the central unit knows of one robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RobotView<'a> {
    /// Alive, no pose received yet.
    New,
    /// Its last pose, when it was received (master time), and its mean
    /// velocity over its last poses when known.
    Seen(&'a RobotPose, Time, Option<Velocity>),
}

/// A cycle's firing plan: the transmitters packed into the cycle, the
/// spacings the packing kept, and each tracked robot's HDOP with the
/// transmitters that fire (with [`FiringConfig::needs`]; empty without).
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Where each transmitter fires, and the cycle period.
    pub packing: Packing,
    /// The spacings the packing kept.
    pub need: NeedMatrix,
    /// Per robot the choice served, the HDOP of its transmitters seen from
    /// the centre of its region.
    pub hdops: Vec<f64>,
}

/// The transmitters to fire at `now` for `robots`, packed into a cycle
/// with the spacings that packing kept, or `None` when everything must fire. `cycle` is the expected length of
/// the next cycle (the region grows by the distance driven in it).
///
/// Only the floor the robots may be on matters: a transmitter fires when
/// it is audible (within `fire_range_m`, in line of sight) at a sample
/// point of some robot's region, and two transmitters need to be spaced
/// only as far as their arrivals at those points require (bursts that
/// never meet at an occupied point do not conflict). Among equally
/// constrained transmitters the nearest to a robot go first; the packer
/// keeps that ranking unless a sweep across the floor gives a shorter
/// cycle ([`SpacingTable::pack_with`]). This is [`plan`] without
/// [`FiringConfig::needs`] and without history.
pub fn firing_plan(
    table: &SpacingTable,
    robots: &[RobotView],
    config: &FiringConfig,
    now: Time,
    cycle: Duration,
) -> Option<(Packing, NeedMatrix)> {
    let everything = FiringConfig {
        needs: None,
        reverb: None,
        ..*config
    };
    plan(
        table,
        robots,
        &everything,
        now,
        cycle,
        &FiringHistory::default(),
    )
    .map(|p| (p.packing, p.need))
}

/// The firing plan of the next cycle for `robots` at `now` (`None`: every
/// transmitter fires). With [`FiringConfig::needs`] each tracked robot
/// gets what it needs ([`crate::selection`]) instead of everything it can
/// hear; a robot too uncertain for that (fewer candidates than it needs)
/// gets everything it can hear, a stale or lost one a sweep of its area,
/// and a new one (or a pose that is not a number) makes everything fire.
/// A pose off the site's floor is ignored: it changes nothing for the
/// others. With [`FiringConfig::reverb`] the spacings follow the room's
/// reverberation at the points that matter ([`SpacingTable::needs_among`])
/// instead of the site's guard time. `history` says when each transmitter
/// last fired (the rotation).
pub fn plan(
    table: &SpacingTable,
    robots: &[RobotView],
    config: &FiringConfig,
    now: Time,
    cycle: Duration,
    history: &FiringHistory,
) -> Option<Plan> {
    if !config.occupancy || robots.is_empty() {
        return None;
    }
    let mut fire = vec![false; table.tx_ids.len()];
    // The sample points of every robot's region, marked: with a
    // thousand robots each region's points collected and sorted took most
    // of a cycle's plan.
    let mut in_region = vec![false; table.point_count()];
    // The widest fire range each point's transmitters were marked for
    // (negative: none yet).
    let mut marked = vec![-1.0f64; table.point_count()];
    let mut centres: Vec<[f64; 2]> = Vec::new();
    let mut needs: Vec<Need> = Vec::new();
    for robot in robots {
        let RobotView::Seen(pose, received, velocity) = robot else {
            return None;
        };
        if !(pose.x_m.is_finite() && pose.y_m.is_finite()) {
            return None;
        }
        let last = [pose.x_m, pose.y_m];
        if table.nearest_point(last).is_none_or(|(_, d)| d > GRID_M) {
            // Off the floor: no region of the site holds it, and what it
            // claims must not cost the others their rate.
            continue;
        }
        let age = now.since(*received).max(Duration::ZERO);
        let sigma = largest_sigma_m(pose);
        let tracked = age <= config.stale_after && sigma <= config.lost_sigma_m;
        let (centre, radius, range) = if tracked {
            let (centre, drift) = reach(last, sigma, *velocity, age, cycle, config);
            (
                centre,
                config.sigma_k * sigma + config.margin_m + drift,
                config.fire_range_m,
            )
        } else {
            (last, config.sweep_radius_m, f64::INFINITY)
        };
        let mut points = table.points_within(centre, radius);
        if points.is_empty() {
            // A disc between the sample points: the nearest one; off the
            // sampled floor: a sweep around where it was.
            points = match table.nearest_point(centre) {
                Some((p, d)) if d <= GRID_M => vec![p],
                _ => table.points_within(last, config.sweep_radius_m),
            };
        }
        let served = match (&config.needs, tracked) {
            (Some(n), true) => {
                let candidates = heard_everywhere(table, &points, range);
                (candidates.len() >= n.signals).then_some(Need { centre, candidates })
            }
            _ => None,
        };
        match served {
            Some(need) => needs.push(need),
            None => mark_heard(table, &points, range, &mut marked, &mut fire),
        }
        for &p in &points {
            in_region[p] = true;
        }
        centres.push(centre);
    }
    let hdops = match &config.needs {
        Some(n) => {
            let (chosen, hdops) = choose(table, &needs, n, history, table.msu_height_m(), now);
            for k in chosen {
                fire[k] = true;
            }
            hdops
        }
        None => Vec::new(),
    };
    let region: Vec<usize> = (0..in_region.len()).filter(|&p| in_region[p]).collect();
    let set: Vec<usize> = (0..fire.len()).filter(|&k| fire[k]).collect();
    if set.is_empty() {
        return None;
    }
    Some(packed_plan(
        table, &set, region, &centres, history, config, hdops,
    ))
}

/// Marks for firing every transmitter heard within `range_m` at one of
/// `points`. A point of many robots' regions is walked once for the widest
/// range asked of it (`marked`): the plan's time grows with the floor and
/// the fleet, not their product.
fn mark_heard(
    table: &SpacingTable,
    points: &[usize],
    range_m: f64,
    marked: &mut [f64],
    fire: &mut [bool],
) {
    for &p in points {
        if marked[p] >= range_m {
            continue;
        }
        marked[p] = range_m;
        for &(k, d) in table.heard_at(p) {
            if d <= range_m {
                fire[k] = true;
            }
        }
    }
}

/// The plan of firing `set`: the spacings needed over `region` (and, with
/// the reverberation modelled, against the previous cycle's bursts),
/// packed with the transmitters nearest the robots' `centres` first.
fn packed_plan(
    table: &SpacingTable,
    set: &[usize],
    region: Vec<usize>,
    centres: &[[f64; 2]],
    history: &FiringHistory,
    config: &FiringConfig,
    hdops: Vec<f64>,
) -> Plan {
    let need = match &config.reverb {
        Some(reverb) => {
            // The previous cycle's bursts may still be in the air when
            // this one starts: their spacings to this cycle's are needed.
            let mut spaced = set.to_vec();
            spaced.extend_from_slice(history.previous());
            table.needs_among(&spaced, region.into_iter(), reverb)
        }
        None => table.needs_over(region.into_iter()),
    };
    let nearest = |k: usize| {
        let p = table.position(k);
        centres
            .iter()
            .map(|c| {
                let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                dx * dx + dy * dy
            })
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    };
    Plan {
        packing: table.pack_with(set, &need, &nearest),
        need,
        hdops,
    }
}

/// The transmitters (table indices, ascending) heard within `range_m` at
/// every one of `points`.
fn heard_everywhere(table: &SpacingTable, points: &[usize], range_m: f64) -> Vec<usize> {
    let mut count = vec![0usize; table.tx_ids.len()];
    for &p in points {
        for &(k, d) in table.heard_at(p) {
            if d <= range_m {
                count[k] += 1;
            }
        }
    }
    (0..count.len())
        .filter(|&k| count[k] == points.len() && !points.is_empty())
        .collect()
}

/// Where a tracked robot last at `last` (largest position sigma `sigma`,
/// pose received `age` ago) may be during the next `cycle`: the centre of
/// a disc and how far from it the robot may get, metres, besides its
/// position's own uncertainty. Of the disc its top speed allows around
/// `last` and the one its velocity predicts, the smaller.
fn reach(
    last: [f64; 2],
    sigma: f64,
    velocity: Option<Velocity>,
    age: Duration,
    cycle: Duration,
    config: &FiringConfig,
) -> ([f64; 2], f64) {
    let end_s = (age + cycle).as_secs_f64();
    let anywhere = (last, config.max_speed_m_s * end_s);
    let Some(v) = velocity.filter(|v| v.speed_m_s() <= config.max_speed_m_s) else {
        return anywhere;
    };
    // The velocity is the mean over the poses' span: the robot's velocity
    // at any later instant differs from it by at most the acceleration
    // times the time since the span's middle. Integrated to the cycle's
    // end: a (t^2 / 2 + span t / 2). The two poses' errors make the
    // velocity uncertain by sqrt(2) sigma / span.
    let mid_s = age.as_secs_f64() + 0.5 * cycle.as_secs_f64();
    let centre = [last[0] + v.v_m_s[0] * mid_s, last[1] + v.v_m_s[1] * mid_s];
    let along = v.speed_m_s() * 0.5 * cycle.as_secs_f64();
    let stray = config.max_accel_m_s2 * (0.5 * end_s * end_s + 0.5 * v.span_s * end_s);
    let velocity_sigma = std::f64::consts::SQRT_2 * sigma / v.span_s;
    let predicted = (
        centre,
        along + stray + config.sigma_k * velocity_sigma * end_s,
    );
    if predicted.1.is_finite() && predicted.1 < anywhere.1 {
        predicted
    } else {
        anywhere
    }
}

/// The largest standard deviation of the pose's x-y covariance, metres
/// (infinite for a covariance that is not a number).
pub fn largest_sigma_m(pose: &RobotPose) -> f64 {
    let (a, b, d) = (pose.covariance[0], pose.covariance[1], pose.covariance[4]);
    let half_trace = 0.5 * (a + d);
    let disc = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let largest = half_trace + disc;
    if largest.is_finite() {
        largest.max(0.0).sqrt()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
pub(crate) mod tests;
