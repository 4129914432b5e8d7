//! What `ickon sim` measures while the mesh runs: pose error against truth,
//! fix and pose counts, arrival-to-pose latency, and what each cell fired.
//! Pure bookkeeping, fed by the launcher's subscribers.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::time::Instant;

use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::{PoseStatus, RobotPose, Truth};
use ickon_proto::time::Time;
use serde::Serialize;

/// How much truth history is kept per robot to interpolate at pose stamps.
const TRUTH_HISTORY: usize = 2_000;
/// Arrival messages remembered per robot to match poses to (latency).
const ARRIVALS_REMEMBERED: usize = 256;
/// Truth is extrapolated at most this far past its newest sample, seconds.
const MAX_EXTRAPOLATION_S: f64 = 0.05;
/// Poses in the first seconds of a run are not scored: estimators start from
/// the configured pose and need a few fixes to converge.
pub const WARM_UP_S: f64 = 3.0;

/// The `p`-th percentile (0..=100) of `values` by nearest rank; `None` when empty.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    Some(sorted[rank.clamp(1, sorted.len()) - 1])
}

/// Events per second over the last [`RecentRate::WINDOW_S`] seconds, for
/// the status line.
#[derive(Debug, Default)]
pub struct RecentRate {
    times: VecDeque<Instant>,
}

impl RecentRate {
    /// The window, seconds.
    pub const WINDOW_S: f64 = 2.0;

    /// Notes one event at `at`.
    pub fn note(&mut self, at: Instant) {
        self.times.push_back(at);
        while self
            .times
            .front()
            .is_some_and(|t| at.duration_since(*t).as_secs_f64() > Self::WINDOW_S)
        {
            self.times.pop_front();
        }
    }

    /// Events per second over the window.
    pub fn per_s(&self) -> f64 {
        self.times.len() as f64 / Self::WINDOW_S
    }
}

/// Measurements of one robot.
#[derive(Debug, Default)]
pub struct RobotStats {
    truth: VecDeque<Truth>,
    arrivals_seen: VecDeque<(u64, Instant)>,
    latest_fix_seq_scored: u64,
    first_pose_stamp: Option<Time>,
    /// Fixes received.
    pub fixes: u64,
    /// Poses received.
    pub poses: u64,
    /// Arrival messages received.
    pub arrival_messages: u64,
    /// Poses its MSU published as not yet confirmed by a fix.
    pub localising_poses: u64,
    errors_m: Vec<f64>,
    /// The NEES of each scored pose under the covariance it was published
    /// with (`None`: not positive definite).
    nees: Vec<Option<f64>>,
    /// Errors of the positions the robot's ranging kit reported itself.
    kit_errors_m: Vec<f64>,
    first_kit_stamp: Option<Time>,
    latencies_us: Vec<f64>,
    /// Error of the newest scored pose, metres.
    pub current_error_m: Option<f64>,
    fix_rate: RecentRate,
    last_fix_at: Option<Instant>,
    longest_fix_gap_s: Option<f64>,
    /// Signals the fixes used, added up.
    signals_used: u64,
    /// HDOPs of the signals of the fixes that had one, added up, and their count.
    hdop_sum: f64,
    hdops: u64,
}

impl RobotStats {
    /// Records a truth sample.
    pub fn on_truth(&mut self, truth: Truth) {
        if self.truth.len() == TRUTH_HISTORY {
            self.truth.pop_front();
        }
        self.truth.push_back(truth);
    }

    /// Records an arrival message received at `at`.
    pub fn on_arrivals(&mut self, seq: u64, at: Instant) {
        self.arrival_messages += 1;
        if self.arrivals_seen.len() == ARRIVALS_REMEMBERED {
            self.arrivals_seen.pop_front();
        }
        self.arrivals_seen.push_back((seq, at));
    }

    /// Records a fix received at `at`.
    pub fn on_fix(&mut self, at: Instant) {
        self.fixes += 1;
        if let Some(last) = self.last_fix_at {
            let gap = at.duration_since(last).as_secs_f64();
            self.longest_fix_gap_s = Some(self.longest_fix_gap_s.map_or(gap, |g| g.max(gap)));
        }
        self.last_fix_at = Some(at);
        self.fix_rate.note(at);
    }

    /// Records how many signals a fix used and their HDOP at the fix
    /// (`None`: no fix geometry, or transmitters the site does not know).
    pub fn on_fix_geometry(&mut self, used: usize, hdop: Option<f64>) {
        self.signals_used += used as u64;
        if let Some(h) = hdop.filter(|h| h.is_finite()) {
            self.hdop_sum += h;
            self.hdops += 1;
        }
    }

    /// Fixes per second over the last two seconds.
    pub fn fixes_per_s(&self) -> f64 {
        self.fix_rate.per_s()
    }

    /// Records a pose received at `at`: scores it against the truth at its
    /// stamp, and the latency from the arrivals of its newest fix.
    pub fn on_pose(&mut self, pose: &RobotPose, at: Instant) {
        self.poses += 1;
        let first = *self.first_pose_stamp.get_or_insert(pose.stamp);
        if pose.fix_seq > self.latest_fix_seq_scored {
            self.latest_fix_seq_scored = pose.fix_seq;
            if let Some((_, t)) = self.arrivals_seen.iter().find(|(s, _)| *s == pose.fix_seq) {
                self.latencies_us
                    .push(at.duration_since(*t).as_secs_f64() * 1e6);
            }
        }
        // A pose its MSU says is a guess (no fix has confirmed it since a
        // restart) is counted apart, not scored: nothing may steer by it.
        let confirmed = pose.status != PoseStatus::Localising;
        self.localising_poses += u64::from(!confirmed);
        if let Some((x, y)) = self.truth_at(pose.stamp) {
            let err = ((pose.x_m - x).powi(2) + (pose.y_m - y).powi(2)).sqrt();
            self.current_error_m = Some(err);
            if confirmed && pose.stamp.since(first).as_secs_f64() >= WARM_UP_S {
                self.errors_m.push(err);
                let c = pose.covariance;
                self.nees.push(ickon_sim::score::nees_2d(
                    [pose.x_m - x, pose.y_m - y],
                    [c[0], c[1], c[4]],
                ));
            }
        }
    }

    /// Records a position the robot's ranging kit reported (on the
    /// truth's layout): scored against the truth at its instant, after the
    /// same warm-up as the poses.
    pub fn on_kit_position(&mut self, kit: &Truth) {
        let first = *self.first_kit_stamp.get_or_insert(kit.robot_clock);
        if let Some((x, y)) = self.truth_at(kit.robot_clock)
            && kit.robot_clock.since(first).as_secs_f64() >= WARM_UP_S
        {
            self.kit_errors_m
                .push(((kit.x_m - x).powi(2) + (kit.y_m - y).powi(2)).sqrt());
        }
    }

    /// Truth position at `stamp` on the robot's clock, interpolated; `None`
    /// outside the kept history.
    fn truth_at(&self, stamp: Time) -> Option<(f64, f64)> {
        let idx = self.truth.partition_point(|t| t.robot_clock <= stamp);
        let a = self.truth.get(idx.checked_sub(1)?)?;
        let Some(b) = self.truth.get(idx) else {
            // Newer than the newest truth (the pose and the truth of one
            // instant race over the mesh): extrapolate briefly along the motion.
            let dt = stamp.since(a.robot_clock).as_secs_f64();
            if dt > MAX_EXTRAPOLATION_S {
                return None;
            }
            let d = a.v_m_s * dt;
            return Some((a.x_m + d * a.theta_rad.cos(), a.y_m + d * a.theta_rad.sin()));
        };
        let span = b.robot_clock.since(a.robot_clock).as_nanos();
        if span <= 0 || span > 1_000_000_000 {
            return None;
        }
        let w = stamp.since(a.robot_clock).as_nanos() as f64 / span as f64;
        Some((a.x_m + w * (b.x_m - a.x_m), a.y_m + w * (b.y_m - a.y_m)))
    }

    /// The summary of this robot; `cycles`: the cycles triggered and over
    /// while the run was watched.
    pub fn summary(&self, id: &str, cycles: usize, watched_s: f64) -> RobotSummary {
        let n = self.errors_m.len() as f64;
        let share = |count: u64| (cycles > 0).then(|| (count as f64 / cycles as f64).min(1.0));
        let mean = (n > 0.0).then(|| self.errors_m.iter().sum::<f64>() / n);
        let rmse = (n > 0.0).then(|| (self.errors_m.iter().map(|e| e * e).sum::<f64>() / n).sqrt());
        let kit = &self.kit_errors_m;
        let k = kit.len() as f64;
        let (inside_95_pct, nees) = ickon_sim::score::consistency(&self.nees);
        RobotSummary {
            inside_95_pct,
            nees,
            kit_positions: kit.len() as u64,
            kit_mean_mm: (k > 0.0).then(|| kit.iter().sum::<f64>() / k * 1e3),
            kit_rmse_mm: (k > 0.0)
                .then(|| (kit.iter().map(|e| e * e).sum::<f64>() / k).sqrt() * 1e3),
            kit_p95_mm: percentile(kit, 95.0).map(|m| m * 1e3),
            id: id.to_string(),
            fixes: self.fixes,
            fixes_per_s: (watched_s > 0.0).then(|| self.fixes as f64 / watched_s),
            signals_per_fix: (self.fixes > 0).then(|| self.signals_used as f64 / self.fixes as f64),
            fix_hdop: (self.hdops > 0).then(|| self.hdop_sum / self.hdops as f64),
            poses: self.poses,
            arrival_messages: self.arrival_messages,
            arrivals_share: share(self.arrival_messages),
            fix_share: share(self.fixes),
            scored_poses: self.errors_m.len() as u64,
            localising_poses: self.localising_poses,
            mean_mm: mean.map(|m| m * 1e3),
            rmse_mm: rmse.map(|m| m * 1e3),
            p95_mm: percentile(&self.errors_m, 95.0).map(|m| m * 1e3),
            latency_p50_us: percentile(&self.latencies_us, 50.0),
            latency_p99_us: percentile(&self.latencies_us, 99.0),
            longest_fix_gap_s: self.longest_fix_gap_s,
        }
    }
}

/// A cycle: the central unit's epoch and the cycle number in it (a
/// restarted central unit counts from 0 again).
pub type CycleKey = (u64, u64);

/// What each cell fired.
#[derive(Debug, Default)]
pub struct CellStats {
    cycles: BTreeSet<CycleKey>,
    bursts: u64,
    sync_errors_us: Vec<f64>,
}

impl CellStats {
    /// Records a burst report.
    pub fn on_burst(&mut self, burst: &Burst) {
        self.bursts += 1;
        self.cycles.insert((burst.epoch, burst.cycle));
        let err_ns = burst.actual.as_nanos() - burst.scheduled.as_nanos();
        self.sync_errors_us.push(err_ns.unsigned_abs() as f64 / 1e3);
    }

    /// Cycles in which the cell fired.
    pub fn cycles_fired(&self) -> u64 {
        self.cycles.len() as u64
    }

    /// The summary of this cell; `completed`: the cycles triggered and
    /// over while the run was watched.
    pub fn summary(&self, id: &str, completed: &BTreeSet<CycleKey>) -> CellSummary {
        let fired = completed.intersection(&self.cycles).count();
        CellSummary {
            id: id.to_string(),
            cycles_missed: (completed.len() - fired) as u64,
            fired_share: (!completed.is_empty()).then(|| fired as f64 / completed.len() as f64),
            cycles_fired: self.cycles_fired(),
            bursts: self.bursts,
            sync_error_us: percentile(&self.sync_errors_us, 99.0),
            sync_error_max_us: self.sync_errors_us.iter().copied().reduce(f64::max),
        }
    }
}

/// One robot in the run summary.
#[derive(Debug, Clone, Serialize)]
pub struct RobotSummary {
    /// Robot id.
    pub id: String,
    /// Fixes received.
    pub fixes: u64,
    /// Of those, per second of the run.
    pub fixes_per_s: Option<f64>,
    /// Mean number of signals (arrivals) a fix used.
    pub signals_per_fix: Option<f64>,
    /// Mean HDOP of the transmitters each fix used, seen from the fix.
    pub fix_hdop: Option<f64>,
    /// Poses received.
    pub poses: u64,
    /// Ultrasound arrival messages received (one per cycle heard).
    pub arrival_messages: u64,
    /// Arrival messages per cycle triggered while watched (at most 1).
    pub arrivals_share: Option<f64>,
    /// Fixes per cycle triggered while watched (at most 1).
    pub fix_share: Option<f64>,
    /// Poses scored against truth (after the warm-up; only those a fix
    /// has confirmed).
    pub scored_poses: u64,
    /// Poses published as `Localising` (not yet confirmed by a fix: the
    /// start pose of a restarted MSU), not scored.
    pub localising_poses: u64,
    /// Mean position error, mm.
    pub mean_mm: Option<f64>,
    /// Root-mean-square position error, mm.
    pub rmse_mm: Option<f64>,
    /// 95th percentile of the position error, mm.
    pub p95_mm: Option<f64>,
    /// Median latency from the arrivals being published to the pose using them, us.
    pub latency_p50_us: Option<f64>,
    /// 99th percentile of that latency, us.
    pub latency_p99_us: Option<f64>,
    /// Longest time between two fixes received, seconds.
    pub longest_fix_gap_s: Option<f64>,
    /// Positions the robot's ranging kit reported itself, scored (0
    /// without a kit).
    pub kit_positions: u64,
    /// Their mean error, mm: the kit as an estimator of its own.
    pub kit_mean_mm: Option<f64>,
    /// Their root-mean-square error, mm.
    pub kit_rmse_mm: Option<f64>,
    /// Share of the scored poses whose truth lies inside the 95 % ellipse
    /// of the covariance published with them, percent (`None`: a pose had
    /// no usable covariance).
    pub inside_95_pct: Option<f64>,
    /// Their average NEES and its 95 % bounds (Bar-Shalom's test).
    pub nees: Option<ickon_sim::score::Nees>,
    /// The 95th percentile of their error, mm.
    pub kit_p95_mm: Option<f64>,
}

/// One cell in the run summary.
#[derive(Debug, Clone, Serialize)]
pub struct CellSummary {
    /// Cell id.
    pub id: String,
    /// Cycles in which it fired.
    pub cycles_fired: u64,
    /// Cycles triggered (and over) while the run was watched in which it
    /// was to fire (the whole schedule, or named by the trigger) and did not.
    pub cycles_missed: u64,
    /// Share of the cycles triggered (and over) while the run was watched,
    /// in which it was to fire, in which it fired.
    pub fired_share: Option<f64>,
    /// Bursts it fired.
    pub bursts: u64,
    /// 99th percentile of |actual - scheduled| emission time, us.
    pub sync_error_us: Option<f64>,
    /// Largest |actual - scheduled| emission time, us.
    pub sync_error_max_us: Option<f64>,
}

/// Everything measured in one run.
#[derive(Debug, Default)]
pub struct RunStats {
    /// Per robot, by id.
    pub robots: BTreeMap<String, RobotStats>,
    /// Per cell, by id.
    pub cells: BTreeMap<String, CellStats>,
    /// One-hop Zenoh latencies measured alongside, us.
    pub hop_latencies_us: Vec<f64>,
    /// Messages that could not be decoded, per key (at most
    /// [`BAD_MESSAGE_KEYS`] keys; the rest under [`OTHER_KEYS`]).
    pub bad_messages: HashMap<String, u64>,
    /// The log budget of undecodable messages, per message type.
    pub bad_log: ickon_runtime::LogLimiter<&'static str>,
    /// Cycles the central unit triggered while the run was watched.
    pub cycles_triggered: BTreeSet<CycleKey>,
    /// Nodes restarted after they died (`--restart`), by name.
    pub restarts: Vec<String>,
    /// Faults injected (`--faults`), as planned and when they were done, seconds.
    pub faults_done: Vec<(String, f64)>,
    /// Cycle triggers per second lately, for the status line.
    pub trigger_rate: RecentRate,
    /// Transmitters the newest trigger named (`None`: the whole schedule).
    pub last_firing: Option<usize>,
    /// Which cell each transmitter hangs in (from the site), to know which
    /// cells a trigger naming transmitters asks to fire.
    pub tx_cells: HashMap<u32, String>,
    /// Per cell, the cycles whose trigger named some of its transmitters.
    pub named_cycles: BTreeMap<String, BTreeSet<CycleKey>>,
    /// Cycles whose trigger named none: the whole schedule fires.
    pub whole_schedule_cycles: BTreeSet<CycleKey>,
    /// Where each transmitter hangs (from the site), for the HDOP of a fix.
    pub tx_positions: HashMap<u32, [f64; 3]>,
    /// Height of the MSUs, metres.
    pub msu_height_m: f64,
    /// Triggers that named their transmitters.
    pub named_triggers: u64,
    /// Transmitters those named, distinct emission times (slots) and
    /// periods (seconds), added up.
    pub named_sums: (u64, u64, f64),
}

/// What the triggers that named their transmitters fired, on average.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlanSummary {
    /// Transmitters per cycle.
    pub transmitters_per_cycle: f64,
    /// Distinct emission times (slots) per cycle.
    pub slots_per_cycle: f64,
    /// Cycle period over its slots, ms.
    pub mean_slot_ms: f64,
}

/// Keys whose undecodable messages are counted apart: forged puts may
/// name any number of keys under a wildcard, and must not grow the count.
pub const BAD_MESSAGE_KEYS: usize = 64;
/// Where undecodable messages of further keys are counted.
pub const OTHER_KEYS: &str = "(other keys)";

impl RunStats {
    /// Counts an undecodable message on `key`.
    pub fn count_bad_message(&mut self, key: &str) {
        let bucket =
            if self.bad_messages.len() < BAD_MESSAGE_KEYS || self.bad_messages.contains_key(key) {
                key
            } else {
                OTHER_KEYS
            };
        *self.bad_messages.entry(bucket.to_string()).or_default() += 1;
    }

    /// What the triggers that named their transmitters fired (`None`: none did).
    pub fn plan_summary(&self) -> Option<PlanSummary> {
        let n = self.named_triggers as f64;
        let (firing, slots, period_s) = self.named_sums;
        (self.named_triggers > 0 && slots > 0).then(|| PlanSummary {
            transmitters_per_cycle: firing as f64 / n,
            slots_per_cycle: slots as f64 / n,
            mean_slot_ms: 1e3 * period_s / slots as f64,
        })
    }

    /// HDOP of the transmitters `fix` used, seen from the fix at MSU
    /// height (`None`: an unknown transmitter or no fix geometry).
    pub fn fix_hdop(&self, fix: &ickon_proto::msg::robot::Fix) -> Option<f64> {
        let txs: Option<Vec<nalgebra::Vector3<f64>>> = fix
            .used
            .iter()
            .map(|id| {
                self.tx_positions
                    .get(id)
                    .map(|p| nalgebra::Vector3::from(*p))
            })
            .collect();
        let h = self.msu_height_m;
        let d = ickon_fusion::tdoa::dop(
            &txs?,
            nalgebra::Vector3::new(fix.x_m, fix.y_m, h),
            ickon_fusion::tdoa::Mode::TwoD { height_m: h },
        )
        .ok()?;
        d.hdop.is_finite().then_some(d.hdop)
    }

    /// Notes a cycle trigger received at `at`.
    pub fn on_trigger(&mut self, trigger: &ickon_proto::msg::control::CycleTrigger, at: Instant) {
        let key = (trigger.epoch, trigger.cycle);
        self.cycles_triggered.insert(key);
        if !trigger.firing.is_empty() {
            let mut offsets: Vec<_> = trigger.firing.iter().map(|f| f.offset).collect();
            offsets.sort();
            offsets.dedup();
            self.named_triggers += 1;
            self.named_sums.0 += trigger.firing.len() as u64;
            self.named_sums.1 += offsets.len() as u64;
            self.named_sums.2 += trigger.cycle_period.as_secs_f64();
        }
        self.last_firing = (!trigger.firing.is_empty()).then_some(trigger.firing.len());
        if trigger.firing.is_empty() {
            self.whole_schedule_cycles.insert(key);
        }
        for f in &trigger.firing {
            if let Some(cell) = self.tx_cells.get(&f.tx_id) {
                self.named_cycles
                    .entry(cell.clone())
                    .or_default()
                    .insert(key);
            }
        }
        self.trigger_rate.note(at);
    }

    /// Of the `completed` cycles, those `cell` was to fire: all of the
    /// whole schedule's, and those whose trigger named one of its
    /// transmitters (occupancy firing leaves a cell no robot hears out).
    pub fn cycles_for_cell(
        &self,
        cell: &str,
        completed: &BTreeSet<CycleKey>,
    ) -> BTreeSet<CycleKey> {
        let named = self.named_cycles.get(cell);
        completed
            .iter()
            .filter(|k| {
                self.whole_schedule_cycles.contains(k) || named.is_some_and(|n| n.contains(k))
            })
            .copied()
            .collect()
    }

    /// Cycles triggered per second over the last two seconds.
    pub fn cycles_per_s(&self) -> f64 {
        self.trigger_rate.per_s()
    }
}

/// Triggered cycles whose bursts and arrivals had time to be seen: all but
/// the newest two (a trigger goes out ahead of its cycle, which may end
/// after the run stops watching).
pub fn completed_cycles(triggered: &BTreeSet<CycleKey>) -> BTreeSet<CycleKey> {
    let keep = triggered.len().saturating_sub(2);
    triggered.iter().copied().take(keep).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undecodable_messages_are_all_counted_under_a_bounded_number_of_keys() {
        let mut stats = RunStats::default();
        for k in 0..80_000 {
            let key = format!("site/lab/robot/forged{k}/fix");
            let got = crate::observe::decode_or_count::<Burst>(&mut stats, &key, b"garbage");
            assert!(got.is_none());
        }
        assert_eq!(stats.bad_messages.len(), BAD_MESSAGE_KEYS + 1);
        assert_eq!(stats.bad_messages.values().sum::<u64>(), 80_000);
        assert_eq!(
            stats.bad_messages[OTHER_KEYS],
            80_000 - BAD_MESSAGE_KEYS as u64
        );
        // One line was written, the rest held back for the next window.
        assert_eq!(stats.bad_log.admit("Burst", Instant::now()), None);
    }

    fn truth(t_s: f64, x: f64) -> Truth {
        Truth {
            stamp: Time::from_secs_f64(t_s),
            robot_clock: Time::from_secs_f64(t_s + 100.0),
            x_m: x,
            y_m: 0.0,
            theta_rad: 0.0,
            v_m_s: 1.0,
            omega_rad_s: 0.0,
        }
    }

    fn pose(t_robot_s: f64, x: f64, fix_seq: u64) -> RobotPose {
        RobotPose {
            stamp: Time::from_secs_f64(t_robot_s),
            x_m: x,
            y_m: 0.0,
            theta_rad: 0.0,
            covariance: [0.0; 9],
            estimator: "test".into(),
            fix_seq,
            status: ickon_proto::msg::robot::PoseStatus::Tracking,
        }
    }

    #[test]
    fn percentile_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), Some(50.0));
        assert_eq!(percentile(&v, 99.0), Some(99.0));
        assert_eq!(percentile(&v, 100.0), Some(100.0));
        assert_eq!(percentile(&[], 50.0), None);
    }

    #[test]
    fn poses_are_scored_against_truth_on_the_robot_clock() {
        let mut r = RobotStats::default();
        for k in 0..200 {
            let t = k as f64 * 0.05;
            r.on_truth(truth(t, t)); // x = t metres
        }
        let now = Instant::now();
        // The robot clock runs 100 s ahead of true time; a pose 20 mm off.
        r.on_pose(&pose(100.0, 0.0, 0), now);
        r.on_pose(&pose(105.0, 5.02, 0), now);
        let s = r.summary("r1", 10, 10.0);
        assert_eq!(s.poses, 2);
        assert_eq!(s.scored_poses, 1, "the first pose is inside the warm-up");
        assert!((s.mean_mm.unwrap() - 20.0).abs() < 1e-6);
        // At the newest truth sample itself, and a little past it.
        let last = 199.0 * 0.05;
        r.on_pose(&pose(100.0 + last, last, 0), now);
        r.on_pose(&pose(100.0 + last + 0.02, last + 0.02, 0), now);
        r.on_pose(&pose(100.0 + last + 0.5, 0.0, 0), now);
        let s = r.summary("r1", 10, 10.0);
        assert_eq!(s.scored_poses, 3, "far past the truth is not scored");
        assert!((s.mean_mm.unwrap() - 20.0 / 3.0).abs() < 1e-6);
        // A pose its MSU says is a guess is counted, not scored.
        let guess = RobotPose {
            status: PoseStatus::Localising,
            ..pose(100.0 + last, 3.0, 0)
        };
        r.on_pose(&guess, now);
        let s = r.summary("r1", 10, 10.0);
        assert_eq!((s.scored_poses, s.localising_poses), (3, 1));
        assert!((s.mean_mm.unwrap() - 20.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn latency_counts_each_fix_once() {
        let mut r = RobotStats::default();
        let t0 = Instant::now();
        r.on_arrivals(7, t0);
        let later = t0 + std::time::Duration::from_micros(800);
        r.on_pose(&pose(1.0, 0.0, 7), later);
        r.on_pose(
            &pose(1.1, 0.0, 7),
            later + std::time::Duration::from_millis(100),
        );
        let s = r.summary("r1", 10, 10.0);
        assert_eq!(s.latency_p50_us.map(|v| v.round()), Some(800.0));
        assert_eq!(s.latency_p99_us.map(|v| v.round()), Some(800.0));
    }

    #[test]
    fn cells_count_distinct_cycles_and_sync_error() {
        let mut c = CellStats::default();
        for (cycle, err) in [(1u64, 30i64), (1, -50), (2, 10)] {
            c.on_burst(&Burst {
                cell_id: "c1".into(),
                tx_id: 11,
                cycle,
                scheduled: Time(1_000_000),
                actual: Time(1_000_000 + err * 1_000),
                epoch: 1,
            });
        }
        let s = c.summary("c1", &(0..5).map(|k| (1, k)).collect());
        assert_eq!(s.fired_share, Some(0.4));
        assert_eq!(s.cycles_fired, 2);
        assert_eq!(s.cycles_missed, 3);
        assert_eq!(s.bursts, 3);
        assert_eq!(s.sync_error_max_us, Some(50.0));
    }

    /// Under occupancy firing a cell is due only in the cycles whose
    /// trigger names one of its transmitters: a cell no robot hears is not
    /// counted as missing cycles (the scale benchmark showed 1.2 % fired).
    #[test]
    fn a_cell_is_due_in_the_cycles_that_name_its_transmitters() {
        use ickon_proto::msg::control::{CycleTrigger, Firing};
        use ickon_proto::time::Duration;
        let mut stats = RunStats {
            tx_cells: [(11, "c1".to_string()), (21, "c2".to_string())].into(),
            ..RunStats::default()
        };
        let trigger = |cycle, firing: &[u32]| CycleTrigger {
            cycle,
            start: Time(0),
            schedule_version: 1,
            epoch: 1,
            firing: firing
                .iter()
                .map(|&tx_id| Firing {
                    tx_id,
                    offset: Duration::ZERO,
                })
                .collect(),
            cycle_period: Duration::ZERO,
        };
        let now = Instant::now();
        stats.on_trigger(&trigger(0, &[]), now);
        stats.on_trigger(&trigger(1, &[11]), now);
        stats.on_trigger(&trigger(2, &[11, 99]), now);
        let completed: BTreeSet<CycleKey> = (0..3).map(|k| (1, k)).collect();
        let c1 = stats.cycles_for_cell("c1", &completed);
        let c2 = stats.cycles_for_cell("c2", &completed);
        assert_eq!(c1, completed);
        assert_eq!(c2, [(1, 0)].into());
        let mut cell = CellStats::default();
        cell.on_burst(&Burst {
            cell_id: "c2".into(),
            tx_id: 21,
            cycle: 0,
            scheduled: Time(0),
            actual: Time(0),
            epoch: 1,
        });
        let s = cell.summary("c2", &c2);
        assert_eq!((s.fired_share, s.cycles_missed), (Some(1.0), 0));
    }

    #[test]
    fn a_fix_s_hdop_comes_from_the_transmitters_it_used_and_unknown_ones_give_none() {
        let stats = RunStats {
            tx_positions: [
                (1, [0.0, 0.0, 3.0]),
                (2, [4.0, 0.0, 3.0]),
                (3, [4.0, 4.0, 3.0]),
                (4, [0.0, 4.0, 3.0]),
            ]
            .into(),
            msu_height_m: 0.5,
            ..RunStats::default()
        };
        let fix = |used: Vec<u32>| ickon_proto::msg::robot::Fix {
            stamp: Time(0),
            arrivals_seq: 1,
            x_m: 2.0,
            y_m: 2.0,
            z_m: 0.5,
            covariance: [0.0; 9],
            heading_rad: 0.0,
            heading_valid: false,
            used,
            rejected: Vec::new(),
            residuals_m: Vec::new(),
            quality: ickon_proto::msg::robot::FixQuality::Good,
            survey_version: 0,
            unused: Vec::new(),
            unused_residuals_m: Vec::new(),
        };
        let square = stats.fix_hdop(&fix(vec![1, 2, 3, 4])).unwrap();
        assert!(square > 0.5 && square < 5.0, "{square}");
        // Too few for a fix, or an id the site does not know: none.
        assert!(stats.fix_hdop(&fix(vec![1, 2])).is_none());
        assert!(stats.fix_hdop(&fix(vec![1, 2, 3, 99])).is_none());
        let mut robot = RobotStats::default();
        robot.on_fix(Instant::now());
        robot.on_fix_geometry(4, Some(square));
        let s = robot.summary("r1", 10, 2.0);
        assert_eq!(s.fixes_per_s, Some(0.5));
        assert_eq!(s.signals_per_fix, Some(4.0));
        assert_eq!(s.fix_hdop, Some(square));
    }
}
