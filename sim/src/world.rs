//! The simulated world of one robot (its random streams are labelled by its
//! route, so robots on different routes draw independent numbers while the
//! site-wide errors, survey and cell sync, are shared): its true motion and history, its
//! sensors, its MSU clock, and the cells' emissions as it hears them.

use std::collections::VecDeque;

use ickon_proto::msg::robot::{Arrival, Imu, ObstacleRanges, Odometry, UltrasoundArrivals};
use ickon_proto::site::{Route, Site};
use ickon_proto::time::Time;
use rand_chacha::ChaCha8Rng;

use crate::acoustic;
use crate::air::AirField;
use crate::clock::DeviceClock;
use crate::collision::{self, BurstTiming, CollisionCounts, Detection, Sound};
use crate::profile::NoiseProfile;
use crate::rng;
use crate::robot::{DriveSpec, Robot};
use crate::sensors::{self, Gyro, RangerMount};
use crate::tx_faults::{TransmitterFault, TransmitterFaults};

/// How long a burst's sound is remembered for collisions with later bursts,
/// seconds: after it, every profile's tail is far under any burst.
const SOUND_MEMORY_S: f64 = 0.25;

/// A true pose at a true time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// True time, seconds.
    pub t_s: f64,
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians, continuous.
    pub theta_rad: f64,
}

/// One robot in the world.
pub struct World {
    site: Site,
    profile: NoiseProfile,
    /// The robot.
    pub robot: Robot,
    /// Drive geometry.
    pub drive: DriveSpec,
    history: VecDeque<TruthSample>,
    gyro: Gyro,
    last_gyro_theta: f64,
    /// The MSU's (and robot computer's) clock.
    pub msu_clock: DeviceClock,
    acoustic_rng: ChaCha8Rng,
    collision_rng: ChaCha8Rng,
    timing: BurstTiming,
    /// Sounds of the last cycles that may still collide with or mask the
    /// next cycle's bursts (pruned after [`SOUND_MEMORY_S`]).
    recent_sounds: Vec<Sound>,
    collisions: CollisionCounts,
    ranger_rng: ChaCha8Rng,
    air: AirField,
    faults: TransmitterFaults,
    /// Draws of the weak transmitters' losses: a stream of their own, so
    /// that a fault changes nothing else the world draws.
    fault_rng: ChaCha8Rng,
    odom: [f64; 3],
    last_ticks: (i64, i64),
    seq: u64,
}

impl World {
    /// The world of one robot on `route`, its random streams derived from `seed`.
    pub fn new(site: &Site, route: &Route, profile: &NoiseProfile, seed: u64) -> Self {
        Self::for_robot(site, route, profile, seed, &route.name)
    }

    /// The world of one robot of a fleet: its own random streams are
    /// labelled `label` (its id), so robots sharing a route draw
    /// independent numbers; the site-wide errors (survey) stay shared.
    pub fn for_robot(
        site: &Site,
        route: &Route,
        profile: &NoiseProfile,
        seed: u64,
        label: &str,
    ) -> Self {
        let drive = DriveSpec::default();
        let robot = Robot::new(
            drive,
            profile.encoders,
            route,
            rng::stream(seed, &format!("robot/{label}/slip")),
        );
        let mut clock_rng = rng::stream(seed, &format!("robot/{label}/clock"));
        let msu_clock = DeviceClock {
            offset_s: rng::normal(&mut clock_rng, profile.clocks.msu_offset_sigma_ms) * 1e-3,
            drift: rng::normal(&mut clock_rng, profile.clocks.msu_drift_sigma_ppm) * 1e-6,
        };
        // The MSU assumes the site's speed of sound; the air is off by the
        // profile's error on average, and varies with time and place.
        let air = AirField::new(
            site,
            &profile.ultrasound.air,
            profile.ultrasound.temperature_error_c,
        );
        let s = robot.state;
        // The world's transmitters hang where they really are; the MSU's table keeps the surveyed values.
        let mut true_site = site.clone();
        let mut survey_rng = rng::stream(seed, "site/survey");
        for t in &mut true_site.transmitters {
            for k in 0..3 {
                t.position_m[k] += rng::normal(&mut survey_rng, profile.ultrasound.survey_sigma_m);
            }
        }
        let mut w = Self {
            site: true_site,
            profile: profile.clone(),
            robot,
            drive,
            history: VecDeque::new(),
            gyro: Gyro::new(
                profile.gyro,
                rng::stream(seed, &format!("robot/{label}/gyro")),
            ),
            last_gyro_theta: s.theta_rad,
            msu_clock,
            acoustic_rng: rng::stream(seed, &format!("robot/{label}/ultrasound")),
            collision_rng: rng::stream(seed, &format!("robot/{label}/collisions")),
            timing: BurstTiming::of(site),
            recent_sounds: Vec::new(),
            collisions: CollisionCounts::default(),
            ranger_rng: rng::stream(seed, &format!("robot/{label}/rangers")),
            air,
            faults: TransmitterFaults::default(),
            fault_rng: rng::stream(seed, &format!("robot/{label}/transmitter-faults")),
            odom: [s.x_m, s.y_m, s.theta_rad],
            last_ticks: (0, 0),
            seq: 0,
        };
        w.record(0.0);
        w
    }

    /// Makes transmitters fail as `faults` say.
    pub fn set_transmitter_faults(&mut self, faults: &[TransmitterFault]) {
        self.faults = TransmitterFaults::new(faults.to_vec());
    }

    /// The site as the world has it: the transmitters where they really
    /// hang (the MSU's table keeps the surveyed positions).
    pub fn true_site(&self) -> &Site {
        &self.site
    }

    /// The air the bursts fly through.
    pub fn air(&self) -> &AirField {
        &self.air
    }

    /// The speed of sound a system that knew the air would use at `t_s`
    /// for this robot: the mean of the path speeds from the transmitters
    /// within `range_m` of the receiver (slowness-averaged), m/s; `None`
    /// when none is that near.
    pub fn path_speed_m_s(&self, t_s: f64, range_m: f64) -> Option<f64> {
        let s = self.robot.state;
        let p = [s.x_m, s.y_m, self.site.msu.height_m];
        let mut slowness = 0.0;
        let mut n = 0usize;
        for tx in &self.site.transmitters {
            let d = (0..3)
                .map(|k| (tx.position_m[k] - p[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            if d <= range_m && d > 0.0 {
                slowness += 1.0 / self.air.path_speed_m_s(tx.position_m, p, t_s);
                n += 1;
            }
        }
        (n > 0).then(|| n as f64 / slowness)
    }

    /// What collisions and reverberation did to this robot's detections so far.
    pub fn collision_counts(&self) -> CollisionCounts {
        self.collisions
    }

    /// The current true pose.
    pub fn truth(&self, t_s: f64) -> TruthSample {
        let s = self.robot.state;
        TruthSample {
            t_s,
            x_m: s.x_m,
            y_m: s.y_m,
            theta_rad: s.theta_rad,
        }
    }

    fn record(&mut self, t_s: f64) {
        let sample = self.truth(t_s);
        self.history.push_back(sample);
        while self.history.front().is_some_and(|f| f.t_s < t_s - 3.0) {
            self.history.pop_front();
        }
    }

    /// The true pose at `t_s`, interpolated in the last seconds of history.
    pub fn truth_at(&self, t_s: f64) -> TruthSample {
        let h = &self.history;
        let i = h.partition_point(|s| s.t_s < t_s);
        match (i.checked_sub(1).and_then(|j| h.get(j)), h.get(i)) {
            (Some(a), Some(b)) if b.t_s > a.t_s => {
                let f = (t_s - a.t_s) / (b.t_s - a.t_s);
                TruthSample {
                    t_s,
                    x_m: a.x_m + f * (b.x_m - a.x_m),
                    y_m: a.y_m + f * (b.y_m - a.y_m),
                    theta_rad: a.theta_rad + f * (b.theta_rad - a.theta_rad),
                }
            }
            (_, Some(b)) => TruthSample { t_s, ..*b },
            (Some(a), None) => TruthSample { t_s, ..*a },
            (None, None) => self.truth(t_s),
        }
    }

    /// Advances the robot to `t_s` by `dt_s`.
    pub fn step(&mut self, t_s: f64, dt_s: f64, drive: bool) {
        self.robot.step(dt_s, drive);
        self.record(t_s);
    }

    /// A gyro reading at `t_s`: the mean true rate since the previous one, plus noise.
    pub fn gyro(&mut self, t_s: f64, dt_s: f64) -> Imu {
        let theta = self.robot.state.theta_rad;
        let omega = (theta - self.last_gyro_theta) / dt_s;
        self.last_gyro_theta = theta;
        Imu {
            stamp: self.msu_clock.stamp(t_s),
            gyro_z_rad_s: self.gyro.sample(omega, dt_s),
        }
    }

    /// The wheel encoders and the robot's own dead reckoning at `t_s`.
    pub fn odometry(&mut self, t_s: f64) -> Odometry {
        let s = self.robot.state;
        let left = sensors::ticks(s.left_wheel_rad, self.drive.ticks_per_turn);
        let right = sensors::ticks(s.right_wheel_rad, self.drive.ticks_per_turn);
        let m = self.drive.m_per_tick();
        let dl = (left - self.last_ticks.0) as f64 * m;
        let dr = (right - self.last_ticks.1) as f64 * m;
        self.last_ticks = (left, right);
        let dth = (dr - dl) / self.drive.wheel_base_m;
        let mid = self.odom[2] + 0.5 * dth;
        self.odom[0] += 0.5 * (dl + dr) * mid.cos();
        self.odom[1] += 0.5 * (dl + dr) * mid.sin();
        self.odom[2] += dth;
        Odometry {
            stamp: self.msu_clock.stamp(t_s),
            x_m: self.odom[0],
            y_m: self.odom[1],
            theta_rad: self.odom[2],
            left_ticks: left,
            right_ticks: right,
        }
    }

    /// The obstacle sensors at `t_s`.
    pub fn ranges(&mut self, t_s: f64) -> ObstacleRanges {
        let s = self.robot.state;
        let r = sensors::sample_ranges(
            &self.site,
            &RangerMount::default(),
            &self.profile.obstacles,
            [s.x_m, s.y_m, s.theta_rad],
            &mut self.ranger_rng,
        );
        ObstacleRanges {
            stamp: self.msu_clock.stamp(t_s),
            left_m: r.left_ultrasonic_m.unwrap_or(0.0),
            left_valid: r.left_ultrasonic_m.is_some(),
            right_m: r.right_ultrasonic_m.unwrap_or(0.0),
            right_valid: r.right_ultrasonic_m.is_some(),
            left_ir_m: r.left_ir_m.unwrap_or(0.0),
            left_ir_valid: r.left_ir_m.is_some(),
            right_ir_m: r.right_ir_m.unwrap_or(0.0),
            right_ir_valid: r.right_ir_m.is_some(),
        }
    }

    /// Everything the MSU hears of emissions at known true times
    /// `(tx_id, t_emit_s)`: the real-time world, fed by the cells' burst
    /// reports, calls this once the last burst of a cycle has had time to
    /// arrive. Ids not in the site are ignored.
    pub fn arrivals_from_emissions(&mut self, emissions: &[(u32, f64)]) -> UltrasoundArrivals {
        let indexed: Vec<(usize, f64)> = emissions
            .iter()
            .filter_map(|&(id, t)| {
                let tx = self.site.transmitters.iter().position(|x| x.id == id)?;
                Some((tx, t))
            })
            .collect();
        let mid = if indexed.is_empty() {
            0.0
        } else {
            indexed.iter().map(|e| e.1).sum::<f64>() / indexed.len() as f64
        };
        self.hear_cycle(&indexed, mid)
    }

    /// The arrivals of emissions `(transmitter index, true emission time)`;
    /// `t_guess_s` starts the search for the mean arrival time when the robot
    /// is frozen during the cycle.
    fn hear_cycle(&mut self, emissions: &[(usize, f64)], t_guess_s: f64) -> UltrasoundArrivals {
        let (detections, sounds, strengths) = if self.profile.ultrasound.motion_during_cycle {
            let mut rng = self.acoustic_rng.clone();
            let heard = self.hear_all(emissions, None, &mut rng);
            self.acoustic_rng = rng;
            heard
        } else {
            // Frozen robot: at the mean arrival time, found by fixed-point
            // iteration (arrival times move by v/c per metre of motion).
            let mut t_ref = t_guess_s;
            for _ in 0..4 {
                let mut trial = self.acoustic_rng.clone();
                let (h, _, _) = self.hear_all(emissions, Some(t_ref), &mut trial);
                if !h.is_empty() {
                    t_ref = h.iter().map(|a| a.heard.t_true_s).sum::<f64>() / h.len() as f64;
                }
            }
            let mut rng = self.acoustic_rng.clone();
            let heard = self.hear_all(emissions, Some(t_ref), &mut rng);
            self.acoustic_rng = rng;
            heard
        };
        let detections = if self.faults.is_empty() {
            detections
        } else {
            detections
                .into_iter()
                .zip(strengths)
                .filter(|(_, k)| *k >= 1.0 || rng::chance(&mut self.fault_rng, *k))
                .map(|(d, _)| d)
                .collect()
        };
        let heard = self.collide(detections, sounds);
        let q_s = self.profile.ultrasound.quantisation_us * 1e-6;
        let mut arrivals: Vec<Arrival> = heard
            .iter()
            .map(|h| {
                let mut local = self.msu_clock.local_s(h.t_true_s);
                if q_s > 0.0 {
                    local = (local / q_s).round() * q_s;
                }
                Arrival {
                    tx_id: h.tx_id,
                    receiver_id: h.receiver_id,
                    t_arrival: Time::from_secs_f64(local),
                }
            })
            .collect();
        arrivals.sort_by_key(|a| a.t_arrival);
        self.seq += 1;
        UltrasoundArrivals {
            seq: self.seq,
            arrivals,
        }
    }

    /// This cycle's detections among this cycle's and the recent cycles' sounds.
    fn collide(
        &mut self,
        mut detections: Vec<Detection>,
        sounds: Vec<Sound>,
    ) -> Vec<acoustic::Heard> {
        let mut all = std::mem::take(&mut self.recent_sounds);
        let base = all.len();
        for d in &mut detections {
            d.own = d.own.map(|i| i + base);
        }
        all.extend(sounds);
        let heard = collision::resolve(
            &self.profile.ultrasound.collisions,
            &self.timing,
            &detections,
            &all,
            &mut self.collision_rng,
            &mut self.collisions,
        );
        let latest = all
            .iter()
            .map(|s| s.onset_s)
            .fold(f64::NEG_INFINITY, f64::max);
        all.retain(|s| s.onset_s > latest - SOUND_MEMORY_S);
        self.recent_sounds = all;
        heard
    }

    /// What the detector picks up of each emission, the sound each leaves
    /// at the MSU (direct, in line of sight, within range), and each
    /// detection's transmitter's strength (the probability it is kept, of
    /// a weak transmitter's: [`TransmitterFaults::strength`]). A dead
    /// transmitter makes no sound; a moved one makes it from where it hangs.
    fn hear_all(
        &self,
        emissions: &[(usize, f64)],
        frozen_at: Option<f64>,
        rng: &mut ChaCha8Rng,
    ) -> (Vec<Detection>, Vec<Sound>, Vec<f64>) {
        let h = self.site.msu.height_m;
        let frozen = frozen_at.map(|t| self.truth_at(t));
        let pose_at = |t: f64| {
            let s = frozen.unwrap_or_else(|| self.truth_at(t));
            ([s.x_m, s.y_m, h], s.theta_rad)
        };
        let noise = &self.profile.ultrasound;
        let mut detections = Vec::with_capacity(emissions.len());
        let mut sounds = Vec::with_capacity(emissions.len());
        let mut strengths = Vec::with_capacity(emissions.len());
        for &(tx, t_emit) in emissions {
            let mut moved;
            let mut tx = &self.site.transmitters[tx];
            if !self.faults.is_empty() {
                if self.faults.dead(tx.id, t_emit) {
                    continue;
                }
                let d = self.faults.displacement(tx.id, t_emit);
                if d != [0.0; 3] {
                    moved = tx.clone();
                    for (p, dk) in moved.position_m.iter_mut().zip(d) {
                        *p += dk;
                    }
                    tx = &moved;
                }
            }
            let path = acoustic::propagate(&self.site, &self.air, tx, t_emit, &pose_at);
            let own = if path.in_sight && path.direct_m <= noise.max_range_m {
                sounds.push(Sound {
                    tx_id: tx.id,
                    channel: tx.channel,
                    onset_s: t_emit + path.tau_s,
                    level_db: collision::level_db(&noise.collisions, path.direct_m),
                });
                Some(sounds.len() - 1)
            } else {
                None
            };
            let heard = acoustic::detect(&self.site, noise, tx, t_emit, &path, rng);
            if let Some(heard) = heard {
                detections.push(Detection {
                    heard,
                    channel: tx.channel,
                    own,
                });
                strengths.push(self.faults.strength(tx.id, t_emit));
            }
        }
        (detections, sounds, strengths)
    }
}
