//! The world in real time: the same [`World`] as the virtual-time engine, but
//! driven by the wall clock and fed with the cells' real burst reports, so
//! that the cell controllers and MSU agents can run as separate processes.
//!
//! [`RealtimeWorld`] is a pure state machine: [`RealtimeWorld::on_burst`]
//! records an emission, [`RealtimeWorld::advance`] moves every robot to a
//! time and returns what its sensors produced on the way (gyro, odometry,
//! obstacle ranges, truth, and the arrivals of every cycle whose sound has
//! arrived). Its contract is the one of every node:
//! [`RealtimeWorld::handle`] takes `now` and one [`WorldEvent`] and returns
//! the outputs. Inside, times are true seconds since the first event (the
//! world's epoch); the adapter owns the clock.
//!
//! A cycle is named by the central unit's epoch and its number: a
//! restarted central unit's cycle 0 is a new cycle, and a burst with an
//! absurd cycle number (2^62) only makes a cycle of its own. Nothing waits
//! for a cycle number: a cycle is delivered once its sound is over, and
//! only the last [`DELIVERED_KEPT`] delivered ones are remembered, to drop
//! their stragglers. Schedules are taken under the rules of
//! [`ickon_proto::epoch`].
//!
//! A cycle's trigger, when heard, says which transmitters fire in it and
//! how long it lasts (the central unit fires only where the robots are):
//! the cycle is then complete when those have fired, as an MSU that
//! follows the triggers knows, instead of waiting the whole schedule's
//! period for transmitters that do not fire in it.

use std::collections::{BTreeMap, VecDeque};

use ickon_proto::epoch::{ScheduleBook, ScheduleRefused};
use ickon_proto::msg::control::{Burst, CycleTrigger, Schedule};
use ickon_proto::msg::robot::{Imu, ObstacleRanges, Odometry, Truth, UltrasoundArrivals};
use ickon_proto::site::Site;
use ickon_proto::time::Time;

use ickon_sim::engine::{ENCODER_HZ, PHYSICS_DT_S, RANGES_HZ, REST_S};
use ickon_sim::profile::NoiseProfile;
use ickon_sim::world::World;

/// Truth samples per second published for observers.
pub const TRUTH_HZ: f64 = 50.0;
/// Extra wait after the last possible arrival before a cycle is delivered.
const DELIVERY_MARGIN_S: f64 = 0.002;

/// Why a real-time world could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RealtimeError {
    /// A robot id not in the site.
    #[error("robot {0:?} is not in the site (known: {1})")]
    UnknownRobot(String, String),
    /// A robot whose route is not in the site (the site validator prevents this).
    #[error("robot {0:?} drives unknown route {1:?}")]
    UnknownRoute(String, String),
}

/// What the world produced, for one robot (index into [`RealtimeWorld::robot_ids`]).
#[derive(Debug, Clone, PartialEq)]
pub enum WorldOutput {
    /// A gyro sample.
    Imu(usize, Imu),
    /// Wheel odometry.
    Odometry(usize, Odometry),
    /// Obstacle ranges.
    Ranges(usize, ObstacleRanges),
    /// Ground truth.
    Truth(usize, Truth),
    /// The arrivals of one cycle.
    Arrivals(usize, UltrasoundArrivals),
}

/// Something that happened to the world.
#[derive(Debug, Clone, PartialEq)]
pub enum WorldEvent {
    /// A (new) schedule from the central unit.
    Schedule(Schedule),
    /// A cell's report of a burst it fired (its `actual` time on the true
    /// time base).
    Burst(Burst),
    /// The central unit's trigger of a cycle: which transmitters fire in
    /// it, and its length.
    Trigger(CycleTrigger),
    /// Time to move the robots to `now`.
    Tick,
}

/// A burst reported further than this from `now` cannot be real (a forged
/// or corrupt report): it is ignored instead of holding a cycle open.
const MAX_BURST_SKEW_S: f64 = 10.0;

/// Delivered cycles remembered, to drop bursts that come after their cycle
/// was delivered (a few seconds' worth of cycles).
pub const DELIVERED_KEPT: usize = 64;

/// A cycle: (epoch of the central unit, cycle number).
type CycleKey = (u64, u64);

/// What a cycle's trigger says of its sound.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TriggeredCycle {
    /// Bursts that make it complete.
    emissions: usize,
    /// Its length, seconds.
    period_s: f64,
}

#[derive(Debug, Default)]
struct PendingCycle {
    emissions: Vec<(u32, f64)>,
    first_s: f64,
    last_s: f64,
}

/// Every simulated robot of a real-time run.
pub struct RealtimeWorld {
    ids: Vec<String>,
    worlds: Vec<World>,
    gyro_dt_s: f64,
    t_s: f64,
    next_gyro_s: f64,
    next_odom_s: f64,
    next_ranges_s: f64,
    next_truth_s: f64,
    pending: BTreeMap<CycleKey, PendingCycle>,
    delivered: VecDeque<CycleKey>,
    /// The triggers of the cycles not yet delivered (at most
    /// [`DELIVERED_KEPT`]: a trigger whose bursts never come is forgotten).
    triggered: BTreeMap<CycleKey, TriggeredCycle>,
    schedules: ScheduleBook,
    emissions_per_cycle: Option<usize>,
    period_s: f64,
    max_flight_s: f64,
    epoch: Option<Time>,
    bursts_ignored: u64,
}

/// Decorrelates the random streams of the robots of one run.
fn robot_seed(seed: u64, index: usize) -> u64 {
    seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

impl RealtimeWorld {
    /// Makes transmitters fail as `faults` say, in every robot's world.
    pub fn set_transmitter_faults(&mut self, faults: &[ickon_sim::tx_faults::TransmitterFault]) {
        for w in &mut self.worlds {
            w.set_transmitter_faults(faults);
        }
    }

    /// The world of the robots `robot_ids` of `site`, each on its own route.
    pub fn new(
        site: &Site,
        robot_ids: &[String],
        profile: &NoiseProfile,
        seed: u64,
    ) -> Result<Self, RealtimeError> {
        let mut worlds = Vec::new();
        for (i, id) in robot_ids.iter().enumerate() {
            let spec = site.robots.iter().find(|r| &r.id == id).ok_or_else(|| {
                let known: Vec<&str> = site.robots.iter().map(|r| r.id.as_str()).collect();
                RealtimeError::UnknownRobot(id.clone(), known.join(", "))
            })?;
            let route = site
                .route(&spec.route)
                .ok_or_else(|| RealtimeError::UnknownRoute(id.clone(), spec.route.clone()))?;
            // Robots sharing a route start spread along it (the site's `start`).
            let route = route.starting_near([spec.start[0], spec.start[1]]);
            worlds.push(World::new(site, &route, profile, robot_seed(seed, i)));
        }
        let max_flight_s = (profile.ultrasound.max_range_m
            + profile.ultrasound.reflection_extra_m[1])
            / site.speed_of_sound_m_s;
        let gyro_dt_s = 1.0 / profile.gyro.rate_hz.max(1.0);
        Ok(Self {
            ids: robot_ids.to_vec(),
            worlds,
            gyro_dt_s,
            t_s: 0.0,
            next_gyro_s: gyro_dt_s,
            next_odom_s: 1.0 / ENCODER_HZ,
            next_ranges_s: 1.0 / RANGES_HZ,
            next_truth_s: 0.0,
            pending: BTreeMap::new(),
            delivered: VecDeque::new(),
            triggered: BTreeMap::new(),
            schedules: ScheduleBook::new(),
            emissions_per_cycle: None,
            period_s: 1.0,
            max_flight_s,
            epoch: None,
            bursts_ignored: 0,
        })
    }

    /// Handles one event at true time `now` and returns what the sensors
    /// produced. The first event fixes the world's epoch.
    pub fn handle(&mut self, now: Time, event: WorldEvent) -> Vec<WorldOutput> {
        let epoch = *self.epoch.get_or_insert(now);
        let seconds = |t: Time| t.since(epoch).as_secs_f64();
        let mut out = Vec::new();
        match event {
            WorldEvent::Schedule(s) => {
                if let Err(e) = self.set_schedule(s) {
                    tracing::debug!("world: {e}");
                }
            }
            WorldEvent::Burst(b) => {
                if (seconds(b.actual) - seconds(now)).abs() > MAX_BURST_SKEW_S {
                    self.bursts_ignored += 1;
                } else {
                    self.on_burst((b.epoch, b.cycle), b.tx_id, seconds(b.actual));
                }
            }
            WorldEvent::Trigger(t) => self.on_trigger(&t),
            WorldEvent::Tick => self.advance(seconds(now), &mut out),
        }
        out
    }

    /// Takes a cycle's trigger: the cycle is complete once the bursts it
    /// names have fired. A trigger of a cycle already delivered, or under
    /// no schedule the world holds, changes nothing; a repeated one
    /// replaces the first.
    pub fn on_trigger(&mut self, trigger: &CycleTrigger) {
        let key = (trigger.epoch, trigger.cycle);
        if self.delivered.contains(&key) {
            return;
        }
        let Some(schedule) = self
            .schedules
            .get_in(trigger.epoch, trigger.schedule_version)
        else {
            return;
        };
        let emissions = trigger.emissions(schedule).len();
        if emissions == 0 {
            // Names only transmitters the schedule does not have: no cell
            // fires them, and "complete" would mean nothing.
            return;
        }
        let cycle = TriggeredCycle {
            emissions,
            period_s: trigger.period(schedule).as_secs_f64().clamp(1e-3, 10.0),
        };
        if self.triggered.len() >= DELIVERED_KEPT && !self.triggered.contains_key(&key) {
            self.triggered.pop_first();
        }
        self.triggered.insert(key, cycle);
    }

    /// Robot `index` keeps the true time as its clock (a robot on an
    /// emulated device: its host learns the device's clock instead).
    pub fn use_true_clock(&mut self, index: usize) {
        if let Some(w) = self.worlds.get_mut(index) {
            w.msu_clock = ickon_sim::clock::DeviceClock::PERFECT;
        }
    }

    /// The true time the world's seconds count from (the first event's `now`).
    pub fn epoch(&self) -> Option<Time> {
        self.epoch
    }

    /// Burst reports ignored for being stamped far from `now`.
    pub fn bursts_ignored(&self) -> u64 {
        self.bursts_ignored
    }

    /// The robots, in the order of the indices in [`WorldOutput`].
    pub fn robot_ids(&self) -> &[String] {
        &self.ids
    }

    /// The schedule in force: how many bursts make a complete cycle, and how
    /// long to wait for a cycle whose bursts do not all come (a dead cell).
    /// A schedule the rules refuse (an altered version, an old epoch) changes nothing.
    pub fn set_schedule(&mut self, schedule: Schedule) -> Result<(), ScheduleRefused> {
        self.schedules.offer(schedule)?;
        if let Some(s) = self.schedules.latest() {
            self.emissions_per_cycle = Some(s.emissions.len());
            self.period_s = s.cycle_period.as_secs_f64().max(1e-3);
        }
        Ok(())
    }

    /// Schedules refused so far.
    pub fn schedules_refused(&self) -> u64 {
        self.schedules.refused()
    }

    /// Records that transmitter `tx_id` fired in `cycle` (epoch, number) at
    /// true time `t_emit_s`. Bursts of cycles just delivered, and
    /// non-finite times, are ignored.
    pub fn on_burst(&mut self, cycle: CycleKey, tx_id: u32, t_emit_s: f64) {
        if !t_emit_s.is_finite() {
            return;
        }
        if self.delivered.contains(&cycle) {
            return;
        }
        let p = self.pending.entry(cycle).or_insert_with(|| PendingCycle {
            first_s: t_emit_s,
            last_s: t_emit_s,
            ..PendingCycle::default()
        });
        p.first_s = p.first_s.min(t_emit_s);
        p.last_s = p.last_s.max(t_emit_s);
        p.emissions.push((tx_id, t_emit_s));
    }

    /// Moves every robot to true time `t_s`, appending what the sensors produced.
    pub fn advance(&mut self, t_s: f64, out: &mut Vec<WorldOutput>) {
        while self.t_s + PHYSICS_DT_S <= t_s {
            self.t_s += PHYSICS_DT_S;
            let t = self.t_s;
            for w in &mut self.worlds {
                w.step(t, PHYSICS_DT_S, t > REST_S);
            }
            if t >= self.next_gyro_s {
                self.next_gyro_s += self.gyro_dt_s;
                for (i, w) in self.worlds.iter_mut().enumerate() {
                    out.push(WorldOutput::Imu(i, w.gyro(t, self.gyro_dt_s)));
                }
            }
            if t >= self.next_odom_s {
                self.next_odom_s += 1.0 / ENCODER_HZ;
                for (i, w) in self.worlds.iter_mut().enumerate() {
                    out.push(WorldOutput::Odometry(i, w.odometry(t)));
                }
            }
            if t >= self.next_ranges_s {
                self.next_ranges_s += 1.0 / RANGES_HZ;
                for (i, w) in self.worlds.iter_mut().enumerate() {
                    out.push(WorldOutput::Ranges(i, w.ranges(t)));
                }
            }
            if t >= self.next_truth_s {
                self.next_truth_s += 1.0 / TRUTH_HZ;
                for (i, w) in self.worlds.iter().enumerate() {
                    let s = w.robot.state;
                    out.push(WorldOutput::Truth(
                        i,
                        Truth {
                            stamp: Time::from_secs_f64(t),
                            robot_clock: w.msu_clock.stamp(t),
                            x_m: s.x_m,
                            y_m: s.y_m,
                            theta_rad: ickon_fusion::angle::wrap_pi(s.theta_rad),
                            v_m_s: s.v_m_s,
                            omega_rad_s: s.omega_rad_s,
                        },
                    ));
                }
            }
            self.deliver_due(out);
        }
    }

    /// Delivers every cycle whose sound has certainly arrived: all its bursts
    /// are in and the farthest flight is over, or it waited a whole period
    /// beyond its first burst (bursts of a dead cell never come).
    fn deliver_due(&mut self, out: &mut Vec<WorldOutput>) {
        let now = self.t_s;
        let due: Vec<CycleKey> = self
            .pending
            .iter()
            .filter(|(k, p)| {
                let trigger = self.triggered.get(k);
                let heard_all = now >= p.last_s + self.max_flight_s + DELIVERY_MARGIN_S;
                let complete = trigger
                    .map(|t| t.emissions)
                    .or(self.emissions_per_cycle)
                    .is_some_and(|n| p.emissions.len() >= n);
                let period_s = trigger.map_or(self.period_s, |t| t.period_s);
                let timed_out = now >= p.first_s + period_s + self.max_flight_s;
                heard_all && (complete || timed_out)
            })
            .map(|(&k, _)| k)
            .collect();
        for k in due {
            self.triggered.remove(&k);
            if let Some(p) = self.pending.remove(&k) {
                if self.delivered.len() == DELIVERED_KEPT {
                    self.delivered.pop_front();
                }
                self.delivered.push_back(k);
                for (i, w) in self.worlds.iter_mut().enumerate() {
                    out.push(WorldOutput::Arrivals(
                        i,
                        w.arrivals_from_emissions(&p.emissions),
                    ));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::control::Emission;
    use ickon_proto::time::Duration;

    /// The epoch of the tests' central unit.
    const E: u64 = 1_000;

    fn setup(profile: &str) -> (Site, RealtimeWorld, Schedule) {
        let site = Site::default_site();
        let profile = NoiseProfile::by_name(profile).unwrap();
        let ids = vec!["r3".to_string(), "r4".to_string()];
        let world = RealtimeWorld::new(&site, &ids, &profile, 7).unwrap();
        let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        let schedule = Schedule {
            epoch: E,
            ..ickon_central::compute_schedule(&site, &cells, 1, 0).unwrap()
        };
        (site, world, schedule)
    }

    /// Every burst of one cycle `key` starting at `start_s`, then time up
    /// to the end of its sound: the number of arrival messages delivered.
    fn run_cycle(
        world: &mut RealtimeWorld,
        schedule: &Schedule,
        key: CycleKey,
        start_s: f64,
    ) -> usize {
        for e in &schedule.emissions {
            world.on_burst(key, e.tx_id, start_s + e.offset.as_secs_f64());
        }
        let mut out = Vec::new();
        world.advance(
            start_s + schedule.cycle_period.as_secs_f64() + 0.1,
            &mut out,
        );
        count(&out)[4]
    }

    #[test]
    fn a_burst_with_cycle_2_pow_62_does_not_stop_the_real_cycles() {
        let (_, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        let period = schedule.cycle_period.as_secs_f64();
        assert_eq!(run_cycle(&mut world, &schedule, (E, 7), 3.0), 2);
        world.on_burst((E, 1 << 62), 31, 3.0 + period);
        assert_eq!(
            run_cycle(&mut world, &schedule, (E, 8), 3.0 + 2.0 * period),
            2 + 2
        );
        assert_eq!(
            run_cycle(&mut world, &schedule, (E, 9), 3.0 + 4.0 * period),
            2
        );
    }

    #[test]
    fn a_restarted_central_units_cycle_0_is_heard_at_once() {
        let (_, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        let period = schedule.cycle_period.as_secs_f64();
        assert_eq!(run_cycle(&mut world, &schedule, (E, 80), 3.0), 2);
        let restarted = Schedule {
            epoch: E + 1,
            ..schedule.clone()
        };
        world.set_schedule(restarted.clone()).unwrap();
        assert_eq!(
            run_cycle(&mut world, &restarted, (E + 1, 0), 3.0 + 2.0 * period),
            2
        );
    }

    #[test]
    fn an_empty_schedule_under_the_current_version_is_refused() {
        let (_, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        let empty = Schedule {
            emissions: Vec::new(),
            ..schedule.clone()
        };
        assert!(world.set_schedule(empty).is_err());
        assert_eq!(world.schedules_refused(), 1);
        // The cycle is still complete with the real schedule's bursts: no
        // waiting a period for bursts that do not exist.
        for e in &schedule.emissions {
            world.on_burst((E, 1), e.tx_id, 3.0 + e.offset.as_secs_f64());
        }
        let mut out = Vec::new();
        let last = schedule
            .emissions
            .iter()
            .map(|e| e.offset.as_secs_f64())
            .fold(0.0, f64::max);
        world.advance(3.0 + last + 0.1, &mut out);
        assert_eq!(count(&out)[4], 2);
    }

    /// The trigger of cycle `cycle` starting at `start_s` that fires the
    /// schedule's first `n` emissions, and those emissions.
    fn trigger_of_first(
        schedule: &Schedule,
        cycle: u64,
        start_s: f64,
        n: usize,
    ) -> (CycleTrigger, Vec<Emission>) {
        let fired: Vec<Emission> = schedule.emissions.iter().take(n).cloned().collect();
        let last = fired.iter().map(|e| e.offset).max().unwrap_or_default();
        let trigger = CycleTrigger {
            cycle,
            start: Time::from_secs_f64(start_s),
            schedule_version: schedule.version,
            epoch: E,
            firing: fired
                .iter()
                .map(|e| ickon_proto::msg::control::Firing {
                    tx_id: e.tx_id,
                    offset: e.offset,
                })
                .collect(),
            cycle_period: last + Duration::from_millis(20),
        };
        (trigger, fired)
    }

    /// Arrival messages out of cycle `cycle` firing the schedule's first
    /// three emissions at `start_s`, time moved to just after the last
    /// one's sound; with or without its trigger heard.
    fn delivered_after_own_sound(triggered: bool, cycle: u64, start_s: f64) -> usize {
        let (_, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        let (trigger, fired) = trigger_of_first(&schedule, cycle, start_s, 3);
        assert!(fired.len() < schedule.emissions.len());
        if triggered {
            world.on_trigger(&trigger);
        }
        for e in &fired {
            world.on_burst((E, cycle), e.tx_id, start_s + e.offset.as_secs_f64());
        }
        let last = fired
            .iter()
            .map(|e| e.offset.as_secs_f64())
            .fold(0.0, f64::max);
        let mut out = Vec::new();
        world.advance(start_s + last + world.max_flight_s + 0.01, &mut out);
        count(&out)[4]
    }

    #[test]
    fn a_triggered_cycle_is_over_when_its_own_bursts_are_heard() {
        // Two robots: each gets the cycle once its three bursts are heard.
        assert_eq!(delivered_after_own_sound(true, 5, 3.0), 2);
        // Without the trigger the world waits for the schedule's other
        // transmitters, a whole period.
        assert_eq!(delivered_after_own_sound(false, 5, 3.0), 0);
    }

    #[test]
    fn a_trigger_under_an_unknown_schedule_of_unknown_transmitters_or_of_a_delivered_cycle_changes_nothing()
     {
        let (_, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        let (mut unknown, _) = trigger_of_first(&schedule, 9, 3.0, 3);
        unknown.schedule_version += 7;
        world.on_trigger(&unknown);
        let (mut other_epoch, _) = trigger_of_first(&schedule, 9, 3.0, 3);
        other_epoch.epoch = E + 1;
        world.on_trigger(&other_epoch);
        let (mut strangers, _) = trigger_of_first(&schedule, 9, 3.0, 3);
        for f in &mut strangers.firing {
            f.tx_id += 10_000;
        }
        world.on_trigger(&strangers);
        assert!(world.triggered.is_empty());
        assert_eq!(run_cycle(&mut world, &schedule, (E, 7), 3.0), 2);
        let (late, _) = trigger_of_first(&schedule, 7, 3.0, 3);
        world.on_trigger(&late);
        assert!(world.triggered.is_empty());
    }

    #[test]
    fn triggers_whose_bursts_never_come_are_forgotten() {
        let (_, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        for cycle in 0..(3 * DELIVERED_KEPT as u64) {
            let (t, _) = trigger_of_first(&schedule, cycle, 3.0, 3);
            world.on_trigger(&t);
        }
        assert_eq!(world.triggered.len(), DELIVERED_KEPT);
        // The newest are kept.
        assert!(
            world
                .triggered
                .contains_key(&(E, 3 * DELIVERED_KEPT as u64 - 1))
        );
    }

    fn count(out: &[WorldOutput]) -> [usize; 5] {
        let mut n = [0; 5];
        for o in out {
            let k = match o {
                WorldOutput::Imu(..) => 0,
                WorldOutput::Odometry(..) => 1,
                WorldOutput::Ranges(..) => 2,
                WorldOutput::Truth(..) => 3,
                WorldOutput::Arrivals(..) => 4,
            };
            n[k] += 1;
        }
        n
    }

    #[test]
    fn sensors_come_at_their_rates_for_every_robot() {
        let (_, mut world, _) = setup("paper");
        let mut out = Vec::new();
        world.advance(1.0, &mut out);
        let [imu, odom, ranges, truth, arrivals] = count(&out);
        // Two robots; one second; the first sample of each stream is one step in.
        assert!((198..=200).contains(&imu), "{imu}");
        assert!((98..=100).contains(&odom), "{odom}");
        assert!((18..=20).contains(&ranges), "{ranges}");
        assert!((98..=100).contains(&truth), "{truth}");
        assert_eq!(arrivals, 0, "no bursts, no arrivals");
    }

    #[test]
    fn a_complete_cycle_is_delivered_once_its_sound_has_arrived() {
        let (site, mut world, schedule) = setup("ideal");
        world.set_schedule(schedule.clone()).unwrap();
        let start = 3.0;
        for e in &schedule.emissions {
            world.on_burst((E, 1), e.tx_id, start + e.offset.as_secs_f64());
        }
        let mut out = Vec::new();
        let last = schedule
            .emissions
            .iter()
            .map(|e| e.offset.as_secs_f64())
            .fold(0.0, f64::max);
        world.advance(start + last, &mut out);
        assert_eq!(count(&out)[4], 0, "delivered before the last flight ended");
        world.advance(start + last + 0.1, &mut out);
        let arrivals: Vec<&UltrasoundArrivals> = out
            .iter()
            .filter_map(|o| match o {
                WorldOutput::Arrivals(_, a) => Some(a),
                _ => None,
            })
            .collect();
        assert_eq!(arrivals.len(), 2, "one message per robot");
        // Robot r3 on the rectangle in cell c3 hears its cell's four transmitters.
        let heard: Vec<u32> = arrivals[0].arrivals.iter().map(|a| a.tx_id).collect();
        for id in [31, 32, 33, 34] {
            assert!(heard.contains(&id), "{id} not heard: {heard:?}");
        }
        assert!(site.transmitter(31).is_some());
        // Bursts of a delivered cycle are ignored.
        world.on_burst((E, 1), 31, start);
        world.advance(start + 2.0, &mut out);
        assert_eq!(count(&out)[4], 2);
    }

    #[test]
    fn the_event_contract_delivers_a_cycle_and_ignores_a_forged_far_burst() {
        use ickon_proto::msg::control::Burst;
        let (_site, mut world, schedule) = setup("ideal");
        let t0 = Time::from_nanos(1_764_000_000_000_000_000);
        let at = |s: f64| t0 + ickon_proto::time::Duration::from_secs_f64(s);
        assert!(
            world
                .handle(t0, WorldEvent::Schedule(schedule.clone()))
                .is_empty()
        );
        assert_eq!(world.epoch(), Some(t0));
        let burst = |tx_id: u32, actual: Time| Burst {
            cell_id: "c1".into(),
            tx_id,
            cycle: 1,
            scheduled: actual,
            actual,
            epoch: E,
        };
        // A forged report of cycle 1 an hour ahead: ignored, counted.
        let forged = world.handle(at(3.0), WorldEvent::Burst(burst(31, at(3_603.0))));
        assert!(forged.is_empty());
        assert_eq!(world.bursts_ignored(), 1);
        for e in &schedule.emissions {
            world.handle(
                at(3.0),
                WorldEvent::Burst(burst(e.tx_id, at(3.0 + e.offset.as_secs_f64()))),
            );
        }
        let out = world.handle(at(4.5), WorldEvent::Tick);
        let c = count(&out);
        assert_eq!(c[4], 2, "one cycle for each robot: {c:?}");
        assert!(c[0] > 0 && c[1] > 0, "sensors ran: {c:?}");
    }

    #[test]
    fn a_cycle_missing_bursts_is_delivered_after_a_period() {
        let (_, mut world, mut schedule) = setup("ideal");
        schedule.emissions.push(Emission {
            tx_id: 99,
            cell_id: "ghost".into(),
            offset: Duration::ZERO,
            slot: 0,
        });
        schedule.active_cells.push("ghost".into());
        world.set_schedule(schedule.clone()).unwrap();
        world.on_burst((E, 5), 31, 3.0);
        let mut out = Vec::new();
        world.advance(3.2, &mut out);
        assert_eq!(count(&out)[4], 0, "still waiting for the missing bursts");
        world.advance(3.0 + schedule.cycle_period.as_secs_f64() + 0.2, &mut out);
        assert_eq!(count(&out)[4], 2);
    }

    #[test]
    fn unknown_robots_are_refused_by_name() {
        let site = Site::default_site();
        let profile = NoiseProfile::by_name("paper").unwrap();
        let err = RealtimeWorld::new(&site, &["r9".to_string()], &profile, 1)
            .err()
            .unwrap();
        assert!(err.to_string().contains("r9"));
    }
}
