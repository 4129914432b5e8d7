//! A fleet in virtual time: the first N robots of the site, each with its
//! own world and MSU core, sharing one control plane (the central unit's
//! and the cells' own cores). Each robot's pose goes to the central unit
//! as the live agent publishes it, so occupancy-aware firing sees the
//! fleet as it would on a site. Reports what a site's update rate is judged by: each
//! robot's achieved fix rate, its pose error against the truth, and what
//! collisions cost; and the cycles the central unit triggered.

use std::collections::BTreeMap;

use ickon_central::core::{CentralConfig, Event as CentralEvent};
use ickon_central::selection::PlanStats;
use ickon_fusion::estimator;
use ickon_msu::summary::SummaryMaker;
use ickon_msu::{Event as MsuEvent, MsuCore, MsuDriver};
use ickon_proto::msg::control::CycleTrigger;
use ickon_proto::site::Site;
use ickon_proto::time::Time;
use serde::Serialize;

use crate::collision::CollisionCounts;
use crate::control::ControlPlane;
use crate::engine::{
    ENCODER_HZ, FilterOptions, PHYSICS_DT_S, REST_S, RunError, estimator_config, msu_config,
};
use crate::profile::NoiseProfile;
use crate::world::World;

/// How often each robot's pose reaches the central unit, and is scored, seconds.
const POSE_DT_S: f64 = 0.1;

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetConfig {
    /// How many of the site's robots drive (the first N).
    pub robots: usize,
    /// Virtual seconds to run.
    pub duration_s: f64,
    /// Seconds left out of the scores at the start (standing still included).
    pub warm_up_s: f64,
    /// Noise profile.
    pub profile: NoiseProfile,
    /// Run seed.
    pub seed: u64,
    /// The estimator every robot runs.
    pub estimator: String,
    /// The central unit's tuning (schedule, firing).
    pub central: CentralConfig,
    /// Filter options a user sets in the MSU configuration.
    pub filter: FilterOptions,
    /// Transmitters that fail during the run.
    pub transmitter_faults: Vec<crate::tx_faults::TransmitterFault>,
}

/// One robot's results.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobotResult {
    /// Robot id.
    pub id: String,
    /// Its route.
    pub route: String,
    /// Raw fixes per second after the warm-up.
    pub fixes_per_s: f64,
    /// Mean number of signals (arrivals) each of those fixes used.
    pub signals_per_fix: f64,
    /// Mean error of the fused pose against the truth, sampled every 0.1 s after the warm-up, mm.
    pub mean_err_mm: f64,
    /// 95th percentile of the same, mm.
    pub p95_err_mm: f64,
    /// What collisions and reverberation did to its detections.
    pub collisions: CollisionCounts,
    /// Of its fixes after the warm-up, those solved with the central unit's
    /// survey calibration.
    pub calibrated_fixes: u64,
    /// Inputs its MSU core refused, by kind, with the first reason (absent:
    /// none was).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refused_inputs: Option<String>,
    /// Mean error of each [`ERROR_WINDOW_S`] of the run after the
    /// warm-up, mm (`null`: no pose in it).
    pub window_err_mm: Vec<Option<f64>>,
}

/// Seconds of one window of [`RobotResult::window_err_mm`].
pub const ERROR_WINDOW_S: f64 = 30.0;

/// A transmitter left out of the fixes, or taken back, by the central unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TransmitterEvent {
    /// When, seconds of the run.
    pub t_s: f64,
    /// The transmitter.
    pub tx_id: u32,
    /// Its condition then (`dead`, `weak`, `moved`, `healthy`).
    pub condition: String,
    /// The evidence, in words.
    pub evidence: String,
}

/// A fleet run's results.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetOutput {
    /// Per robot.
    pub robots: Vec<RobotResult>,
    /// Cycles triggered per second after the warm-up.
    pub cycles_per_s: f64,
    /// Mean number of transmitters a trigger named after the warm-up.
    pub mean_firing: f64,
    /// Mean number of distinct emission times (slots) of those triggers.
    pub slots_per_cycle: f64,
    /// Mean length of a slot, ms: the cycle period over its slots.
    pub mean_slot_ms: f64,
    /// What the central unit's firing plans chose (the HDOP of each
    /// robot's transmitters), over the whole run.
    pub plan: PlanStats,
    /// Transmitters of the schedule.
    pub transmitters: usize,
    /// Every robot's collisions added up.
    pub collisions: CollisionCounts,
    /// Fixes the central unit's survey calibration learnt from (`None`:
    /// the calibration was off).
    pub survey_fixes_taken: Option<u64>,
    /// Transmitters left out of the fixes and taken back, in time order.
    pub transmitter_events: Vec<TransmitterEvent>,
    /// The speed of sound the central unit published against the air's,
    /// every second: the true value is the mean over the robots of their
    /// paths' ([`crate::engine::AirSample`]).
    pub air: Vec<crate::engine::AirSample>,
}

/// One robot of the fleet: its world, its MSU and what is scored of it.
struct Member {
    id: String,
    route: String,
    world: World,
    msu: MsuDriver,
    /// Its summaries for the central unit, as its agent on the mesh makes them.
    summary: SummaryMaker,
    fixes: u64,
    /// Signals those fixes used, added up.
    signals_used: u64,
    calibrated_fixes: u64,
    errors_mm: Vec<f64>,
}

/// Runs the first `config.robots` robots of `site` for `config.duration_s`.
pub fn run_fleet(site: &Site, config: &FleetConfig) -> Result<FleetOutput, RunError> {
    if config.robots == 0 || config.robots > site.robots.len() {
        return Err(RunError::FleetSize {
            asked: config.robots,
            site: site.robots.len(),
        });
    }
    let mut control =
        ControlPlane::with_config(site, &config.profile.clocks, config.seed, config.central)?;
    let members = build_members(site, config, &mut control)?;
    let mut fleet = Fleet::new(site, config, control, members);
    let steps = (config.duration_s / PHYSICS_DT_S).ceil() as u64;
    for step in 1..=steps {
        fleet.step(step);
    }
    Ok(fleet.results())
}

/// One member per robot of the fleet (the first `config.robots` of the
/// site), each on its route from its start, with its MSU on the control
/// plane's schedule; the central unit is told each one is alive.
fn build_members(
    site: &Site,
    config: &FleetConfig,
    control: &mut ControlPlane,
) -> Result<Vec<Member>, RunError> {
    let mut members = Vec::with_capacity(config.robots);
    for spec in site.robots.iter().take(config.robots) {
        let route = site
            .route(&spec.route)
            .ok_or_else(|| RunError::UnknownRoute {
                name: spec.route.clone(),
                known: String::new(),
            })?
            .starting_near([spec.start[0], spec.start[1]]);
        let mut world = World::for_robot(site, &route, &config.profile, config.seed, &spec.id);
        world.set_transmitter_faults(&config.transmitter_faults);
        let s0 = world.robot.state;
        let start = [s0.x_m, s0.y_m, s0.theta_rad];
        let est = estimator::build(&estimator_config(
            &config.estimator,
            start,
            site,
            &config.profile,
            config.filter,
        )?)?;
        let msu = msu_config(site, &config.profile, world.drive.geometry());
        let mut msu = MsuDriver::new(MsuCore::with_estimators(msu, vec![est]));
        msu.feed(MsuEvent::Schedule(
            control.central().latest_schedule().clone(),
        ));
        control.send_to_central(CentralEvent::RobotAlive {
            id: spec.id.clone(),
            up: true,
        });
        members.push(Member {
            id: spec.id.clone(),
            route: spec.route.clone(),
            world,
            msu,
            summary: SummaryMaker::default(),
            fixes: 0,
            signals_used: 0,
            calibrated_fixes: 0,
            errors_mm: Vec::new(),
        });
    }
    Ok(members)
}

/// A fleet run in progress: the shared control plane, the members, the
/// cycles triggered and not yet delivered, and the trigger counts.
struct Fleet<'a> {
    config: &'a FleetConfig,
    control: ControlPlane,
    members: Vec<Member>,
    /// Seconds after a cycle's last burst by which every burst has been heard.
    max_flight_s: f64,
    /// Physics steps between two gyro samples.
    gyro_every: u64,
    /// Physics steps between two odometry samples.
    encoder_every: u64,
    /// Physics steps between two poses sent to the central unit.
    pose_every: u64,
    /// Seconds between two gyro samples.
    gyro_dt: f64,
    /// Triggered cycles, until delivered or forgotten.
    triggers: BTreeMap<u64, CycleTrigger>,
    /// Cycles by the time (ns) every burst of theirs has been heard.
    due: BTreeMap<i64, Vec<u64>>,
    /// The true emission times of each cycle's bursts, until it is delivered.
    emissions: BTreeMap<u64, Vec<(u32, f64)>>,
    /// Cycles triggered after the warm-up.
    counted_cycles: u64,
    /// Transmitters those cycles named, added up.
    firing_sum: u64,
    /// Their distinct emission times, added up.
    slot_sum: u64,
    /// Their periods added up, seconds.
    period_sum_s: f64,
    /// The transmitters left out at the last look.
    left_out: std::collections::BTreeSet<u32>,
    transmitter_events: Vec<TransmitterEvent>,
    air: Vec<crate::engine::AirSample>,
    /// The cells' boards' air temperature sensors, when the profile gives
    /// them one.
    air_sensors: Option<crate::air_sensor::CellAirSensors>,
}

impl<'a> Fleet<'a> {
    /// The fleet at time zero, with the sensor rates in physics steps.
    fn new(
        site: &Site,
        config: &'a FleetConfig,
        control: ControlPlane,
        members: Vec<Member>,
    ) -> Self {
        let max_flight_s = (config.profile.ultrasound.max_range_m
            + config.profile.ultrasound.reflection_extra_m[1])
            / site.speed_of_sound_m_s
            + 0.005;
        let gyro_every = ((1.0 / config.profile.gyro.rate_hz.max(1.0)) / PHYSICS_DT_S)
            .round()
            .max(1.0) as u64;
        let encoder_every = ((1.0 / ENCODER_HZ) / PHYSICS_DT_S).round().max(1.0) as u64;
        let pose_every = (POSE_DT_S / PHYSICS_DT_S).round().max(1.0) as u64;
        let gyro_dt = gyro_every as f64 * PHYSICS_DT_S;
        let air_sensors = members.first().and_then(|m| {
            crate::air_sensor::CellAirSensors::new(
                m.world.true_site(),
                &config.profile.air_sensors,
                config.seed,
            )
        });
        Self {
            air_sensors,
            config,
            control,
            members,
            max_flight_s,
            gyro_every,
            encoder_every,
            pose_every,
            gyro_dt,
            triggers: BTreeMap::new(),
            due: BTreeMap::new(),
            emissions: BTreeMap::new(),
            counted_cycles: 0,
            firing_sum: 0,
            slot_sum: 0,
            period_sum_s: 0.0,
            left_out: std::collections::BTreeSet::new(),
            transmitter_events: Vec::new(),
            air: Vec::new(),
        }
    }

    /// Notes the transmitters the central unit left out or took back by
    /// `t`, and every second the speed of sound it published against the
    /// air's.
    fn watch_central(&mut self, t: f64) {
        let now = ickon_proto::time::Time::from_secs_f64(t);
        let Some(publisher) = self.control.central().survey() else {
            return;
        };
        if publisher.left_out() != &self.left_out {
            for r in publisher.transmitters(now) {
                if publisher.left_out().contains(&r.tx_id) != self.left_out.contains(&r.tx_id) {
                    self.transmitter_events.push(TransmitterEvent {
                        t_s: t,
                        tx_id: r.tx_id,
                        condition: r.condition.label().to_string(),
                        evidence: ickon_central::transmitter_health::TransmitterHealth::evidence(
                            &r,
                        ),
                    });
                }
            }
            self.left_out = publisher.left_out().clone();
        }
        if self.air.last().is_none_or(|a| t - a.t_s >= 1.0 - 1e-9) {
            let speeds: Vec<f64> = self
                .members
                .iter()
                .filter_map(|m| m.world.path_speed_m_s(t, crate::engine::AIR_PATHS_M))
                .collect();
            let used = publisher
                .published_speed()
                .map_or(publisher.site_speed_m_s(), |s| s.speed_m_s);
            self.air.push(crate::engine::AirSample {
                t_s: t,
                true_m_s: (!speeds.is_empty())
                    .then(|| speeds.len() as f64 / speeds.iter().map(|v| 1.0 / v).sum::<f64>()),
                used_m_s: used,
            });
        }
    }

    /// Physics step number `step` (from 1): the control plane, the robots'
    /// motion and sensors, the cycles due, and every few steps the poses.
    fn step(&mut self, step: u64) {
        let t = step as f64 * PHYSICS_DT_S;
        self.forward_control_plane(t);
        let moving = t > REST_S;
        let scoring = t > self.config.warm_up_s;
        for m in &mut self.members {
            m.world.step(t, PHYSICS_DT_S, moving);
            if step.is_multiple_of(self.gyro_every) {
                let imu = m.world.gyro(t, self.gyro_dt);
                m.msu.feed(MsuEvent::Imu(imu));
            }
            if step.is_multiple_of(self.encoder_every) {
                let odom = m.world.odometry(t);
                m.msu.feed(MsuEvent::Odometry(odom));
            }
        }
        self.deliver_due(t, scoring);
        self.forget_stale(t);
        if step.is_multiple_of(self.pose_every) {
            self.watch_central(t);
            self.sample_poses(t, scoring);
        }
    }

    /// Advances the control plane to `t` and hands every MSU what it sent
    /// (cell statuses, surveys, triggers); counts the triggers after the
    /// warm-up, notes when each cycle is due and keeps its bursts' true
    /// emission times.
    fn forward_control_plane(&mut self, t: f64) {
        let control = &mut self.control;
        control.advance_to(Time::from_secs_f64(t));
        if let (Some(sensors), Some(m)) = (self.air_sensors.as_mut(), self.members.first()) {
            control.send_air_temperatures(sensors.due(m.world.air(), t));
        }
        for status in control.take_statuses() {
            for m in &mut self.members {
                m.msu.feed(MsuEvent::CellStatus(status.clone()));
            }
        }
        for survey in control.take_surveys() {
            for m in &mut self.members {
                m.msu.feed(MsuEvent::Survey(survey.clone()));
            }
        }
        for trigger in control.take_triggers() {
            let schedule = control.schedule_for(trigger.cycle);
            let end = trigger.start.as_secs_f64()
                + trigger.period(schedule).as_secs_f64()
                + self.max_flight_s;
            if trigger.start.as_secs_f64() > self.config.warm_up_s {
                self.counted_cycles += 1;
                let emissions = trigger.emissions(schedule);
                self.firing_sum += emissions.len() as u64;
                let mut offsets: Vec<_> = emissions.iter().map(|e| e.offset).collect();
                offsets.sort();
                offsets.dedup();
                self.slot_sum += offsets.len() as u64;
                self.period_sum_s += trigger.period(schedule).as_secs_f64();
            }
            self.due
                .entry((end * 1e9) as i64)
                .or_default()
                .push(trigger.cycle);
            // As on the mesh: every MSU hears every trigger and matches its
            // arrivals to one itself (`ickon_msu::cycle_match`).
            for m in &mut self.members {
                m.msu.feed(MsuEvent::Trigger(trigger.clone()));
            }
            self.triggers.insert(trigger.cycle, trigger);
        }
        for b in control.take_fired() {
            self.emissions
                .entry(b.cycle)
                .or_default()
                .push((b.tx_id, b.actual.as_secs_f64()));
        }
    }

    /// Delivers every cycle due by `t` to every member; their fixes go to
    /// the central unit with their next summaries and, when `scoring`, are
    /// counted.
    fn deliver_due(&mut self, t: f64, scoring: bool) {
        let now_ns = (t * 1e9) as i64;
        let ready: Vec<i64> = self.due.range(..=now_ns).map(|(k, _)| *k).collect();
        for key in ready {
            for k in self.due.remove(&key).unwrap_or_default() {
                let fired = self.emissions.remove(&k).unwrap_or_default();
                if self.triggers.remove(&k).is_none() {
                    continue;
                }
                if fired.is_empty() {
                    continue;
                }
                self.deliver_cycle(k, &fired, scoring);
            }
        }
    }

    /// Delivers cycle `k`, whose bursts `fired`, to every member.
    fn deliver_cycle(&mut self, k: u64, fired: &[(u32, f64)], scoring: bool) {
        let schedule = self.control.schedule_for(k).clone();
        for m in &mut self.members {
            let msg = m.world.arrivals_from_emissions(fired);
            m.msu.feed(MsuEvent::Schedule(schedule.clone()));
            if let Some(fix) = m.msu.feed(MsuEvent::Arrivals(msg)).fix {
                let calibrated = fix.survey_version != 0;
                let used = fix.used.len() as u64;
                // To the central unit with the robot's next summary.
                m.summary.on_fix(&fix);
                if scoring {
                    m.fixes += 1;
                    m.signals_used += used;
                    m.calibrated_fixes += u64::from(calibrated);
                }
            }
        }
    }

    /// Forgets the oldest triggered cycle if it never fired within a
    /// second of its end (a whole schedule may take longer than a second
    /// on a large open site: counting from its start would drop every one).
    fn forget_stale(&mut self, t: f64) {
        let stale = self.triggers.keys().next().copied().filter(|&k| {
            let trigger = &self.triggers[&k];
            let end = trigger.start.as_secs_f64()
                + trigger.period(self.control.schedule_for(k)).as_secs_f64()
                + self.max_flight_s;
            end < t - 1.0
        });
        if let Some(k) = stale {
            self.triggers.remove(&k);
            self.emissions.remove(&k);
        }
    }

    /// Sends each member's summary to the central unit when one is due and,
    /// when `scoring`, records its error against the truth at `t`.
    fn sample_poses(&mut self, t: f64, scoring: bool) {
        for m in &mut self.members {
            let Some(pose) = m.msu.core().pose() else {
                continue;
            };
            if scoring {
                let truth = m.world.truth(t);
                let err = (pose.x_m - truth.x_m).hypot(pose.y_m - truth.y_m);
                m.errors_mm.push(err * 1e3);
            }
            if let Some(summary) = m.summary.on_pose(&pose) {
                self.control.send_to_central(CentralEvent::Summary {
                    robot: m.id.clone(),
                    summary: Box::new(summary),
                });
            }
        }
    }

    /// The run's results, per robot and for the fleet.
    fn results(self) -> FleetOutput {
        let config = self.config;
        let scored_s = (config.duration_s - config.warm_up_s).max(1e-9);
        let mut total = CollisionCounts::default();
        let robots = self
            .members
            .into_iter()
            .map(|m| m.result(scored_s, &mut total))
            .collect();
        let counted_cycles = self.counted_cycles;
        let per_cycle = |sum: f64| {
            if counted_cycles == 0 {
                0.0
            } else {
                sum / counted_cycles as f64
            }
        };
        FleetOutput {
            robots,
            cycles_per_s: counted_cycles as f64 / scored_s,
            mean_firing: per_cycle(self.firing_sum as f64),
            slots_per_cycle: per_cycle(self.slot_sum as f64),
            mean_slot_ms: if self.slot_sum == 0 {
                0.0
            } else {
                1e3 * self.period_sum_s / self.slot_sum as f64
            },
            plan: *self.control.central().plan_stats(),
            transmitters: self.control.central().latest_schedule().emissions.len(),
            collisions: total,
            survey_fixes_taken: self
                .control
                .central()
                .survey()
                .map(|p| p.calibration().fixes_taken()),
            transmitter_events: self.transmitter_events,
            air: self.air,
        }
    }
}

impl Member {
    /// This robot's results over `scored_s` seconds; its collisions are
    /// added to `total`.
    fn result(mut self, scored_s: f64, total: &mut CollisionCounts) -> RobotResult {
        let c = self.world.collision_counts();
        total.add(&c);
        let per_window = ((ERROR_WINDOW_S / POSE_DT_S).round() as usize).max(1);
        let window_err_mm = self
            .errors_mm
            .chunks(per_window)
            .map(|w| (!w.is_empty()).then(|| w.iter().sum::<f64>() / w.len() as f64))
            .collect();
        self.errors_mm.sort_by(f64::total_cmp);
        let n = self.errors_mm.len();
        RobotResult {
            id: self.id,
            route: self.route,
            fixes_per_s: self.fixes as f64 / scored_s,
            signals_per_fix: if self.fixes == 0 {
                0.0
            } else {
                self.signals_used as f64 / self.fixes as f64
            },
            mean_err_mm: if n == 0 {
                f64::NAN
            } else {
                self.errors_mm.iter().sum::<f64>() / n as f64
            },
            p95_err_mm: if n == 0 {
                f64::NAN
            } else {
                self.errors_mm[((n as f64 * 0.95) as usize).min(n - 1)]
            },
            collisions: c,
            calibrated_fixes: self.calibrated_fixes,
            refused_inputs: self.msu.refusal_summary(),
            window_err_mm,
        }
    }
}

#[cfg(test)]
mod tests;
