//! `ickon record --synthetic-robots N`: the recorder's throughput on the
//! message mix of an N-robot site, without Zenoh: every message a robot of
//! `ickon sim` produces (gyro 100 Hz, odometry 50 Hz, truth 50 Hz, a pose
//! per odometry sample and per fix, ranges 10 Hz, arrivals and a fix per
//! cycle), the cells' bursts, triggers and status, encoded by `proto` and
//! written through the same [`Recorder`] as a live recording, as fast as
//! it goes. The values follow a robot on a circle (so that compression sees
//! realistic, slowly changing numbers) with seeded noise.

use std::time::Instant;

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::control::{Burst, CellStatus, CycleTrigger};
use ickon_proto::msg::robot::{
    Arrival, Fix, FixQuality, Imu, ObstacleRanges, Odometry, RobotPose, Truth, UltrasoundArrivals,
};
use ickon_proto::{Time, encode};
use rand::{Rng, SeedableRng};

use super::{RecordArgs, RecordReport, Recorder, base_metadata, cpu_seconds, create_output};
use ickon_runtime::CommandError;

/// The world's step (its publishing tick), ns.
const STEP_NS: i64 = 10_000_000;
/// Cycles per second of the lab site's schedule (the `ickon sim` README figure).
const CYCLE_HZ: f64 = 2.63;
/// Transmitters heard per cycle.
const ARRIVALS_PER_CYCLE: u32 = 8;
/// Cells of the synthetic site (four per 16 robots, as the lab's four cells for its robots).
const ROBOTS_PER_CELL: usize = 4;

/// Runs the measurement and prints the report.
pub fn run(args: &RecordArgs, keys: &Keys, robots: usize) -> Result<(), CommandError> {
    if robots == 0 || robots > 10_000 {
        return Err(CommandError::bad_input(
            "--synthetic-robots must be between 1 and 10000",
        ));
    }
    let out = create_output(&args.out).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let duration_s = args.duration.unwrap_or(60.0);
    let mut recorder = Recorder::new(out, keys.clone(), &base_metadata(keys_site(keys)))
        .map_err(|e| CommandError::failure(e.to_string()))?;
    let started = Instant::now();
    let cpu0 = cpu_seconds();
    if let Err(e) = feed(&mut recorder, keys, robots, duration_s) {
        return Err(CommandError::failure(
            super::write_failure(&args.out, &e).to_string(),
        ));
    }
    let stats = match recorder.finish() {
        Ok((s, _)) => s,
        Err(e) => {
            return Err(CommandError::failure(
                super::write_failure(&args.out, &e).to_string(),
            ));
        }
    };
    let report = RecordReport::new(
        &args.out,
        stats,
        cpu_seconds() - cpu0,
        started.elapsed().as_secs_f64(),
    );
    let capacity = report.stats.messages as f64 / report.wall_s.max(1e-9);
    if args.json {
        let mut doc = serde_json::to_value(&report).unwrap_or_default();
        doc["robots"] = robots.into();
        doc["capacity_messages_per_s"] = capacity.into();
        doc["cpu_share_at_site_rate"] = (report.cpu_s / report.duration_s.max(1e-9)).into();
        println!("{doc}");
    } else {
        eprint!("{}", report.render());
        eprintln!(
            "{robots} robots: the site makes {:.0} messages/s; the recorder wrote {capacity:.0} messages/s ({:.1}x the site's rate), {:.1} % of one core per second of site time",
            report.messages_per_s,
            capacity / report.messages_per_s.max(1e-9),
            100.0 * report.cpu_s / report.duration_s.max(1e-9),
        );
    }
    Ok(())
}

fn keys_site(keys: &Keys) -> &str {
    keys.prefix().strip_prefix("ickon/").unwrap_or("lab")
}

fn put<T: serde::Serialize, W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    key: &str,
    msg: &T,
    now: Time,
) -> Result<(), super::RecordError> {
    // Encoding our own messages cannot fail (bounded sizes, no maps).
    if let Ok(bytes) = encode(msg) {
        recorder.record(key, &bytes, now)?;
    }
    Ok(())
}

/// Every message of `robots` robots over `duration_s` seconds of site time.
fn feed<W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    keys: &Keys,
    robots: usize,
    duration_s: f64,
) -> Result<(), super::RecordError> {
    let mut rng = Rng8::seed_from_u64(1);
    let t0 = 1_764_000_000_000_000_000i64;
    let ids: Vec<String> = (1..=robots).map(|i| format!("r{i}")).collect();
    let topic = |id: &str, t: RobotTopic| keys.robot(id, t).unwrap_or_default();
    let robot_keys: Vec<[String; 7]> = ids
        .iter()
        .map(|id| {
            [
                topic(id, RobotTopic::Imu),
                topic(id, RobotTopic::Odom),
                topic(id, RobotTopic::Pose),
                topic(id, RobotTopic::Range),
                topic(id, RobotTopic::Ultrasound),
                topic(id, RobotTopic::Fix),
                keys.sim_truth(id).unwrap_or_default(),
            ]
        })
        .collect();
    let cells: Vec<String> = (1..=robots.div_ceil(ROBOTS_PER_CELL))
        .map(|c| format!("c{c}"))
        .collect();
    let steps = (duration_s * 1e9 / STEP_NS as f64) as i64;
    let cycle_ns = (1e9 / CYCLE_HZ) as i64;
    let mut next_cycle = 0i64;
    let mut cycle = 0u64;
    let mut seq = 0u64;
    for step in 0..steps {
        let now_ns = t0 + step * STEP_NS;
        let now = Time::from_nanos(now_ns);
        let t_s = step as f64 * STEP_NS as f64 * 1e-9;
        let is_cycle = now_ns >= t0 + next_cycle;
        if is_cycle {
            next_cycle += cycle_ns;
            cycle += 1;
            seq += 1;
        }
        let tick = Tick {
            step,
            now_ns,
            now,
            t_s,
            is_cycle,
            cycle,
            seq,
        };
        if is_cycle {
            put_cycle(recorder, keys, &cells, &tick, &mut rng)?;
        }
        if step % 100 == 0 {
            put_cell_status(recorder, keys, &cells, &tick, &mut rng)?;
        }
        for (i, k) in robot_keys.iter().enumerate() {
            put_robot(recorder, k, i, &tick, &mut rng)?;
        }
    }
    Ok(())
}

/// The random numbers of the fed messages.
type Rng8 = rand_chacha::ChaCha8Rng;

/// One step of the fed site time.
struct Tick {
    /// Its index.
    step: i64,
    /// Site time, nanoseconds and as a time.
    now_ns: i64,
    now: Time,
    /// Seconds since the first step.
    t_s: f64,
    /// Whether a cycle is triggered at this step.
    is_cycle: bool,
    /// The last cycle triggered, and the arrivals' sequence number.
    cycle: u64,
    seq: u64,
}

/// A noise draw uniform in `(-s, s)`.
fn noise(rng: &mut Rng8, s: f64) -> f64 {
    rng.random_range(-s..s)
}

/// The central unit's trigger of a new cycle and every cell's bursts in it.
fn put_cycle<W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    keys: &Keys,
    cells: &[String],
    tick: &Tick,
    rng: &mut Rng8,
) -> Result<(), super::RecordError> {
    let (now, now_ns, cycle) = (tick.now, tick.now_ns, tick.cycle);
    let trigger = CycleTrigger {
        cycle,
        start: now,
        schedule_version: 1,
        epoch: 1,
        firing: Vec::new(),
        cycle_period: ickon_proto::time::Duration::ZERO,
    };
    put(recorder, &keys.central_cycle(), &trigger, now)?;
    for (c, cell) in cells.iter().enumerate() {
        for tx in 0..4u32 {
            let burst = Burst {
                cell_id: cell.clone(),
                tx_id: c as u32 * 4 + tx,
                cycle,
                scheduled: Time::from_nanos(now_ns + i64::from(tx) * 40_000_000),
                actual: Time::from_nanos(
                    now_ns + i64::from(tx) * 40_000_000 + rng.random_range(-30_000..30_000),
                ),
                epoch: 1,
            };
            put(
                recorder,
                &keys.cell_burst(cell).unwrap_or_default(),
                &burst,
                now,
            )?;
        }
    }
    Ok(())
}

/// Every cell's status report.
fn put_cell_status<W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    keys: &Keys,
    cells: &[String],
    tick: &Tick,
    rng: &mut Rng8,
) -> Result<(), super::RecordError> {
    let (now, cycle) = (tick.now, tick.cycle);
    for cell in cells {
        let status = CellStatus {
            cell_id: cell.clone(),
            stamp: now,
            offset_ns: rng.random_range(-50_000_000..50_000_000),
            drift_ppb: rng.random_range(-20_000..20_000),
            offset_sigma_ns: 5_000,
            sync_samples: 8,
            last_cycle_fired: cycle,
            cycles_fired: cycle,
            slots_skipped: 0,
            faults: Vec::new(),
            inputs_refused: 0,
            device: String::new(),
        };
        put(
            recorder,
            &keys.cell_status(cell).unwrap_or_default(),
            &status,
            now,
        )?;
    }
    Ok(())
}

/// The messages of robot `i` (its keys `k`) at one step: it drives a
/// circle, each robot a little further round it.
fn put_robot<W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    k: &[String; 7],
    i: usize,
    tick: &Tick,
    rng: &mut Rng8,
) -> Result<(), super::RecordError> {
    let (step, now, t_s) = (tick.step, tick.now, tick.t_s);
    let phase = i as f64 * 0.7;
    let a = 0.1 * t_s + phase;
    let (x, y, theta) = (
        3.0 + 2.0 * a.cos(),
        3.0 + 2.0 * a.sin(),
        a + std::f64::consts::FRAC_PI_2,
    );
    put(
        recorder,
        &k[0],
        &Imu {
            stamp: now,
            gyro_z_rad_s: 0.1 + noise(rng, 0.002),
        },
        now,
    )?;
    if step % 2 == 0 {
        put_drive(recorder, k, tick, [x, y, theta], rng)?;
    }
    if step % 10 == 0 {
        let ranges = ObstacleRanges {
            stamp: now,
            left_m: 1.0 + noise(rng, 0.5),
            left_valid: true,
            right_m: 2.0 + noise(rng, 0.5),
            right_valid: true,
            left_ir_m: 0.0,
            left_ir_valid: false,
            right_ir_m: 0.0,
            right_ir_valid: false,
        };
        put(recorder, &k[3], &ranges, now)?;
    }
    if tick.is_cycle {
        put_robot_cycle(recorder, k, tick, [x, y, theta], rng)?;
    }
    Ok(())
}

/// A robot's odometry, pose and true pose at `[x, y, theta]`.
fn put_drive<W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    k: &[String; 7],
    tick: &Tick,
    [x, y, theta]: [f64; 3],
    rng: &mut Rng8,
) -> Result<(), super::RecordError> {
    let (now, now_ns, t_s) = (tick.now, tick.now_ns, tick.t_s);
    let ticks = (t_s * 0.2 / 3.2e-5) as i64;
    put(
        recorder,
        &k[1],
        &Odometry {
            stamp: now,
            x_m: x + noise(rng, 0.01),
            y_m: y + noise(rng, 0.01),
            theta_rad: theta,
            left_ticks: ticks,
            right_ticks: ticks + (t_s * 100.0) as i64,
        },
        now,
    )?;
    let pose = RobotPose {
        stamp: now,
        x_m: x + noise(rng, 0.02),
        y_m: y + noise(rng, 0.02),
        theta_rad: theta.sin().atan2(theta.cos()),
        covariance: [4e-4, 1e-6, 0.0, 1e-6, 4e-4, 0.0, 0.0, 0.0, 1e-3],
        estimator: "tdoa-ekf".into(),
        fix_seq: tick.seq,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    };
    put(recorder, &k[2], &pose, now)?;
    let truth = Truth {
        stamp: now,
        robot_clock: Time::from_nanos(now_ns + 12_345_678),
        x_m: x,
        y_m: y,
        theta_rad: theta.sin().atan2(theta.cos()),
        v_m_s: 0.2,
        omega_rad_s: 0.1,
    };
    put(recorder, &k[6], &truth, now)
}

/// A robot's arrivals, fix and pose of a new cycle, at `[x, y, theta]`.
fn put_robot_cycle<W: std::io::Write + std::io::Seek>(
    recorder: &mut Recorder<W>,
    k: &[String; 7],
    tick: &Tick,
    [x, y, theta]: [f64; 3],
    rng: &mut Rng8,
) -> Result<(), super::RecordError> {
    let (now, now_ns, seq) = (tick.now, tick.now_ns, tick.seq);
    let arrivals = UltrasoundArrivals {
        seq,
        arrivals: (0..ARRIVALS_PER_CYCLE)
            .map(|tx| Arrival {
                tx_id: tx,
                receiver_id: (tx % 6) as u8,
                t_arrival: Time::from_nanos(
                    now_ns + i64::from(tx) * 40_000_000 + rng.random_range(0..15_000_000),
                ),
            })
            .collect(),
    };
    put(recorder, &k[4], &arrivals, now)?;
    let fix = Fix {
        stamp: now,
        arrivals_seq: seq,
        x_m: x + noise(rng, 0.05),
        y_m: y + noise(rng, 0.05),
        z_m: 0.5,
        covariance: [1e-3, 1e-5, 0.0, 1e-5, 1e-3, 0.0, 0.0, 0.0, 1e-6],
        heading_rad: theta,
        heading_valid: true,
        used: (0..ARRIVALS_PER_CYCLE).collect(),
        rejected: Vec::new(),
        residuals_m: (0..ARRIVALS_PER_CYCLE).map(|_| noise(rng, 0.01)).collect(),
        quality: FixQuality::Good,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    };
    put(recorder, &k[5], &fix, now)?;
    let pose = RobotPose {
        stamp: now,
        x_m: x,
        y_m: y,
        theta_rad: theta.sin().atan2(theta.cos()),
        covariance: [4e-4, 1e-6, 0.0, 1e-6, 4e-4, 0.0, 0.0, 0.0, 1e-3],
        estimator: "tdoa-ekf".into(),
        fix_seq: seq,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    };
    put(recorder, &k[2], &pose, now)
}
