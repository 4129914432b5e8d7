//! [`MsuCore`]: arrivals -> fix -> estimator -> pose, and odometry, gyro and
//! obstacle ranges -> estimator. Fed with messages, never reads a clock.

use ickon_fusion::estimator::{
    EncoderSample, Estimator, EstimatorError, FixSample, GyroSample, Input, RangeDifferenceSample,
    RangeSample, WheelGeometry,
};
use ickon_fusion::tdoa;
use ickon_proto::msg::control::{Schedule, TransmitterEntry};
use ickon_proto::msg::robot::{
    Fix, FixQuality, Imu, ObstacleRanges, Odometry, RobotPose, UltrasoundArrivals,
};
use nalgebra::{Vector2, Vector3};

use crate::assembly::{AssemblyError, assemble};

/// What the MSU knows about its site and its robot.
#[derive(Debug, Clone, PartialEq)]
pub struct MsuConfig {
    /// Speed of sound the MSU assumes, m/s.
    pub speed_of_sound_m_s: f64,
    /// Height of the receivers above the floor, metres.
    pub height_m: f64,
    /// Pointing angle of each receiver from the heading, counter-clockwise, radians.
    pub receiver_angles_rad: Vec<f64>,
    /// The transmitter lookup table.
    pub transmitters: Vec<TransmitterEntry>,
    /// The robot's nominal drive geometry (turns encoder ticks into metres).
    pub wheels: WheelGeometry,
    /// One-sigma timing noise of an arrival, seconds (weights the fix covariance).
    pub timing_sigma_s: f64,
    /// Largest range residual a used signal may keep, metres (reflection gate).
    pub residual_gate_m: f64,
    /// Floor area a fix must lie in (`[min_x, min_y]`, `[max_x, max_y]`, metres):
    /// a solution outside cannot be the robot (a reflection or a wrong root).
    pub floor_bounds_m: Option<[[f64; 2]; 2]>,
    /// Largest acceptable one-sigma position uncertainty of a fix, metres
    /// (larger: degenerate geometry, reported as no fix).
    pub max_fix_sigma_m: f64,
}

/// Why a message could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MsuError {
    /// No schedule yet: arrivals cannot be matched to emissions.
    #[error("no schedule received yet")]
    NoSchedule,
    /// The cycle could not be assembled.
    #[error(transparent)]
    Assembly(#[from] AssemblyError),
    /// The cycle's signals are malformed (cannot come from a working MSU).
    #[error(transparent)]
    Solve(#[from] tdoa::SolveError),
    /// The estimator rejected the input.
    #[error(transparent)]
    Estimator(#[from] EstimatorError),
}

/// The per-robot MSU state machine.
pub struct MsuCore {
    config: MsuConfig,
    schedule: Option<Schedule>,
    estimator: Box<dyn Estimator>,
    fix_seq: u64,
}

impl MsuCore {
    /// A core hosting `estimator`.
    pub fn new(config: MsuConfig, estimator: Box<dyn Estimator>) -> Self {
        Self {
            config,
            schedule: None,
            estimator,
            fix_seq: 0,
        }
    }

    /// Installs the schedule the arrivals are matched against.
    pub fn set_schedule(&mut self, schedule: Schedule) {
        self.schedule = Some(schedule);
    }

    /// The hosted estimator's name.
    pub fn estimator_name(&self) -> &'static str {
        self.estimator.name()
    }

    /// The solver set-up: 2D with the MSU height known, the timing noise as
    /// range noise, the reflection gate, and the floor as the allowed area.
    fn solver_config(&self) -> tdoa::SolverConfig {
        let height_m = self.config.height_m;
        tdoa::SolverConfig {
            mode: tdoa::Mode::TwoD { height_m },
            sigma_range_m: (self.config.speed_of_sound_m_s * self.config.timing_sigma_s).max(1e-6),
            gate: tdoa::Gate::Metres(self.config.residual_gate_m),
            allowed_area_m: self.config.floor_bounds_m.map(|[lo, hi]| tdoa::Aabb {
                min_m: Vector3::new(lo[0], lo[1], height_m),
                max_m: Vector3::new(hi[0], hi[1], height_m),
            }),
            ..tdoa::SolverConfig::default()
        }
    }

    /// Solves one cycle (seed 000 eq. 1-3 with refinement and reflection
    /// rejection, [`tdoa::solve`]) and hands the fix to the estimator.
    /// `Ok(None)`: no fix this cycle (too few or inconsistent signals,
    /// degenerate geometry, a solution off the floor or too uncertain).
    pub fn on_arrivals(&mut self, msg: &UltrasoundArrivals) -> Result<Option<Fix>, MsuError> {
        let schedule = self.schedule.as_ref().ok_or(MsuError::NoSchedule)?;
        let c = self.config.speed_of_sound_m_s;
        let cycle = assemble(msg, schedule, &self.config.transmitters, c)?;
        self.feed_range_differences(&cycle.signals);
        let signals: Vec<tdoa::Signal> = cycle
            .signals
            .iter()
            .map(|s| tdoa::Signal {
                tx_id: s.tx_id,
                tx_m: Vector3::from(s.tx_m),
                pseudo_range_m: s.pseudo_range_m,
            })
            .collect();
        let mut sol = match tdoa::solve(&signals, &self.solver_config()) {
            Ok(sol) => sol,
            Err(e) if e.is_bad_input() => return Err(MsuError::Solve(e)),
            Err(_) => return Ok(None),
        };
        if let (tdoa::Quality::Ambiguous, Some(other)) = (sol.quality, sol.alternative_m) {
            // Two roots fit: keep the one nearer to where the robot is believed to be.
            if let Some(p) = self.estimator.pose() {
                let here = Vector3::new(p.x_m, p.y_m, self.config.height_m);
                if (other - here).norm() < (sol.position_m - here).norm() {
                    sol.alternative_m = Some(sol.position_m);
                    sol.position_m = other;
                }
            }
        }
        let cov = sol.covariance_xy_m2();
        let sigma_m = cov.trace().max(0.0).sqrt();
        if !(sigma_m.is_finite() && sigma_m <= self.config.max_fix_sigma_m) {
            return Ok(None);
        }
        let [x_m, y_m] = [sol.position_m[0], sol.position_m[1]];
        let mut rejected = cycle.rejected.clone();
        rejected.extend(sol.rejected.iter().map(|r| r.tx_id));
        // Seed 000 s3.1.3: heading from the first emitted signal used (eq. 4-6).
        let heading = sol.used_tx_ids.first().and_then(|id| {
            let s = cycle.signals.iter().find(|s| s.tx_id == *id)?;
            tdoa::heading_from_first_receiver(
                Vector2::new(s.tx_m[0], s.tx_m[1]),
                Vector2::new(x_m, y_m),
                usize::from(s.receiver_id),
                &self.config.receiver_angles_rad,
            )
            .ok()
        });
        let quality = match sol.quality {
            tdoa::Quality::Good => FixQuality::Good,
            tdoa::Quality::Minimal => FixQuality::Minimal,
            tdoa::Quality::Ambiguous => FixQuality::Ambiguous,
            tdoa::Quality::Suspect => FixQuality::Suspect,
        };
        let fix = Fix {
            stamp: cycle.stamp,
            arrivals_seq: msg.seq,
            x_m,
            y_m,
            z_m: self.config.height_m,
            covariance: [
                cov[(0, 0)],
                cov[(0, 1)],
                0.0,
                cov[(1, 0)],
                cov[(1, 1)],
                0.0,
                0.0,
                0.0,
                0.0,
            ],
            heading_rad: heading.unwrap_or(0.0),
            heading_valid: heading.is_some(),
            used: sol.used_tx_ids,
            rejected,
            residuals_m: sol.residuals_m,
            quality,
        };
        self.fix_seq = msg.seq;
        self.estimator.handle(&Input::Fix(FixSample {
            t_s: fix.stamp.as_secs_f64(),
            x_m,
            y_m,
            covariance: cov,
            heading_rad: heading,
        }))?;
        Ok(Some(fix))
    }

    /// Hands the cycle's arrivals to the estimator one time difference at a
    /// time (for tightly-coupled filters such as `tdoa-ekf`; the others
    /// ignore them), before and whether or not a fix can be solved. Pairs
    /// are consecutive in emission order: the robot moves only during one
    /// slot between the two arrivals of a pair (about 1 cm at 0.3 m/s),
    /// where a common reference would span the whole cycle. Each pair is
    /// stamped at its later arrival; its sigma is that of two arrivals.
    fn feed_range_differences(&mut self, signals: &[crate::assembly::Signal]) {
        let sigma_m =
            std::f64::consts::SQRT_2 * self.config.speed_of_sound_m_s * self.config.timing_sigma_s;
        for pair in signals.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            let sample = RangeDifferenceSample {
                t_s: b.t_arrival.as_secs_f64(),
                a_m: a.tx_m,
                b_m: b.tx_m,
                d_m: b.pseudo_range_m - a.pseudo_range_m,
                sigma_m,
            };
            // A rejected difference (a reflection failing the physical check,
            // an outlier at the gate, one too late for the history) leaves
            // the estimator as it was: the filter counts it, nothing else to do.
            let _ = self.estimator.handle(&Input::RangeDifference(sample));
        }
    }

    /// Feeds wheel odometry (its encoder ticks, with the nominal geometry).
    pub fn on_odometry(&mut self, odom: &Odometry) -> Result<(), MsuError> {
        self.estimator.handle(&Input::Encoders(EncoderSample {
            t_s: odom.stamp.as_secs_f64(),
            left_ticks: odom.left_ticks,
            right_ticks: odom.right_ticks,
            geometry: self.config.wheels,
        }))?;
        Ok(())
    }

    /// Feeds one gyro sample.
    pub fn on_imu(&mut self, imu: &Imu) -> Result<(), MsuError> {
        self.estimator.handle(&Input::Gyro(GyroSample {
            t_s: imu.stamp.as_secs_f64(),
            rate_rad_s: imu.gyro_z_rad_s,
        }))?;
        Ok(())
    }

    /// Feeds one obstacle-sensor sample (the single front infrared stands for both sides).
    pub fn on_range(&mut self, r: &ObstacleRanges) -> Result<(), MsuError> {
        let ir = r.ir_valid.then_some(r.ir_m);
        self.estimator.handle(&Input::Range(RangeSample {
            t_s: r.stamp.as_secs_f64(),
            left_ultrasonic_m: r.left_valid.then_some(r.left_m),
            right_ultrasonic_m: r.right_valid.then_some(r.right_m),
            left_ir_m: ir,
            right_ir_m: ir,
            planned_heading_rad: None,
        }))?;
        Ok(())
    }

    /// The current fused pose, once the estimator is initialised.
    pub fn pose(&self) -> Option<RobotPose> {
        let p = self.estimator.pose()?;
        let c = p.covariance;
        Some(RobotPose {
            stamp: ickon_proto::time::Time::from_secs_f64(p.t_s),
            x_m: p.x_m,
            y_m: p.y_m,
            theta_rad: p.theta_rad,
            covariance: [
                c[(0, 0)],
                c[(0, 1)],
                c[(0, 2)],
                c[(1, 0)],
                c[(1, 1)],
                c[(1, 2)],
                c[(2, 0)],
                c[(2, 1)],
                c[(2, 2)],
            ],
            estimator: self.estimator.name().to_owned(),
            fix_seq: self.fix_seq,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_fusion::estimator::build_by_name;
    use ickon_proto::msg::control::Emission;
    use ickon_proto::msg::robot::Arrival;
    use ickon_proto::time::{Duration, Time};

    const C: f64 = 343.0;
    const TX: [(u32, [f64; 3]); 5] = [
        (1, [0.0, 0.0, 2.8]),
        (2, [5.0, 0.0, 2.6]),
        (3, [5.0, 4.0, 2.8]),
        (4, [0.0, 4.0, 2.6]),
        (5, [2.5, 2.0, 2.7]),
    ];

    fn core() -> MsuCore {
        let config = MsuConfig {
            speed_of_sound_m_s: C,
            height_m: 0.5,
            receiver_angles_rad: (0..6).map(|i| f64::from(i) * 60f64.to_radians()).collect(),
            transmitters: TX
                .iter()
                .map(|(id, p)| TransmitterEntry {
                    tx_id: *id,
                    cell_id: "a".into(),
                    x_m: p[0],
                    y_m: p[1],
                    z_m: p[2],
                })
                .collect(),
            wheels: WheelGeometry {
                wheel_base_m: 0.33,
                left_m_per_tick: 1e-4,
                right_m_per_tick: 1e-4,
            },
            timing_sigma_s: 10e-6,
            residual_gate_m: 0.05,
            floor_bounds_m: Some([[0.0, 0.0], [5.0, 4.0]]),
            max_fix_sigma_m: 0.5,
        };
        let mut core = MsuCore::new(config, build_by_name("msu-raw").unwrap());
        core.set_schedule(Schedule {
            version: 1,
            effective_cycle: 0,
            cycle_period: Duration::from_millis(200),
            slot_length: Duration::from_millis(40),
            emissions: TX
                .iter()
                .enumerate()
                .map(|(i, (id, _))| Emission {
                    tx_id: *id,
                    cell_id: "a".into(),
                    offset: Duration::from_millis(40 * i as i64),
                    slot: i as u32,
                })
                .collect(),
            active_cells: vec!["a".into()],
        });
        core
    }

    fn arrivals(p: [f64; 3], late_m: &[(u32, f64)]) -> UltrasoundArrivals {
        let start_s = 10.0;
        let arrivals = TX
            .iter()
            .enumerate()
            .map(|(i, (id, t))| {
                let d =
                    ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt();
                let extra = late_m
                    .iter()
                    .find(|(k, _)| k == id)
                    .map_or(0.0, |(_, e)| *e);
                Arrival {
                    tx_id: *id,
                    receiver_id: 0,
                    t_arrival: Time::from_secs_f64(start_s + 0.04 * i as f64 + (d + extra) / C),
                }
            })
            .collect();
        UltrasoundArrivals { seq: 7, arrivals }
    }

    #[test]
    fn exact_arrivals_give_an_exact_fix_and_the_estimator_takes_it() {
        let mut core = core();
        let fix = core
            .on_arrivals(&arrivals([1.7, 2.9, 0.5], &[]))
            .unwrap()
            .unwrap();
        assert!(
            (fix.x_m - 1.7).abs() < 1e-5 && (fix.y_m - 2.9).abs() < 1e-5,
            "{fix:?}"
        );
        assert_eq!(fix.used.len(), 5);
        assert_eq!(fix.quality, FixQuality::Good);
        let pose = core.pose().unwrap();
        assert!((pose.x_m - 1.7).abs() < 1e-5);
        assert_eq!(pose.fix_seq, 7);
    }

    #[test]
    fn a_reflected_arrival_is_rejected_when_the_others_agree() {
        let mut core = core();
        let fix = core
            .on_arrivals(&arrivals([3.2, 1.1, 0.5], &[(3, 0.6)]))
            .unwrap()
            .unwrap();
        assert_eq!(fix.rejected, vec![3]);
        assert!(
            (fix.x_m - 3.2).abs() < 1e-4 && (fix.y_m - 1.1).abs() < 1e-4,
            "{fix:?}"
        );
    }

    #[test]
    fn a_tightly_coupled_estimator_converges_on_range_differences_alone() {
        let mut core = core();
        core.estimator = build_by_name("tdoa-ekf").unwrap();
        let truth = [2.2, 1.4, 0.5];
        for k in 0..20 {
            let mut msg = arrivals(truth, &[]);
            msg.seq = k;
            for a in &mut msg.arrivals {
                a.t_arrival =
                    a.t_arrival + ickon_proto::time::Duration::from_millis(200 * k as i64);
            }
            let _ = core.on_arrivals(&msg);
        }
        let pose = core
            .pose()
            .expect("the filter started from the differences");
        let err = ((pose.x_m - truth[0]).powi(2) + (pose.y_m - truth[1]).powi(2)).sqrt();
        assert!(err < 0.01, "error {err} m: {pose:?}");
    }

    #[test]
    fn arrivals_before_any_schedule_are_an_error() {
        let mut c = core();
        c.schedule = None;
        assert_eq!(
            c.on_arrivals(&arrivals([1.0, 1.0, 0.5], &[])),
            Err(MsuError::NoSchedule)
        );
    }
}
