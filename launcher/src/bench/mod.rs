//! `ickon bench scale`: the whole mesh (`ickon sim`) at several fleet sizes
//! on one site, in real time, with what a site's operator asks of each size:
//! do the cells fire every cycle, in sync; does every robot get its arrivals
//! and a fix every cycle; how late are the poses; what does it cost in CPU
//! and memory per kind of process. `ickon bench central`: the site's
//! servers against a synthetic fleet, what one central unit can serve.

pub mod central;
mod table;

use std::path::PathBuf;

use clap::{Args, Subcommand};
use serde::Serialize;

use crate::args::Mesh;
use crate::args::{SimArgs, check_args};
use crate::report::SimReport;
use crate::run::measure;
use ickon_runtime::CommandError;

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Run the simulation at each fleet size and tabulate how the site holds up.
    Scale(ScaleArgs),
    /// Run the router, the central unit and the cells against a synthetic
    /// fleet (one process publishing what N robots' agents publish) at each
    /// size, the central unit alone on CPU 0, and tabulate its CPU, memory,
    /// trigger jitter and how fast it answers.
    Central(central::CentralArgs),
}

/// Arguments of `ickon bench scale`.
#[derive(Debug, Args)]
pub struct ScaleArgs {
    /// A built-in site (`lab`, `warehouse`, `hall`) or a site file.
    #[arg(long, default_value = "warehouse")]
    pub site: PathBuf,
    /// Fleet sizes, comma-separated: the first N robots of the site each
    /// (above its robots, more added on its routes, as `ickon sim --robots`).
    #[arg(long, value_delimiter = ',', default_value = "16,32,64,128")]
    pub robots: Vec<usize>,
    /// Seconds each size runs once every node is live.
    #[arg(long, default_value_t = 30.0)]
    pub duration: f64,
    /// Estimator every MSU agent runs.
    #[arg(long, default_value = "tdoa-ekf")]
    pub estimator: String,
    /// Noise profile of the simulated world: ideal, paper, building, harsh, or a TOML file.
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Through a router (as on a site) or a full mesh of peers (to compare).
    #[arg(long, value_enum, default_value = "router")]
    pub mesh: Mesh,
    /// Routers, one per zone of the site (`ickon sim --routers`).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true)]
    pub routers: usize,
    /// Print one JSON document (every size's full `ickon sim` report) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Every size with access control on the router (`ickon sim --secure`,
    /// a fresh set of credentials per size).
    #[arg(long)]
    pub secure: bool,
    /// Which transmitters fire each cycle (`ickon sim --firing`).
    #[arg(long, value_enum, default_value_t = ickon_central::node::Firing::Occupancy)]
    pub firing: ickon_central::node::Firing,
    /// Every agent's `tdoa-ekf` learns each cell's sync error as a state
    /// (`ickon sim --learn-cell-sync`).
    #[arg(long)]
    pub learn_cell_sync: bool,
    /// The central unit does not learn the transmitters' survey errors
    /// (`ickon sim --no-survey-calibration`).
    #[arg(long)]
    pub no_survey_calibration: bool,
    /// Robots whose agents share one process (`ickon sim --robots-per-process`).
    #[arg(long, value_name = "K", allow_hyphen_values = true, value_parser = crate::args::parse_robots_per_process)]
    pub robots_per_process: Option<usize>,
    /// The site's servers and the simulation on separate CPUs (`ickon sim --split-cores`).
    #[arg(long)]
    pub split_cores: bool,
}

/// One size of the benchmark in the JSON document.
#[derive(Debug, Serialize)]
struct SizeResult {
    robots: usize,
    /// Why the run failed (a node died), if it did; its numbers are still given.
    failure: Option<String>,
    report: SimReport,
}

/// Runs `ickon bench scale` and returns the exit code.
pub fn run(command: BenchCommand) -> Result<(), CommandError> {
    let args = match command {
        BenchCommand::Scale(args) => args,
        BenchCommand::Central(args) => return central::run(args),
    };
    if args.robots.is_empty() {
        return Err(CommandError::bad_input("--robots needs at least one size"));
    }
    let runs: Vec<SimArgs> = args
        .robots
        .iter()
        .map(|&n| SimArgs {
            site: Some(args.site.clone()),
            robots: n,
            duration: args.duration,
            estimator: args.estimator.clone(),
            profile: args.profile.clone(),
            seed: args.seed,
            // Quiet: no live status line between the tables.
            json: true,
            mesh: args.mesh,
            routers: args.routers,
            http: None,
            http_token_file: None,
            foxglove: None,
            record: None,
            record_foxglove_view: false,
            ros2: false,
            secure: args.secure.then_some(None),
            firing: args.firing,
            restart: false,
            standby: false,
            faults: None,
            learn_cell_sync: args.learn_cell_sync,
            local_wind: false,
            no_survey_calibration: args.no_survey_calibration,
            no_speed_of_sound: false,
            devices: Default::default(),
            receivers: Default::default(),
            robots_per_process: args.robots_per_process,
            split_cores: args.split_cores,
        })
        .collect();
    // Every size is checked before the first one runs (a size the site
    // cannot take should not surface after an hour).
    let mut checked = Vec::new();
    for sim_args in &runs {
        checked.push(check_args(sim_args)?);
    }
    if let Some(first) = runs.first() {
        crate::run::pin_launcher(first)?;
    }
    let mut results = Vec::new();
    for (sim_args, (site, profile)) in runs.iter().zip(&checked) {
        if !args.json {
            eprintln!(
                "ickon bench scale: {} robots on {} for {} s",
                sim_args.robots, site.name, sim_args.duration
            );
        }
        match ickon_runtime::block_on(2, measure(sim_args, site, profile)) {
            Some(Ok((report, failure))) => {
                if let Some(why) = &failure {
                    eprintln!("warning: {} robots: {why}", sim_args.robots);
                }
                results.push(SizeResult {
                    robots: sim_args.robots,
                    failure,
                    report,
                });
            }
            None => {
                return Err(CommandError::failure(format!(
                    "{} robots: the mesh did not start",
                    sim_args.robots
                )));
            }
            Some(Err(e)) => return Err(e.context(&format!("{} robots", sim_args.robots))),
        }
    }
    if args.json {
        match serde_json::to_string_pretty(&results) {
            Ok(text) => println!("{text}"),
            Err(e) => {
                return Err(CommandError::failure(format!("{e}")));
            }
        }
    } else {
        let reports: Vec<&SimReport> = results.iter().map(|r| &r.report).collect();
        print!("{}", table::render(&reports));
    }
    if results.iter().any(|r| r.failure.is_some()) {
        Err(CommandError::failure("a run failed (see its warning)"))
    } else {
        Ok(())
    }
}
