//! An emulated Marvelmind hedgehog as a sans-IO generator: a robot drives
//! a route of the site (the simulated world's robot), and at the kit's
//! update rate the hedgehog writes what a real one would: the raw
//! distances to the site's beacons (`0x0004`), with seeded Gaussian range
//! noise and at the speed of sound the kit was set to, and its own
//! position (`0x0011`), trilaterated from those same distances as the kit
//! does. On request it misbehaves as a serial line does (random bytes
//! before a frame, frames lost). `ickon emulate marvelmind` drives it over
//! a pseudo-terminal or TCP; the tests drive it directly.

use ickon_fusion::estimator::BeaconRangeSample;
use ickon_fusion::ranging;
use ickon_marvelmind::{BeaconDistance, HedgeTime, Packet, Position, RawDistances};
use ickon_proto::site::Site;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use ickon_sim::profile::EncoderNoise;
use ickon_sim::rng::{chance, normal, stream};
use ickon_sim::robot::{DriveSpec, Robot, RobotState};

/// A hedgehog reports at most four distances per update.
pub const MAX_BEACONS: usize = 4;

/// What the emulated hedgehog is and how it misbehaves.
#[derive(Debug, Clone, PartialEq)]
pub struct HedgehogSpec {
    /// The robot of the site it rides on (its route).
    pub robot: String,
    /// Updates per second.
    pub rate_hz: f64,
    /// One-sigma noise of one distance, metres.
    pub range_sigma_m: f64,
    /// The speed of sound the kit was set to, m/s (the site's air sets the
    /// true one).
    pub kit_speed_of_sound_m_s: f64,
    /// Chance that a frame is preceded by random bytes.
    pub garbage: f64,
    /// Chance that a frame is not written.
    pub drop: f64,
    /// The hedgehog's own address.
    pub address: u8,
    /// Seed of its random draws.
    pub seed: u64,
}

/// One update: where the robot truly was and the bytes written.
#[derive(Debug, Clone, PartialEq)]
pub struct Update {
    /// Time since the emulation started, seconds.
    pub t_s: f64,
    /// The robot's true state.
    pub truth: RobotState,
    /// The frames (and any garbage), as written to the line.
    pub bytes: Vec<u8>,
}

/// Why a hedgehog cannot be emulated on a site.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HedgehogError {
    /// The robot is not in the site, or its route is missing.
    #[error("{0}")]
    Robot(String),
    /// A beacon's id is not a Marvelmind address.
    #[error("transmitter {0} cannot be a Marvelmind beacon: addresses are 1-254")]
    Address(u32),
    /// Fewer than three beacons: no position.
    #[error("the site has {0} transmitter(s); a hedgehog needs at least 3 beacons")]
    TooFewBeacons(usize),
}

/// An emulated hedgehog.
#[derive(Debug)]
pub struct EmulatedHedgehog {
    spec: HedgehogSpec,
    robot: Robot,
    beacons: Vec<(u8, [f64; 3])>,
    height_m: f64,
    site_speed_of_sound_m_s: f64,
    noise: ChaCha8Rng,
    faults: ChaCha8Rng,
    updates: u64,
}

/// Steps of the robot's motion per update (pure pursuit is stepped at
/// 100 Hz or finer, as the simulated world does).
const MOTION_STEP_S: f64 = 0.01;

impl EmulatedHedgehog {
    /// A hedgehog on `spec.robot` of `site`, whose transmitters are the
    /// kit's beacons (ids as addresses).
    pub fn new(site: &Site, spec: HedgehogSpec) -> Result<Self, HedgehogError> {
        let robot = site
            .robots
            .iter()
            .find(|r| r.id == spec.robot)
            .ok_or_else(|| {
                HedgehogError::Robot(format!("no robot {:?} in the site", spec.robot))
            })?;
        let route = site
            .route(&robot.route)
            .ok_or_else(|| HedgehogError::Robot(format!("robot {:?} has no route", spec.robot)))?;
        let beacons = site
            .transmitters
            .iter()
            .map(|t| match u8::try_from(t.id) {
                Ok(a) if (1..=254).contains(&a) => Ok((a, t.position_m)),
                _ => Err(HedgehogError::Address(t.id)),
            })
            .collect::<Result<Vec<_>, _>>()?;
        if beacons.len() < 3 {
            return Err(HedgehogError::TooFewBeacons(beacons.len()));
        }
        let no_slip = EncoderNoise {
            left_radius_error: 0.0,
            right_radius_error: 0.0,
            wheel_base_error: 0.0,
            slip_sigma: 0.0,
            slip_per_rad_s: 0.0,
        };
        Ok(Self {
            robot: Robot::new(
                DriveSpec::default(),
                no_slip,
                route,
                stream(spec.seed, "hedgehog-drive"),
            ),
            beacons,
            height_m: site.msu.height_m,
            site_speed_of_sound_m_s: site.speed_of_sound_m_s,
            noise: stream(spec.seed, "hedgehog-ranges"),
            faults: stream(spec.seed, "hedgehog-faults"),
            updates: 0,
            spec,
        })
    }

    /// The time between updates, seconds.
    pub fn period_s(&self) -> f64 {
        1.0 / self.spec.rate_hz
    }

    /// Drives the robot one update period on and writes what the hedgehog
    /// measured there.
    pub fn update(&mut self) -> Update {
        let period_s = self.period_s();
        let steps = (period_s / MOTION_STEP_S).ceil().max(1.0);
        for _ in 0..steps as usize {
            self.robot.step(period_s / steps, true);
        }
        self.updates += 1;
        let t_s = self.updates as f64 * period_s;
        let truth = self.robot.state;
        let (bytes, _) = self.measure(t_s, [truth.x_m, truth.y_m]);
        Update { t_s, truth, bytes }
    }

    /// What the hedgehog writes when it is at `at_xy_m` at `t_s` seconds
    /// since it started (its time stamps), and the position it reports
    /// there (`None` when it has none): the distances to the four nearest
    /// beacons with the kit's noise, and its own position from them. The
    /// world of `ickon sim` feeds it the robot's true position this way.
    pub fn measure(&mut self, t_s: f64, at_xy_m: [f64; 2]) -> (Vec<u8>, Option<[f64; 2]>) {
        let at = [at_xy_m[0], at_xy_m[1], self.height_m];
        // The four nearest beacons, as the kit hears the closest ones best.
        let mut nearest: Vec<(f64, u8, [f64; 3])> = self
            .beacons
            .iter()
            .map(|&(a, b)| (distance(at, b), a, b))
            .collect();
        nearest.sort_by(|x, y| x.0.total_cmp(&y.0));
        nearest.truncate(MAX_BEACONS);
        let kit_scale = self.spec.kit_speed_of_sound_m_s / self.site_speed_of_sound_m_s;
        let mut slots = [BeaconDistance::default(); MAX_BEACONS];
        let mut ranges = Vec::new();
        for (slot, &(true_m, address, beacon_m)) in slots.iter_mut().zip(&nearest) {
            let measured_m = (true_m + normal(&mut self.noise, self.spec.range_sigma_m)).max(0.001);
            *slot = BeaconDistance {
                beacon: address,
                distance_mm: (measured_m * kit_scale * 1000.0).round() as u32,
            };
            ranges.push(BeaconRangeSample {
                t_s,
                beacon_m,
                range_m: measured_m,
                sigma_m: self.spec.range_sigma_m,
            });
        }
        let time_ms = (t_s * 1000.0).round() as u32;
        let mut packets = vec![Packet::RawDistances(RawDistances {
            hedge: self.spec.address,
            distances: slots,
            time: HedgeTime::Counter(time_ms),
            time_shift_ms: 0,
        })];
        let fix = ranging::trilaterate(&ranges, self.height_m);
        packets.push(Packet::Position(Position {
            time: HedgeTime::Counter(time_ms),
            x_mm: fix.as_ref().map_or(0, |f| (f.x_m * 1000.0).round() as i32),
            y_mm: fix.as_ref().map_or(0, |f| (f.y_m * 1000.0).round() as i32),
            z_mm: (self.height_m * 1000.0).round() as i32,
            // Bit 0: no position; bit 1: the time is in milliseconds.
            flags: if fix.is_some() { 0b10 } else { 0b11 },
            address: self.spec.address,
            heading_raw: 0,
        }));
        let mut bytes = Vec::new();
        for packet in packets {
            if chance(&mut self.faults, self.spec.garbage) {
                let n = self.faults.random_range(1..=32);
                bytes.extend((0..n).map(|_| self.faults.random::<u8>()));
            }
            if chance(&mut self.faults, self.spec.drop) {
                continue;
            }
            // Every packet here fits a frame: its layout is fixed.
            if let Ok(frame) = packet.encode() {
                bytes.extend(frame);
            }
        }
        (bytes, fix.map(|f| [f.x_m, f.y_m]))
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use ickon_marvelmind::Deframer;

    use super::*;

    fn site() -> Site {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../deploy/sites/marvelmind-lab.toml"
        ))
        .expect("the shipped site");
        Site::from_toml(&text, "marvelmind-lab.toml").expect("valid")
    }

    fn spec(seed: u64) -> HedgehogSpec {
        HedgehogSpec {
            robot: "r1".into(),
            rate_hz: 8.0,
            range_sigma_m: 0.02,
            kit_speed_of_sound_m_s: 343.0,
            garbage: 0.0,
            drop: 0.0,
            address: 9,
            seed,
        }
    }

    fn packets(bytes: &[u8]) -> Vec<Packet> {
        let mut out = Vec::new();
        Deframer::new().feed(bytes, |f| {
            if let Ok(frame) = f {
                out.extend(Packet::decode(&frame).expect("decodes"));
            }
        });
        out
    }

    #[test]
    fn distances_are_the_true_ones_with_the_noise_asked_for() {
        let site = site();
        let mut h = EmulatedHedgehog::new(&site, spec(3)).expect("a hedgehog");
        let mut errors = Vec::new();
        let scale = site.speed_of_sound_m_s / 343.0;
        for _ in 0..400 {
            let u = h.update();
            let at = [u.truth.x_m, u.truth.y_m, site.msu.height_m];
            let p = packets(&u.bytes);
            let Packet::RawDistances(d) = &p[0] else {
                panic!("{p:?}")
            };
            for slot in d.distances {
                let b = site.transmitter(u32::from(slot.beacon)).expect("a beacon");
                let measured_m = f64::from(slot.distance_mm) / 1000.0 * scale;
                errors.push(measured_m - distance(at, b.position_m));
            }
            assert!(matches!(p[1], Packet::Position(_)));
        }
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let sd = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        // 1600 draws: the mean within 4 standard errors, the sigma within 10 %.
        assert!(mean.abs() < 4.0 * 0.02 / n.sqrt(), "mean {mean}");
        assert!((sd - 0.02).abs() < 0.002, "sd {sd}");
    }

    #[test]
    fn the_same_seed_writes_the_same_bytes_and_the_robot_moves() {
        let site = site();
        let run = |seed| {
            let mut h = EmulatedHedgehog::new(&site, spec(seed)).expect("a hedgehog");
            (0..80).map(|_| h.update()).collect::<Vec<_>>()
        };
        let (a, b, c) = (run(1), run(1), run(2));
        assert_eq!(a, b);
        assert_ne!(a, c);
        let moved = (a[0].truth.x_m - a[79].truth.x_m).hypot(a[0].truth.y_m - a[79].truth.y_m);
        assert!(moved > 1.0, "{moved} m in 10 s");
    }

    #[test]
    fn faults_cost_frames_but_never_the_stream() {
        let site = site();
        let faulty = HedgehogSpec {
            garbage: 0.3,
            drop: 0.2,
            ..spec(5)
        };
        let mut h = EmulatedHedgehog::new(&site, faulty).expect("a hedgehog");
        let bytes: Vec<u8> = (0..200).flat_map(|_| h.update().bytes).collect();
        let found = packets(&bytes).len();
        // 400 frames written less about a fifth dropped; garbage may cost
        // a frame now and then, never most of them.
        assert!((250..=360).contains(&found), "{found}");
    }

    #[test]
    fn a_robot_the_site_does_not_have_is_refused_by_name() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../deploy/sites/lab.toml"
        ))
        .expect("the shipped site");
        let lab = Site::from_toml(&text, "lab.toml").expect("valid");
        let err = EmulatedHedgehog::new(
            &lab,
            HedgehogSpec {
                robot: "nobody".into(),
                ..spec(1)
            },
        )
        .expect_err("no such robot");
        assert!(err.to_string().contains("nobody"), "{err}");
    }
}
