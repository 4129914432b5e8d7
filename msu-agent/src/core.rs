//! [`MsuCore`]: arrivals -> fix -> estimator -> pose, and odometry, gyro and
//! obstacle ranges -> estimator. Fed with messages, never reads a clock.

use ickon_fusion::angle;
use ickon_fusion::estimator::{
    EncoderSample, Estimator, EstimatorError, FixSample, GyroSample, Input, RangeSample,
    WheelGeometry,
};
use ickon_proto::msg::control::{Schedule, TransmitterEntry};
use ickon_proto::msg::robot::{
    Fix, FixQuality, Imu, ObstacleRanges, Odometry, RobotPose, UltrasoundArrivals,
};
use nalgebra::Matrix2;

use crate::assembly::{AssemblyError, assemble};
use crate::solve::solve_2d;

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
    /// The estimator rejected the input.
    #[error(transparent)]
    Estimator(#[from] EstimatorError),
}

/// The per-robot MSU state machine.
pub struct MsuCore {
    config: MsuConfig,
    schedule: Option<Schedule>,
    estimator: Box<dyn Estimator>,
    last_fix_xy: Option<[f64; 2]>,
    fix_seq: u64,
}

impl MsuCore {
    /// A core hosting `estimator`.
    pub fn new(config: MsuConfig, estimator: Box<dyn Estimator>) -> Self {
        Self {
            config,
            schedule: None,
            estimator,
            last_fix_xy: None,
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

    /// Solves one cycle. `Ok(None)`: too few usable signals for a fix.
    pub fn on_arrivals(&mut self, msg: &UltrasoundArrivals) -> Result<Option<Fix>, MsuError> {
        let schedule = self.schedule.as_ref().ok_or(MsuError::NoSchedule)?;
        let c = self.config.speed_of_sound_m_s;
        let cycle = assemble(msg, schedule, &self.config.transmitters, c)?;
        let start = self.last_fix_xy.unwrap_or_else(|| centroid(&cycle.signals));
        let sigma_m = c * self.config.timing_sigma_s;
        let Some(sol) = solve_2d(
            &cycle.signals,
            self.config.height_m,
            start,
            sigma_m,
            self.config.residual_gate_m,
        ) else {
            return Ok(None);
        };
        let inside = self.config.floor_bounds_m.is_none_or(|[lo, hi]| {
            (lo[0]..=hi[0]).contains(&sol.xy_m[0]) && (lo[1]..=hi[1]).contains(&sol.xy_m[1])
        });
        let sigma_m = (sol.cov_xy[0][0] + sol.cov_xy[1][1]).max(0.0).sqrt();
        let sharp = sigma_m.is_finite() && sigma_m <= self.config.max_fix_sigma_m;
        if !inside || !sharp {
            return Ok(None);
        }
        self.last_fix_xy = Some(sol.xy_m);
        let used: Vec<u32> = sol.used.iter().map(|&i| cycle.signals[i].tx_id).collect();
        let mut rejected = cycle.rejected.clone();
        rejected.extend(
            cycle
                .signals
                .iter()
                .filter(|s| !used.contains(&s.tx_id))
                .map(|s| s.tx_id),
        );
        // Seed 000 s3.1.3: heading from the first emitted signal of the cycle (eq. 4-6).
        let heading = sol.used.first().map(|&i| {
            let s = &cycle.signals[i];
            let bearing = (s.tx_m[1] - sol.xy_m[1]).atan2(s.tx_m[0] - sol.xy_m[0]);
            let alpha = self
                .config
                .receiver_angles_rad
                .get(usize::from(s.receiver_id))
                .copied()
                .unwrap_or(0.0);
            angle::wrap_pi(bearing - alpha)
        });
        let quality = if sol.used.len() <= 3 {
            FixQuality::Minimal
        } else if sol
            .residuals_m
            .iter()
            .any(|r| r.abs() > self.config.residual_gate_m)
        {
            FixQuality::Suspect
        } else {
            FixQuality::Good
        };
        let cov = sol.cov_xy;
        let fix = Fix {
            stamp: cycle.stamp,
            arrivals_seq: msg.seq,
            x_m: sol.xy_m[0],
            y_m: sol.xy_m[1],
            z_m: self.config.height_m,
            covariance: [
                cov[0][0], cov[0][1], 0.0, cov[1][0], cov[1][1], 0.0, 0.0, 0.0, 0.0,
            ],
            heading_rad: heading.unwrap_or(0.0),
            heading_valid: heading.is_some(),
            used,
            rejected,
            residuals_m: sol.residuals_m,
            quality,
        };
        self.fix_seq = msg.seq;
        self.estimator.handle(&Input::Fix(FixSample {
            t_s: fix.stamp.as_secs_f64(),
            x_m: fix.x_m,
            y_m: fix.y_m,
            covariance: Matrix2::new(cov[0][0], cov[0][1], cov[1][0], cov[1][1]),
            heading_rad: heading,
        }))?;
        Ok(Some(fix))
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

fn centroid(signals: &[crate::assembly::Signal]) -> [f64; 2] {
    let n = signals.len().max(1) as f64;
    [
        signals.iter().map(|s| s.tx_m[0]).sum::<f64>() / n,
        signals.iter().map(|s| s.tx_m[1]).sum::<f64>() / n,
    ]
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
    fn arrivals_before_any_schedule_are_an_error() {
        let mut c = core();
        c.schedule = None;
        assert_eq!(
            c.on_arrivals(&arrivals([1.0, 1.0, 0.5], &[])),
            Err(MsuError::NoSchedule)
        );
    }
}
