//! Feeding a recording's arrivals, odometry, gyro and obstacle ranges to the
//! MSU cores ([`MsuCore`], the same code as the live agent), in recorded
//! (receive) order, and publishing a pose where the agent does
//! (`msu-agent/src/node.rs`): after every cycle that gives a fix, and after
//! every odometry sample the estimator takes.
//!
//! **Joining point.** A live agent starts listening a little after the
//! recorder (it first fetches the site and the schedule), so it never saw
//! the first recorded inputs of its robot. To replay what it saw, the
//! replay starts at the first recorded input from which the cores reproduce
//! the agent's first [`PROBE_POSES`] recorded poses bit for bit (trying each
//! input received before the agent's first pose); every later pose is then
//! compared too. Without recorded poses the replay starts at the first input.

use ickon_msu::{Event, MsuCore, MsuDriver};
use ickon_proto::decode;
use ickon_proto::keys::{Key, RobotTopic};
use ickon_proto::site::Site;
use std::sync::Arc;

use ickon_proto::msg::control::{CellStatus, CycleTrigger, Schedule, SurveyCalibration};
use ickon_proto::msg::robot::{
    Fix, Imu, ObstacleRanges, Odometry, RobotPose, Truth, UltrasoundArrivals,
};
use ickon_proto::msg::ros::PoseWithCovarianceStamped;

use super::read::{Problem, Recording};
use crate::record::channels::POSE_FRAME;

/// Poses that must match for a joining point to be taken.
pub const PROBE_POSES: usize = 20;
/// Leading gyro samples tried as unheard after the joining point.
const MAX_LATE_IMU: usize = 4;
/// Leading range samples tried as unheard after the joining point.
const MAX_LATE_RANGE: usize = 1;
/// Recorded inputs tried as the joining point, at most.
const MAX_JOIN_CANDIDATES: usize = 5_000;

/// One input of a robot's MSU, in recorded order.
#[derive(Debug, Clone)]
pub enum Input {
    /// A new schedule (the central unit's, to every robot).
    Schedule(Box<Schedule>),
    /// A cycle trigger (the central unit's, to every robot; shared, since
    /// every robot's stream holds each one).
    Trigger(Arc<CycleTrigger>),
    /// The arrivals of one cycle.
    Arrivals(UltrasoundArrivals),
    /// Wheel odometry.
    Odometry(Odometry),
    /// One gyro sample.
    Imu(Imu),
    /// Obstacle sensors.
    Range(ObstacleRanges),
    /// A cell's status (to every robot; shared like a trigger).
    CellStatus(Arc<CellStatus>),
    /// The fleet's survey calibration (to every robot; shared).
    Survey(Arc<SurveyCalibration>),
}

impl Input {
    /// Whether it comes from the central unit or a cell to every robot
    /// (not the robot's own input): never a joining point.
    fn is_control(&self) -> bool {
        matches!(
            self,
            Input::Schedule(_) | Input::Trigger(_) | Input::CellStatus(_) | Input::Survey(_)
        )
    }
}

/// Everything recorded of one robot.
#[derive(Debug, Clone, Default)]
pub struct RobotStream {
    /// Robot id.
    pub id: String,
    /// Inputs (and schedules) with their receive time, ns.
    pub inputs: Vec<(u64, Input)>,
    /// The poses its agent published (standard ROS type, CDR) with their receive time.
    pub live_poses: Vec<(u64, Vec<u8>)>,
    /// Ground truth, in recorded order (simulation only).
    pub truth: Vec<Truth>,
    /// The fixes its agent published, with their receive time.
    pub fixes: Vec<(u64, Fix)>,
}

/// Splits a recording into per-robot streams (in order of first appearance);
/// messages that do not decode are skipped and counted as a problem.
pub fn streams(rec: &Recording) -> (Vec<RobotStream>, Vec<Problem>) {
    let mut robots: Vec<RobotStream> = Vec::new();
    // The central unit's messages to every robot, with their place in the file.
    let mut control: Vec<(usize, Input)> = Vec::new();
    let mut bad = 0u64;
    fn robot<'a>(robots: &'a mut Vec<RobotStream>, id: &str) -> &'a mut RobotStream {
        if let Some(i) = robots.iter().position(|r| r.id == id) {
            &mut robots[i]
        } else {
            robots.push(RobotStream {
                id: id.to_string(),
                ..Default::default()
            });
            robots.last_mut().expect("just pushed")
        }
    }
    // Each robot's inputs with their place in the file, so that schedules
    // (to every robot) can be put between them afterwards.
    let mut placed: Vec<Vec<usize>> = Vec::new();
    for (i, m) in rec.messages.iter().enumerate() {
        let t = m.log_time_ns;
        let ok = match &m.key {
            Key::CentralSchedule => decode::<Schedule>(&m.data)
                .map(|s| control.push((i, Input::Schedule(Box::new(s)))))
                .is_ok(),
            Key::CentralCycle => decode::<CycleTrigger>(&m.data)
                .map(|c| control.push((i, Input::Trigger(Arc::new(c)))))
                .is_ok(),
            // The agent takes a status only from the cell's own key.
            Key::CellStatus(cell) => match decode::<CellStatus>(&m.data) {
                Ok(s) => {
                    if let Ok(s) = MsuCore::status_under_key(Some(cell.as_str()), s) {
                        control.push((i, Input::CellStatus(Arc::new(s))));
                    }
                    true
                }
                Err(_) => false,
            },
            Key::CentralSurvey => SurveyCalibration::decode(&m.data)
                .map(|c| control.push((i, Input::Survey(Arc::new(c)))))
                .is_ok(),
            Key::SimTruth(id) => decode::<Truth>(&m.data)
                .map(|v| robot(&mut robots, id).truth.push(v))
                .is_ok(),
            Key::Robot(id, topic) => {
                let input: Result<Option<Input>, ickon_proto::DecodeError> = match topic {
                    RobotTopic::Ultrasound => decode(&m.data).map(|v| Some(Input::Arrivals(v))),
                    RobotTopic::Odom => decode(&m.data).map(|v| Some(Input::Odometry(v))),
                    RobotTopic::Imu => decode(&m.data).map(|v| Some(Input::Imu(v))),
                    RobotTopic::Range => decode(&m.data).map(|v| Some(Input::Range(v))),
                    RobotTopic::Pose | RobotTopic::Fix => {
                        kept(robot(&mut robots, id), *topic, t, &m.data).map(|()| None)
                    }
                };
                match input {
                    Ok(Some(input)) => {
                        let k = robots.iter().position(|r| r.id == *id);
                        let r = robot(&mut robots, id);
                        r.inputs.push((t, input));
                        let k = k.unwrap_or(robots.len() - 1);
                        if placed.len() <= k {
                            placed.resize(k + 1, Vec::new());
                        }
                        placed[k].push(i);
                        true
                    }
                    Ok(None) => true,
                    Err(_) => false,
                }
            }
            _ => true,
        };
        if !ok {
            bad += 1;
        }
    }
    for (k, r) in robots.iter_mut().enumerate() {
        let places = placed.get(k).map_or(&[][..], |p| &p[..]);
        let mut merged = Vec::with_capacity(r.inputs.len() + control.len());
        let mut next = 0usize;
        for ((t, input), &at) in r.inputs.drain(..).zip(places) {
            while let Some((_, c)) = control.get(next).filter(|(ci, _)| *ci < at) {
                merged.push((t, c.clone()));
                next += 1;
            }
            merged.push((t, input));
        }
        r.inputs = merged;
    }
    let mut problems = Vec::new();
    if bad > 0 {
        problems.push(Problem(format!(
            "{bad} recorded message(s) did not decode as their channel's type and were skipped"
        )));
    }
    (robots, problems)
}

/// The agent's poses and fixes: not inputs of a replay; the poses are
/// compared with it, a conversion places each cycle by the fixes.
fn kept(
    r: &mut RobotStream,
    topic: RobotTopic,
    t: u64,
    data: &[u8],
) -> Result<(), ickon_proto::DecodeError> {
    if topic == RobotTopic::Fix {
        r.fixes.push((t, decode::<Fix>(data)?));
    } else {
        decode::<PoseWithCovarianceStamped>(data)?;
        r.live_poses.push((t, data.to_vec()));
    }
    Ok(())
}

/// A pose published by a replayed core, with the receive time of the input
/// that made it.
#[derive(Debug, Clone)]
pub struct Published {
    /// Receive time of the input, ns.
    pub log_time_ns: u64,
    /// The pose.
    pub pose: RobotPose,
}

/// Feeds `inputs[join.from..]` to `core` (after the last schedule before
/// it; the first `join.late_imu` gyro and `join.late_range` range samples
/// left out: the agent subscribes to them a moment after the others),
/// calling `publish` for every pose the live agent would have published;
/// `publish` returns `false` to stop early.
pub fn run(
    msu: &mut MsuDriver,
    inputs: &[(u64, Input)],
    join: Join,
    mut publish: impl FnMut(Published) -> bool,
) {
    let from = join.from;
    let (mut late_imu, mut late_range) = (join.late_imu, join.late_range);
    if let Some(Input::Schedule(s)) = inputs[..from.min(inputs.len())]
        .iter()
        .rev()
        .map(|(_, i)| i)
        .find(|i| matches!(i, Input::Schedule(_)))
    {
        // A schedule refused here was refused by the live agent too (same
        // rules); the driver counts it.
        msu.feed(Event::Schedule((**s).clone()));
    }
    // No trigger, status or calibration before the joining point: the
    // agent takes none before its robot's first input (whether it had
    // heard them cannot be told).
    // What the live agent refused, the replay refuses too (same rules):
    // the driver counts it.
    for (t, input) in inputs.iter().skip(from) {
        let event = match input {
            Input::Schedule(s) => Event::Schedule((**s).clone()),
            Input::Trigger(c) => Event::Trigger((**c).clone()),
            Input::CellStatus(s) => Event::CellStatus((**s).clone()),
            Input::Survey(c) => Event::Survey((**c).clone()),
            Input::Arrivals(m) => Event::Arrivals(m.clone()),
            Input::Odometry(m) => Event::Odometry(*m),
            Input::Imu(_) if late_imu > 0 => {
                late_imu -= 1;
                continue;
            }
            Input::Range(_) if late_range > 0 => {
                late_range -= 1;
                continue;
            }
            Input::Imu(m) => Event::Imu(*m),
            Input::Range(m) => Event::Range(*m),
        };
        if let Some(pose) = msu.feed(event).pose
            && !publish(Published {
                log_time_ns: *t,
                pose,
            })
        {
            return;
        }
    }
}

/// The bytes the recorder stores for a pose.
pub fn pose_bytes(pose: &RobotPose) -> Vec<u8> {
    ickon_proto::encode(&PoseWithCovarianceStamped::from_robot_pose(
        pose, POSE_FRAME,
    ))
    .unwrap_or_default()
}

/// A recorded live pose as numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LivePose {
    /// Stamp, ns on the robot's clock.
    pub stamp_ns: i64,
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub theta_rad: f64,
}

/// Decodes a recorded pose (the standard ROS type) into numbers.
pub fn live_pose(bytes: &[u8]) -> Option<LivePose> {
    let p: PoseWithCovarianceStamped = decode(bytes).ok()?;
    let q = p.pose.pose.orientation;
    Some(LivePose {
        stamp_ns: i64::from(p.header.stamp.sec) * 1_000_000_000 + i64::from(p.header.stamp.nanosec),
        x_m: p.pose.pose.position.x,
        y_m: p.pose.pose.position.y,
        theta_rad: 2.0 * q.z.atan2(q.w),
    })
}

/// How far a replayed pose is from a live one: the larger of the position
/// difference (metres) and the heading difference (radians).
pub fn difference(live: &LivePose, replayed: &RobotPose) -> f64 {
    let d_pos = (live.x_m - replayed.x_m).hypot(live.y_m - replayed.y_m);
    let d_theta = ickon_fusion::angle::diff(live.theta_rad, replayed.theta_rad).abs();
    d_pos.max(d_theta)
}

/// How a replay joined the live agent's stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Join {
    /// Index of the first input fed.
    pub from: usize,
    /// Recorded inputs of the robot before it (the agent was not listening yet).
    pub skipped_inputs: usize,
    /// Gyro samples after it the agent had not subscribed to yet.
    pub late_imu: usize,
    /// Obstacle-range samples after it the agent had not subscribed to yet.
    pub late_range: usize,
    /// Largest difference over the first poses compared (see [`difference`]).
    pub probe_difference: f64,
}

/// Finds where the live agent joined (see the module documentation): the
/// first candidate whose first [`PROBE_POSES`] poses equal the live ones
/// bit for bit, else the one closest to them.
pub fn join_point(make: &dyn Fn() -> Option<MsuCore>, stream: &RobotStream) -> Option<Join> {
    let Some(&(first_live_t, _)) = stream.live_poses.first() else {
        return Some(Join::default());
    };
    let live: Vec<(Vec<u8>, LivePose)> = stream
        .live_poses
        .iter()
        .take(PROBE_POSES)
        .filter_map(|(_, b)| Some((b.clone(), live_pose(b)?)))
        .collect();
    let want = live.len();
    let candidates = stream
        .inputs
        .iter()
        .enumerate()
        .filter(|(_, (t, i))| *t <= first_live_t && !i.is_control())
        .map(|(k, _)| k)
        .take(MAX_JOIN_CANDIDATES);
    let mut best: Option<Join> = None;
    let tries = candidates.flat_map(|from| {
        (0..=MAX_LATE_IMU).flat_map(move |late_imu| {
            (0..=MAX_LATE_RANGE).map(move |late_range| (from, late_imu, late_range))
        })
    });
    for (from, late_imu, late_range) in tries {
        let mut msu = MsuDriver::new(make()?);
        let mut k = 0usize;
        let mut exact = 0usize;
        let mut worst = 0.0f64;
        let limit = best.map_or(f64::INFINITY, |b| b.probe_difference);
        let skipped_inputs = stream.inputs[..from]
            .iter()
            .filter(|(_, i)| !i.is_control())
            .count();
        let mut join = Join {
            from,
            skipped_inputs,
            late_imu,
            late_range,
            probe_difference: 0.0,
        };
        // Paired by stamp: a live pose the replay does not make (an input
        // the recorder missed) is passed over; a replayed pose the agent did
        // not publish means the agent was not listening yet.
        run(&mut msu, &stream.inputs, join, |p| {
            let stamp = p.pose.stamp.as_nanos();
            while live.get(k).is_some_and(|(_, lp)| lp.stamp_ns < stamp) {
                k += 1;
            }
            let Some((bytes, lp)) = live.get(k) else {
                return false;
            };
            if lp.stamp_ns != stamp {
                worst = f64::INFINITY;
                return false;
            }
            k += 1;
            if *bytes == pose_bytes(&p.pose) {
                exact += 1;
            }
            worst = worst.max(difference(lp, &p.pose));
            worst < limit && k < want
        });
        if k < want {
            worst = f64::INFINITY;
        }
        join.probe_difference = worst;
        if exact == want {
            return Some(join);
        }
        if worst < limit {
            best = Some(join);
        }
    }
    best.filter(|b| b.probe_difference.is_finite())
}

/// One robot's cycles, odometry and truth on the robot's clock, as a
/// simulated run records them for export; and the cycles left out for
/// want of a schedule.
///
/// Each cycle's emission offsets are those of the trigger its MSU matched
/// it to ([`RecentTriggers::best_for`]: the central unit names the
/// transmitters of each cycle and their offsets when it fires where the
/// robots are), else of the newest schedule. As the MSU does, the match
/// takes the flight times from where the robot last had a fix: the
/// agent's last fix recorded before the cycle's arrivals (none: the
/// starts include the flight times).
pub fn recording_of(stream: &RobotStream, site: &Site) -> (ickon_sim::recording::Recording, u64) {
    use ickon_msu::cycle_match::RecentTriggers;
    use ickon_proto::epoch::ScheduleBook;
    use ickon_sim::recording::RecordedCycle;
    let mut run = ickon_sim::recording::Recording::default();
    let mut book = ScheduleBook::new();
    let mut triggers = RecentTriggers::default();
    let mut unscheduled = 0;
    let mut fixes = stream.fixes.iter().peekable();
    let mut last_fix: Option<[f64; 3]> = None;
    for (t, input) in &stream.inputs {
        while let Some((_, f)) = fixes.next_if(|(ft, _)| ft <= t) {
            last_fix = Some([f.x_m, f.y_m, f.z_m]);
        }
        match input {
            // A schedule the MSU refuses is refused here too.
            Input::Schedule(s) => _ = book.offer((**s).clone()),
            Input::Trigger(t) => triggers.note((**t).clone(), &book),
            Input::Arrivals(m) => {
                let flight_ns = |tx: u32| flight_ns(site, last_fix?, tx);
                let matched = triggers.best_for(m, &book, &flight_ns).and_then(|found| {
                    let t = found.trigger;
                    let schedule = book.get_in(t.epoch, t.schedule_version)?;
                    Some(Schedule {
                        emissions: t.emissions(schedule),
                        ..schedule.clone()
                    })
                });
                match matched.as_ref().or(book.latest()) {
                    Some(s) => run.cycles.push(RecordedCycle::of(m.seq, m, s)),
                    None => unscheduled += 1,
                }
            }
            Input::Odometry(o) => run.odometry.push(*o),
            _ => {}
        }
    }
    run.truth = stream
        .truth
        .iter()
        .map(|t| ickon_sim::world::TruthSample {
            t_s: t.robot_clock.as_secs_f64(),
            x_m: t.x_m,
            y_m: t.y_m,
            theta_rad: t.theta_rad,
        })
        .collect();
    (run, unscheduled)
}

/// The flight time from transmitter `tx` of `site` to `at`, nanoseconds.
fn flight_ns(site: &Site, at: [f64; 3], tx: u32) -> Option<i64> {
    let p = site.transmitter(tx)?.position_m;
    let d_m = ((p[0] - at[0]).powi(2) + (p[1] - at[1]).powi(2) + (p[2] - at[2]).powi(2)).sqrt();
    Some((d_m / site.speed_of_sound_m_s * 1e9).round() as i64)
}
