//! `ickon eval`: estimators on the simulated world in virtual time, scored
//! as in the papers (docs/architecture.md, "Evaluation").
//!
//! Each route runs once per seed on its own thread; every estimator is
//! hosted by its own MSU core on the same world, so all estimators see the
//! same measurements. Tables go to stdout (or one JSON document with
//! `--json`), the progress bar to stderr.

mod fleet;
mod plot;
pub(crate) mod table;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Args;
use ickon_fusion::estimator;
use ickon_proto::site::Site;
use ickon_sim::{NoiseProfile, RunConfig, RunOutput, Score};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use ickon_runtime::CommandError;

/// Arguments of `ickon eval`.
#[derive(Debug, Clone, Args)]
pub struct EvalArgs {
    /// A built-in site (`lab`, `warehouse`, `hall`) or a site file (TOML); `lab` when omitted.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Estimator name, or `all`.
    #[arg(long, default_value = "all")]
    pub estimator: String,
    /// Route name, or `all` (not with `--robots`: each robot drives its own).
    #[arg(long, default_value = "all", conflicts_with = "robots")]
    pub route: String,
    /// Tours per route (not with `--robots`, which runs for `--duration`).
    #[arg(long, default_value_t = 10, conflicts_with = "robots")]
    pub tours: u32,
    /// Noise profile: ideal, paper, building, harsh, or a TOML file (deploy/profiles/paper.toml is a template).
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Run seed: the same seed gives the same numbers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON document on stdout instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots into this directory (per route and tour; not with `--robots`).
    #[arg(long, conflicts_with = "robots")]
    pub plot: Option<PathBuf>,
    /// Run the first N robots of the site at once for `--duration` seconds
    /// instead of one robot per route, and report each robot's fix rate.
    #[arg(long)]
    pub robots: Option<usize>,
    /// Virtual seconds of a `--robots` run [default: 60].
    #[arg(long, requires = "robots")]
    pub duration: Option<f64>,
    /// The central unit's schedule: `tight` (from the geometry) or `uniform` (one slot per emission, cells coloured apart; kept to compare).
    #[arg(long, default_value = "tight")]
    pub schedule: String,
    /// Which transmitters fire in a `--robots` run: `needs` (what each
    /// robot needs: a few in good geometry, spaced by the room's
    /// reverberation), `occupancy` (everything audible where the robots
    /// are) or `all` [default: occupancy].
    #[arg(long, requires = "robots")]
    pub firing: Option<String>,
    /// With `--firing occupancy` or `needs`: a transmitter fires when it is this close
    /// to a robot's uncertainty region, metres.
    /// [default: the central unit's, 8.5]
    #[arg(long, requires = "robots")]
    pub fire_range_m: Option<f64>,
    /// `tdoa-ekf` learns each cell's sync error as a state, as
    /// `[filter.params] learn_cell_sync = true` in an MSU configuration does
    /// (with `--estimator all`: `tdoa-ekf` only).
    #[arg(long)]
    pub learn_cell_sync: bool,
    /// `tdoa-ekf` carries the wind where the robot is as a state, as
    /// `[filter.params] sensors.local_wind_sigma_m_s = 0.5` in an MSU
    /// configuration does: for a hall with drafts (with `--estimator all`:
    /// `tdoa-ekf` only).
    #[arg(long)]
    pub local_wind: bool,
    /// The central unit does not learn the transmitters' survey errors
    /// from the fleet's fixes (on by default; see
    /// `ickon_central::survey_calibration`).
    #[arg(long)]
    pub no_survey_calibration: bool,
    /// The central unit does not publish the speed of sound it learns from
    /// the fleet's fixes: the MSUs use the site file's throughout.
    #[arg(long)]
    pub no_speed_of_sound: bool,
    /// Transmitters that fail during the run, comma-separated:
    /// `dead:tx/ID@T`, `weak:tx/ID@T=FRACTION` (each burst heard with that
    /// probability), `moved:tx/ID@T=DX,DY,DZ` (metres); T in s or ms.
    #[arg(long)]
    pub faults: Option<String>,
    /// Write each route's run into DIR/ROUTE/ in the arrival-time log
    /// format (docs/log-format.md): the arrivals the MSU heard, the truth
    /// and the wheel odometry, for `ickon replay tdoa` (not with `--robots`).
    #[arg(long, value_name = "DIR", conflicts_with = "robots")]
    pub export_tdoa: Option<PathBuf>,
}

/// The transmitter faults `--faults` names on `site` (none without it);
/// a bad plan is bad input.
pub(super) fn transmitter_faults(
    args: &EvalArgs,
    site: &Site,
) -> Result<Vec<ickon_sim::tx_faults::TransmitterFault>, CommandError> {
    let Some(plan) = &args.faults else {
        return Ok(Vec::new());
    };
    for item in ickon_sim::tx_faults::split_plan(plan) {
        if !ickon_sim::tx_faults::TransmitterFault::is_one(&item) {
            return Err(CommandError::bad_input(format!(
                "--faults: {item:?}: `ickon eval` takes transmitter faults only (dead, weak, moved)"
            )));
        }
    }
    let faults = ickon_sim::tx_faults::TransmitterFault::parse_plan(plan, site)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    if faults.is_empty() {
        return Err(CommandError::bad_input("--faults: no fault in the plan"));
    }
    Ok(faults)
}

/// The central unit's survey calibration for `args` on `site` under
/// `profile` (`None` with `--no-survey-calibration`).
pub(super) fn survey_calibration(
    args: &EvalArgs,
    site: &Site,
    profile: &ickon_sim::NoiseProfile,
) -> Option<ickon_central::survey_calibration::CalibrationConfig> {
    (!args.no_survey_calibration).then(|| {
        let mut c = ickon_sim::engine::survey_calibration(site, profile);
        c.learn_speed_of_sound = !args.no_speed_of_sound;
        c
    })
}

/// The filter options of `args` (with `--estimator all` they reach
/// `tdoa-ekf` only).
pub(super) fn filter_options(args: &EvalArgs) -> ickon_sim::engine::FilterOptions {
    ickon_sim::engine::FilterOptions {
        learn_cell_sync: args.learn_cell_sync,
        local_wind: args.local_wind,
    }
}

/// Runs `ickon eval` and returns the exit code.
pub fn run(args: EvalArgs) -> Result<(), CommandError> {
    let (site, _, site_name) = Site::load_or_default(args.site.as_deref())
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let profile =
        NoiseProfile::load(&args.profile).map_err(|e| CommandError::bad_input(e.to_string()))?;
    if !["tight", "uniform"].contains(&args.schedule.as_str()) {
        return Err(CommandError::bad_input(format!(
            "unknown schedule `{}` (known: tight, uniform)",
            args.schedule
        )));
    }
    if args.estimator != "all" {
        filter_options(&args)
            .check_for(&args.estimator)
            .map_err(|e| CommandError::bad_input(e.to_string()))?;
    }
    if let Some(robots) = args.robots {
        return fleet::run(&site, profile, robots, &args);
    }
    let estimators: Vec<String> = match args.estimator.as_str() {
        "all" => estimator::names().iter().map(|s| s.to_string()).collect(),
        name if estimator::names().contains(&name) => vec![name.to_owned()],
        name => {
            return Err(CommandError::bad_input(format!(
                "unknown estimator `{name}` (known: all, {})",
                estimator::names().join(", ")
            )));
        }
    };
    let routes: Vec<String> = match args.route.as_str() {
        "all" => site.routes.iter().map(|r| r.name.clone()).collect(),
        name if site.route(name).is_some() => vec![name.to_owned()],
        name => {
            let known: Vec<&str> = site.routes.iter().map(|r| r.name.as_str()).collect();
            return Err(CommandError::bad_input(format!(
                "unknown route `{name}` (known: all, {})",
                known.join(", ")
            )));
        }
    };
    if args.tours == 0 {
        return Err(CommandError::bad_input("--tours must be at least 1"));
    }
    let started = Instant::now();
    let faults = transmitter_faults(&args, &site)?;
    let outputs = simulate(&site, &routes, &estimators, &profile, &args, &faults)
        .map_err(|e| CommandError::failure(e.to_string()))?;
    let scores: Vec<Vec<Score>> = outputs
        .iter()
        .map(|o| ickon_sim::score(o, site.speed_of_sound_m_s, site.msu.height_m))
        .collect();
    let flat: Vec<&Score> = reorder(&scores, &estimators);
    for o in &outputs {
        if let Some(refused) = &o.refused_inputs {
            eprintln!("warning: route {}: the MSU core {refused}", o.config.route);
        }
    }
    if args.json {
        let doc = serde_json::json!({
            "site": site.name,
            "site_file": site_name,
            "profile": profile.name,
            "seed": args.seed,
            "tours": args.tours,
            "results": flat,
            "cells": outputs.iter().map(|o| serde_json::json!({
                "route": o.config.route,
                "cells": o.cells,
            })).collect::<Vec<_>>(),
            "air": outputs.iter().map(|o| serde_json::json!({
                "route": o.config.route,
                "speed_of_sound": ickon_sim::score::AirScore::of(&o.air, site.speed_of_sound_m_s),
            })).collect::<Vec<_>>(),
            "channel": outputs.iter().map(|o| serde_json::json!({
                "route": o.config.route,
                "cycles_per_s": ickon_central::update_rate_hz(&o.schedule),
                "fixes_per_s": if o.virtual_s > 0.0 { o.fixes.len() as f64 / o.virtual_s } else { 0.0 },
                "collisions": o.collisions,
                "collision_loss_share": o.collisions.lost_share(),
            })).collect::<Vec<_>>(),
        });
        println!("{doc}");
    } else {
        table::print(&flat, &profile.name, args.seed, started.elapsed());
        table::print_cells(&outputs);
        table::print_air(&outputs, site.speed_of_sound_m_s);
    }
    if let Some(dir) = &args.export_tdoa {
        crate::tdoa_log::export::write_all(dir, &site, &outputs)?;
    }
    if let Some(dir) = &args.plot
        && let Err(e) = plot::write_all(dir, &outputs, &scores, &flat)
    {
        return Err(CommandError::failure(format!(
            "cannot write plots to {}: {e}",
            dir.display()
        )));
    }
    Ok(())
}

/// Scores ordered by estimator, then route.
fn reorder<'a>(scores: &'a [Vec<Score>], estimators: &[String]) -> Vec<&'a Score> {
    let mut out = Vec::new();
    for name in estimators {
        for per_route in scores {
            out.extend(per_route.iter().filter(|s| &s.estimator == name));
        }
    }
    out
}

/// A bar that starts hidden: it is shown once the run has lasted a second.
fn progress_bar(steps: u64) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{elapsed:>4} [{bar:40}] {percent:>3}% {msg}") {
        pb.set_style(style.progress_chars("=> "));
    }
    pb
}

fn simulate(
    site: &Site,
    routes: &[String],
    estimators: &[String],
    profile: &NoiseProfile,
    args: &EvalArgs,
    faults: &[ickon_sim::tx_faults::TransmitterFault],
) -> Result<Vec<RunOutput>, ickon_sim::RunError> {
    const STEPS: u64 = 1000;
    let pb = progress_bar(STEPS * routes.len() as u64);
    // With --json and stderr not a terminal, nobody watches: stay hidden.
    let may_show = !args.json || std::io::stderr().is_terminal();
    let started = Instant::now();
    let policy = if args.schedule == "uniform" {
        ickon_central::core::SchedulePolicy::Uniform
    } else {
        ickon_central::core::SchedulePolicy::Tight
    };
    let results: Vec<_> = std::thread::scope(|scope| {
        let handles: Vec<_> = routes
            .iter()
            .map(|route| {
                let pb = pb.clone();
                let config = RunConfig {
                    route: route.clone(),
                    tours: args.tours,
                    profile: profile.clone(),
                    seed: args.seed,
                    estimators: estimators.to_vec(),
                    central: ickon_central::core::CentralConfig {
                        schedule: policy,
                        survey: survey_calibration(args, site, profile),
                        ..Default::default()
                    },
                    filter: filter_options(args),
                    transmitter_faults: faults.to_vec(),
                    record_rows: if args.export_tdoa.is_some() {
                        crate::tdoa_log::export::MAX_ROWS
                    } else {
                        0
                    },
                };
                scope.spawn(move || {
                    let mut done = 0u64;
                    ickon_sim::run(site, &config, &mut |f| {
                        let now = (f * STEPS as f64) as u64;
                        pb.inc(now.saturating_sub(done));
                        done = done.max(now);
                        // Only runs longer than a second get a bar.
                        if may_show && pb.is_hidden() && started.elapsed() > Duration::from_secs(1)
                        {
                            pb.set_draw_target(ProgressDrawTarget::stderr());
                        }
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    });
    pb.finish_and_clear();
    results.into_iter().collect()
}
