//! `ickon eval --robots N`: the first N robots of the site at once, in
//! virtual time, each robot's achieved fix rate and error, and what
//! collisions cost.

use ickon_central::core::{CentralConfig, SchedulePolicy};
use ickon_central::occupancy::FiringConfig;
use ickon_central::selection::NeedsConfig;
use ickon_central::spacing::Reverb;
use ickon_proto::site::Site;
use ickon_sim::NoiseProfile;
use ickon_sim::fleet::{FleetConfig, FleetOutput, run_fleet};

use super::EvalArgs;
use ickon_runtime::CommandError;

/// Virtual seconds of a `--robots` run without `--duration`.
const DEFAULT_DURATION_S: f64 = 60.0;

/// Runs the fleet evaluation of `args` on `site`.
pub fn run(
    site: &Site,
    profile: NoiseProfile,
    robots: usize,
    args: &EvalArgs,
) -> Result<(), CommandError> {
    let (config, firing) = fleet_config(site, profile, robots, args)?;
    let out = match run_fleet(site, &config) {
        Ok(o) => o,
        Err(e @ ickon_sim::RunError::FleetSize { .. }) => {
            return Err(CommandError::bad_input(format!("{e}")));
        }
        Err(e) => {
            return Err(CommandError::failure(format!("{e}")));
        }
    };
    for r in &out.robots {
        if let Some(refused) = &r.refused_inputs {
            eprintln!("warning: robot {}: the MSU core {refused}", r.id);
        }
    }
    if args.json {
        print_json(site, &config, firing, args, &out);
    } else {
        print_report(site, &config, firing, args, &out);
    }
    Ok(())
}

/// The fleet run `args` ask for, and the name of its firing plan; refuses
/// an unknown schedule or firing plan, a fire range outside (0, 100] m and
/// a run no longer than the warm-up.
fn fleet_config<'a>(
    site: &Site,
    profile: NoiseProfile,
    robots: usize,
    args: &'a EvalArgs,
) -> Result<(FleetConfig, &'a str), CommandError> {
    let schedule = match args.schedule.as_str() {
        "tight" => SchedulePolicy::Tight,
        "uniform" => SchedulePolicy::Uniform,
        other => {
            return Err(CommandError::bad_input(format!(
                "unknown schedule `{other}` (known: tight, uniform)"
            )));
        }
    };
    let firing = args.firing.as_deref().unwrap_or("occupancy");
    let fire_range_m = args
        .fire_range_m
        .unwrap_or(FiringConfig::default().fire_range_m);
    let duration = args.duration.unwrap_or(DEFAULT_DURATION_S);
    let (occupancy, needs) = match firing {
        "needs" => (true, true),
        "occupancy" => (true, false),
        "all" => (false, false),
        other => {
            return Err(CommandError::bad_input(format!(
                "unknown firing `{other}` (known: needs, occupancy, all)"
            )));
        }
    };
    // The central unit spaces the bursts by the room the world simulates,
    // as a site's operator configures the reverberation time measured there.
    let room = &profile.ultrasound.collisions;
    let reverb = needs.then(|| Reverb {
        absorption_db_per_m: room.absorption_db_per_m,
        tail_db: room.reverb_tail_db,
        decay_db_per_ms: room.reverb_decay_db_per_ms,
        detection_snr_db: room.detection_snr_db,
        ..Reverb::default()
    });
    let estimator = if args.estimator == "all" {
        "tdoa-ekf".to_string()
    } else {
        args.estimator.clone()
    };
    if !(fire_range_m > 0.0 && fire_range_m <= 100.0) {
        return Err(CommandError::bad_input(
            "--fire-range-m must be in (0, 100] m",
        ));
    }
    if !(duration > 3.0 && duration.is_finite()) {
        return Err(CommandError::bad_input(
            "--duration must be more than the 3 s warm-up",
        ));
    }
    let survey = super::survey_calibration(args, site, &profile);
    let config = FleetConfig {
        robots,
        duration_s: duration,
        warm_up_s: 3.0,
        profile,
        seed: args.seed,
        estimator,
        central: CentralConfig {
            schedule,
            firing: FiringConfig {
                occupancy,
                fire_range_m,
                needs: needs.then(NeedsConfig::default),
                reverb,
                ..FiringConfig::default()
            },
            survey,
            ..CentralConfig::default()
        },
        filter: super::filter_options(args),
        transmitter_faults: super::transmitter_faults(args, site)?,
    };
    Ok((config, firing))
}

/// The run as one JSON document on stdout.
fn print_json(site: &Site, config: &FleetConfig, firing: &str, args: &EvalArgs, out: &FleetOutput) {
    let (robots, duration) = (config.robots, config.duration_s);
    let doc = serde_json::json!({
        "site": site.name,
        "robots": robots,
        "duration_s": duration,
        "schedule": args.schedule,
        "firing": firing,
        "estimator": config.estimator,
        "seed": args.seed,
        "profile": config.profile.name,
        "fleet": out,
        "collision_loss_share": out.collisions.lost_share(),
        "median_robot_mean_err_mm": median(out.robots.iter().map(|r| r.mean_err_mm)),
        "mean_hdop": out.plan.mean_hdop(),
        "speed_of_sound": ickon_sim::score::AirScore::of(&out.air, site.speed_of_sound_m_s),
    });
    println!("{doc}");
}

/// The run as a table on stdout: each robot's fix rate, error and losses
/// to collisions, and their means.
fn print_report(
    site: &Site,
    config: &FleetConfig,
    firing: &str,
    args: &EvalArgs,
    out: &FleetOutput,
) {
    let (robots, duration) = (config.robots, config.duration_s);
    println!(
        "{} robots on {} for {:.0} s (3 s warm-up), schedule {}, firing {}, {} ({}), seed {}",
        robots,
        site.name,
        duration,
        args.schedule,
        firing,
        config.estimator,
        config.profile.name,
        args.seed
    );
    println!(
        "cycles: {:.2}/s, {:.1} of {} transmitters fired per cycle on average in {:.1} slots of {:.1} ms",
        out.cycles_per_s, out.mean_firing, out.transmitters, out.slots_per_cycle, out.mean_slot_ms
    );
    if let Some(mean) = out.plan.mean_hdop() {
        println!(
            "firing plan: HDOP of each robot's transmitters {:.2} on average, {:.2} at worst ({} of {} robot-cycles without a fix geometry)",
            mean, out.plan.hdop_worst, out.plan.no_geometry, out.plan.robots_served
        );
    }
    match out.survey_fixes_taken {
        Some(n) => println!("survey calibration: learnt from {n} of the fleet's fixes"),
        None => println!("survey calibration: off"),
    }
    println!(
        "{:>6} {:>9} {:>8} {:>8} {:>10} {:>10} {:>9}",
        "robot", "route", "fixes/s", "signals", "mean mm", "p95 mm", "lost %"
    );
    for r in &out.robots {
        println!(
            "{:>6} {:>9} {:>8.2} {:>8.1} {:>10.1} {:>10.1} {:>9.2}",
            r.id,
            r.route,
            r.fixes_per_s,
            r.signals_per_fix,
            r.mean_err_mm,
            r.p95_err_mm,
            100.0 * r.collisions.lost_share()
        );
    }
    let n = out.robots.len().max(1) as f64;
    let c = &out.collisions;
    println!(
        "mean over robots: {:.2} fixes/s (lowest {:.2}), {:.1} signals per fix, {:.1} mm (median robot {:.1} mm); collisions: {} of {} direct detections lost ({:.2} %: {} collided, {} of them misdecoded, {} masked); {} of {} detections of blocked transmitters (reflections only) lost",
        out.robots.iter().map(|r| r.fixes_per_s).sum::<f64>() / n,
        out.robots
            .iter()
            .map(|r| r.fixes_per_s)
            .fold(f64::INFINITY, f64::min),
        out.robots.iter().map(|r| r.signals_per_fix).sum::<f64>() / n,
        out.robots.iter().map(|r| r.mean_err_mm).sum::<f64>() / n,
        median(out.robots.iter().map(|r| r.mean_err_mm)),
        c.lost(),
        c.detected,
        100.0 * c.lost_share(),
        c.collided,
        c.misdecoded,
        c.masked,
        c.blocked_lost,
        c.blocked_detected
    );
    if let Some(a) = ickon_sim::score::AirScore::of(&out.air, site.speed_of_sound_m_s) {
        println!(
            "speed of sound published: {:.3} % off the robots' paths on average ({:.3} % in the first minute), {} (the site file's {:.3} % off); the air {:.1}-{:.1} m/s",
            a.used_mean_pct,
            a.first_minute_mean_pct,
            super::table::worst_after_first_minute(a.used_max_pct),
            a.site_mean_pct,
            a.true_range_m_s[0],
            a.true_range_m_s[1]
        );
    }
    for r in &out.robots {
        let windows: Vec<String> = r
            .window_err_mm
            .iter()
            .map(|w| w.map_or("-".to_string(), |v| format!("{v:.1}")))
            .collect();
        println!(
            "{:>6} mean error per {:.0} s after the warm-up, mm: {}",
            r.id,
            ickon_sim::fleet::ERROR_WINDOW_S,
            windows.join(" ")
        );
    }
    if out.transmitter_events.is_empty() {
        println!("transmitters: none left out of the fixes");
    }
    for e in &out.transmitter_events {
        let what = if e.condition == "healthy" {
            "taken back"
        } else {
            "left out"
        };
        println!(
            "transmitter {} {what} at {:.1} s ({}: {})",
            e.tx_id, e.t_s, e.condition, e.evidence
        );
    }
}

/// The median of `values` (NaN for none; the mean of the middle two for an even count).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}
