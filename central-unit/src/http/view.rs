//! What the web map shows beyond the admin status, kept as a sans-IO state
//! machine: the latest fix, fused pose and truth of every robot, a trail of
//! its fused positions, and the last burst of every cell. Fed with decoded
//! messages and the receive time, it makes the [`Snapshot`] the page draws.
//!
//! Everything it holds is bounded by the site (robots and cells it does not
//! know are counted, not kept), and a message with a number that is not
//! finite is counted and ignored, so that nothing from the network can grow
//! it or put a NaN on the page.

use std::collections::{BTreeMap, VecDeque};

use ickon_proto::msg::admin::StatusReport;
use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::{Fix, PoseStatus, RobotPose, Truth};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};
use serde::Serialize;

use crate::admin_json::{CellJson, RobotJson};

/// Fused positions kept per robot for its trail.
pub const TRAIL_POINTS: usize = 150;
/// A trail point is added at most this often (with [`TRAIL_POINTS`]: the
/// last 15 s of motion).
pub const TRAIL_SPACING: Duration = Duration::from_millis(100);
/// Truth samples kept per robot to find the one matching a pose's stamp.
const TRUTH_MEMORY: usize = 64;
/// A truth sample further than this from a pose's stamp is not compared.
const TRUTH_MATCH: Duration = Duration::from_millis(100);

/// A 2-sigma error ellipse, metres and radians (major axis from +x, counter-clockwise).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ellipse {
    /// Semi-major axis, metres.
    pub a_m: f64,
    /// Semi-minor axis, metres.
    pub b_m: f64,
    /// Angle of the major axis, radians.
    pub angle_rad: f64,
}

impl Ellipse {
    /// The 2-sigma ellipse of the 2x2 covariance `[xx, xy; xy, yy]` (m^2);
    /// `None` when it is not a covariance (negative, not finite).
    pub fn two_sigma(xx: f64, xy: f64, yy: f64) -> Option<Self> {
        if !(xx.is_finite() && xy.is_finite() && yy.is_finite()) || xx < 0.0 || yy < 0.0 {
            return None;
        }
        let mean = 0.5 * (xx + yy);
        let radius = (0.25 * (xx - yy).powi(2) + xy * xy).sqrt();
        let (l1, l2) = (mean + radius, mean - radius);
        if l2 < -1e-12 {
            return None;
        }
        Some(Self {
            a_m: 2.0 * l1.max(0.0).sqrt(),
            b_m: 2.0 * l2.max(0.0).sqrt(),
            angle_rad: 0.5 * (2.0 * xy).atan2(xx - yy),
        })
    }
}

/// A position with a heading, metres and radians.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PoseView {
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub theta_rad: f64,
}

/// The latest raw fix of a robot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FixView {
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Its 2-sigma ellipse, when the covariance is one.
    pub ellipse: Option<Ellipse>,
    /// Heading from the MSU's receivers, radians, when the fix has one.
    pub heading_rad: Option<f64>,
    /// Quality flag, as the MSU named it.
    pub quality: String,
    /// Transmitters used.
    pub used: usize,
    /// Transmitters rejected.
    pub rejected: usize,
    /// Since it arrived, milliseconds.
    pub age_ms: f64,
}

/// One robot on the map.
#[derive(Debug, Clone, Serialize)]
pub struct RobotSnapshot {
    /// What `ickon admin robots --json` says of it.
    #[serde(flatten)]
    pub health: RobotJson,
    /// Its fused pose (from its last `pose` message).
    pub fused: Option<PoseView>,
    /// The 2-sigma ellipse of the fused pose's position covariance.
    pub fused_ellipse: Option<Ellipse>,
    /// One sigma of the fused heading, radians (`None`: not a variance).
    pub fused_heading_sigma_rad: Option<f64>,
    /// What the MSU says of its inputs in the last pose (`tracking`,
    /// `no_fixes`, `no_odometry`, `localising`).
    pub pose_status: Option<&'static str>,
    /// Its latest raw fix.
    pub fix: Option<FixView>,
    /// The truth (simulation only).
    pub truth: Option<PoseView>,
    /// The truth at the fused pose's own time (simulation only).
    pub truth_at_pose: Option<PoseView>,
    /// Distance of the fused pose from the truth at the pose's time, mm.
    pub err_mm: Option<f64>,
    /// Since its last pose arrived, milliseconds (`None`: never).
    pub staleness_ms: Option<f64>,
    /// Its recent fused positions, oldest first, metres.
    pub trail: Vec<[f64; 2]>,
}

/// One cell on the map.
#[derive(Debug, Clone, Serialize)]
pub struct CellSnapshot {
    /// What `ickon admin cells --json` says of it.
    #[serde(flatten)]
    pub health: CellJson,
    /// Since its last burst arrived, milliseconds (`None`: never).
    pub last_burst_ms: Option<f64>,
    /// The transmitter of its last burst.
    pub last_tx: Option<u32>,
}

/// What the page draws, pushed to every client several times a second.
#[derive(Debug, Clone, Serialize)]
pub struct Snapshot {
    /// Site name.
    pub site: String,
    /// Last cycle triggered.
    pub cycle: u64,
    /// Whether cycle triggers are paused.
    pub paused: bool,
    /// Version of the schedule in force.
    pub schedule_version: u32,
    /// Cycles per second of the schedule in force.
    pub update_rate_hz: f64,
    /// The speed of sound the robots solve with, m/s (the learnt one, or
    /// the site file's).
    pub speed_of_sound_m_s: f64,
    /// Whether it is learnt from the fleet's fixes.
    pub speed_of_sound_learnt: bool,
    /// Transmitters left out of the fixes (dead, weak or moved), drawn red.
    pub transmitters_left_out: Vec<u32>,
    /// Every cell of the site.
    pub cells: Vec<CellSnapshot>,
    /// Every robot of the site that has been heard from.
    pub robots: Vec<RobotSnapshot>,
    /// Messages ignored: unknown robot or cell, numbers not finite.
    pub ignored_messages: u64,
    /// Web clients connected now.
    pub clients: usize,
    /// Web clients dropped because they did not keep up.
    pub clients_dropped: u64,
}

#[derive(Debug, Default)]
struct RobotState {
    pose: Option<(RobotPose, Time)>,
    fix: Option<(Fix, Time)>,
    truths: VecDeque<Truth>,
    trail: VecDeque<[f64; 2]>,
    last_trail: Option<Time>,
}

/// The web map's own state (see the module doc). Times are the receiving
/// node's clock.
#[derive(Debug, Default)]
pub struct LiveView {
    robots: BTreeMap<String, RobotState>,
    bursts: BTreeMap<String, Option<(Time, u32)>>,
    ignored: u64,
}

impl LiveView {
    /// A view of `site`: its robots and cells, nothing else.
    pub fn new(site: &Site) -> Self {
        Self {
            robots: site
                .robots
                .iter()
                .map(|r| (r.id.clone(), RobotState::default()))
                .collect(),
            bursts: BTreeMap::new(),
            ignored: 0,
        }
        .with_cells(site)
    }

    fn with_cells(mut self, site: &Site) -> Self {
        self.bursts = site.cells.iter().map(|c| (c.id.clone(), None)).collect();
        self
    }

    /// Follows a reloaded site: robots and cells it no longer has go, new ones come.
    pub fn set_site(&mut self, site: &Site) {
        self.robots
            .retain(|id, _| site.robots.iter().any(|r| &r.id == id));
        for r in &site.robots {
            self.robots.entry(r.id.clone()).or_default();
        }
        self.bursts.retain(|id, _| site.cell(id).is_some());
        for c in &site.cells {
            self.bursts.entry(c.id.clone()).or_insert(None);
        }
    }

    fn robot(&mut self, id: &str) -> Option<&mut RobotState> {
        match self.robots.get_mut(id) {
            Some(r) => Some(r),
            None => {
                self.ignored += 1;
                None
            }
        }
    }

    /// Counts a message that could not be used (undecodable, a bad key).
    pub fn ignore(&mut self) {
        self.ignored += 1;
    }

    /// A fused pose of `robot` received at `now`.
    pub fn on_pose(&mut self, robot: &str, pose: RobotPose, now: Time) {
        if !(pose.x_m.is_finite() && pose.y_m.is_finite() && pose.theta_rad.is_finite()) {
            self.ignored += 1;
            return;
        }
        let Some(r) = self.robot(robot) else { return };
        if r.last_trail
            .is_none_or(|t| now.since(t) >= TRAIL_SPACING || now < t)
        {
            if r.trail.len() == TRAIL_POINTS {
                r.trail.pop_front();
            }
            r.trail.push_back([pose.x_m, pose.y_m]);
            r.last_trail = Some(now);
        }
        r.pose = Some((pose, now));
    }

    /// A raw fix of `robot` received at `now`.
    pub fn on_fix(&mut self, robot: &str, fix: Fix, now: Time) {
        if !(fix.x_m.is_finite() && fix.y_m.is_finite()) {
            self.ignored += 1;
            return;
        }
        if let Some(r) = self.robot(robot) {
            r.fix = Some((fix, now));
        }
    }

    /// A truth sample of `robot` (simulation only).
    pub fn on_truth(&mut self, robot: &str, truth: Truth) {
        if !(truth.x_m.is_finite() && truth.y_m.is_finite() && truth.theta_rad.is_finite()) {
            self.ignored += 1;
            return;
        }
        if let Some(r) = self.robot(robot) {
            if r.truths.len() == TRUTH_MEMORY {
                r.truths.pop_front();
            }
            r.truths.push_back(truth);
        }
    }

    /// A burst report received at `now`.
    pub fn on_burst(&mut self, burst: &Burst, now: Time) {
        match self.bursts.get_mut(&burst.cell_id) {
            Some(b) => *b = Some((now, burst.tx_id)),
            None => self.ignored += 1,
        }
    }

    /// The page's picture at `now`, with the central unit's `status` and the
    /// web clients' figures.
    pub fn snapshot(
        &self,
        status: &StatusReport,
        now: Time,
        clients: usize,
        clients_dropped: u64,
    ) -> Snapshot {
        let ms = |t: Time| now.since(t).as_secs_f64() * 1e3;
        let cells = status
            .cells
            .iter()
            .map(|c| {
                let burst = self.bursts.get(&c.id).copied().flatten();
                CellSnapshot {
                    health: CellJson::from(c),
                    last_burst_ms: burst.map(|(t, _)| round(ms(t), 1.0)),
                    last_tx: burst.map(|(_, tx)| tx),
                }
            })
            .collect();
        let robots = status
            .robots
            .iter()
            .map(|h| {
                let state = self.robots.get(&h.id);
                robot_snapshot(RobotJson::from(h), state, now)
            })
            .collect();
        let speed = crate::admin_json::speed_in_use(
            status.speed_of_sound_m_s,
            status.site_speed_of_sound_m_s,
        );
        Snapshot {
            site: status.site.clone(),
            cycle: status.cycle,
            paused: status.paused,
            schedule_version: status.schedule_version,
            update_rate_hz: status.update_rate_hz,
            speed_of_sound_m_s: round(speed.0, 100.0),
            speed_of_sound_learnt: speed.1,
            transmitters_left_out: status.transmitters_left_out.clone(),
            cells,
            robots,
            ignored_messages: self.ignored,
            clients,
            clients_dropped,
        }
    }
}

/// Rounds `v` to `1 / per_unit` (keeps the pushed JSON short; dividing
/// last gives the nearest double, so 1.021 prints as 1.021).
fn round(v: f64, per_unit: f64) -> f64 {
    (v * per_unit).round() / per_unit
}

fn pose_view(x_m: f64, y_m: f64, theta_rad: f64) -> PoseView {
    PoseView {
        x_m: round(x_m, 1e3),
        y_m: round(y_m, 1e3),
        theta_rad: round(theta_rad, 1e3),
    }
}

/// The 2-sigma ellipse of the x/y block of a 3x3 row-major covariance,
/// rounded for the page.
fn rounded_ellipse(covariance: &[f64; 9]) -> Option<Ellipse> {
    Ellipse::two_sigma(covariance[0], covariance[1], covariance[4]).map(|e| Ellipse {
        a_m: round(e.a_m, 1e4),
        b_m: round(e.b_m, 1e4),
        angle_rad: round(e.angle_rad, 1e3),
    })
}

/// The name of a pose status, as the snapshot gives it.
fn pose_status_name(status: PoseStatus) -> &'static str {
    match status {
        PoseStatus::Tracking => "tracking",
        PoseStatus::NoFixes => "no_fixes",
        PoseStatus::NoOdometry => "no_odometry",
        PoseStatus::Localising => "localising",
    }
}

fn robot_snapshot(health: RobotJson, state: Option<&RobotState>, now: Time) -> RobotSnapshot {
    let ms = |t: Time| round(now.since(t).as_secs_f64() * 1e3, 1.0);
    let Some(r) = state else {
        return RobotSnapshot {
            health,
            fused: None,
            fused_ellipse: None,
            fused_heading_sigma_rad: None,
            pose_status: None,
            fix: None,
            truth: None,
            truth_at_pose: None,
            err_mm: None,
            staleness_ms: None,
            trail: Vec::new(),
        };
    };
    let fused = r
        .pose
        .as_ref()
        .map(|(p, _)| pose_view(p.x_m, p.y_m, p.theta_rad));
    let fused_ellipse = r
        .pose
        .as_ref()
        .and_then(|(p, _)| rounded_ellipse(&p.covariance));
    let fused_heading_sigma_rad = r.pose.as_ref().and_then(|(p, _)| {
        let var = p.covariance[8];
        (var.is_finite() && var >= 0.0).then(|| round(var.sqrt(), 1e5))
    });
    let pose_status = r.pose.as_ref().map(|(p, _)| pose_status_name(p.status));
    let fix = r.fix.as_ref().map(|(f, at)| FixView {
        x_m: round(f.x_m, 1e3),
        y_m: round(f.y_m, 1e3),
        ellipse: rounded_ellipse(&f.covariance),
        heading_rad: (f.heading_valid && f.heading_rad.is_finite())
            .then(|| round(f.heading_rad, 1e3)),
        quality: format!("{:?}", f.quality).to_lowercase(),
        used: f.used.len(),
        rejected: f.rejected.len(),
        age_ms: ms(*at),
    });
    let truth = r
        .truths
        .back()
        .map(|t| pose_view(t.x_m, t.y_m, t.theta_rad));
    // The truth at the pose's own time (both on the robot's clock), so that
    // a pose that is a few ms old is not charged for the motion since.
    let matched = r.pose.as_ref().and_then(|(p, _)| {
        let gap = |t: &Truth| t.robot_clock.as_nanos().abs_diff(p.stamp.as_nanos());
        let t = r.truths.iter().min_by_key(|t| gap(t))?;
        (gap(t) <= TRUTH_MATCH.as_nanos().unsigned_abs()).then_some((p, t))
    });
    let err_mm = matched.map(|(p, t)| round((p.x_m - t.x_m).hypot(p.y_m - t.y_m) * 1e3, 10.0));
    let truth_at_pose = matched.map(|(_, t)| pose_view(t.x_m, t.y_m, t.theta_rad));
    RobotSnapshot {
        health,
        fused,
        fused_ellipse,
        fused_heading_sigma_rad,
        pose_status,
        fix,
        truth,
        truth_at_pose,
        err_mm,
        staleness_ms: r.pose.as_ref().map(|(_, at)| ms(*at)),
        trail: r
            .trail
            .iter()
            .map(|p| [round(p[0], 1e3), round(p[1], 1e3)])
            .collect(),
    }
}
