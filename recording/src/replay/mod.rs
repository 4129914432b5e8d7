//! `ickon replay mcap FILE`: a recording of `ickon record` or `ickon sim
//! --record` through the MSU cores again ([`feed`]), every estimator
//! scored against the recorded truth with `ickon eval`'s metrics, the live
//! agent's poses compared with the replayed ones (a deterministic replay
//! reproduces them bit for bit), and the new poses optionally written to an
//! MCAP file ([`out`]) and plotted ([`plot`]).
//!
//! Bad input is reported and the exit code is 2, but whatever can be read is
//! replayed first ([`read`]).

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use ickon_evaluation::tdoa_log::baseline::{Baseline, least_squares};
use ickon_fusion::estimator::{self, EstimatorConfig, WheelGeometry};
use ickon_msu::{MsuConfig, MsuCore};
use ickon_proto::keys::Key;
use ickon_proto::msg::control::SiteInfo;
use ickon_proto::site::Site;
use ickon_sim::{NoiseProfile, Row, Score};

pub(crate) mod feed;
mod out;
mod plot;
pub(crate) mod read;
mod score;

use feed::{Join, Published, RobotStream};
use ickon_runtime::CommandError;
use read::Problem;

use crate::record::sim_hook::{MSU_METADATA_PREFIX, SIM_METADATA};

/// Arguments of `ickon replay mcap`.
#[derive(Debug, Args)]
pub struct McapArgs {
    /// The recording (`ickon record`, `ickon sim --record`).
    pub file: PathBuf,
    /// Estimator to run, or `all`; by default the one the agents ran.
    #[arg(long)]
    pub estimator: Option<String>,
    /// Print one JSON document on stdout instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Write PNG plots (trajectory and error per robot) into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the replayed poses into this MCAP file (refused if it exists).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Site file, for a recording that holds no site (the recorder joined
    /// after the central unit could answer); the built-in site otherwise.
    #[arg(long)]
    pub site: Option<PathBuf>,
}

/// How one robot's agent was set up.
#[derive(Debug, Clone)]
struct AgentSetup {
    timing_sigma_us: f64,
    wheels: WheelGeometry,
    live_config: Option<EstimatorConfig>,
    start: [f64; 3],
}

/// The replay of one estimator on one robot.
#[derive(Debug, serde::Serialize)]
struct EstimatorResult {
    estimator: String,
    poses: usize,
    /// Poses scored against the truth (after the warm-up).
    scored: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    score: Option<Row>,
    /// Share of the scored poses inside their 95 % ellipse, percent.
    #[serde(skip_serializing_if = "Option::is_none")]
    inside_95_pct: Option<f64>,
    /// Their average NEES and its 95 % bounds.
    #[serde(skip_serializing_if = "Option::is_none")]
    nees: Option<ickon_sim::score::Nees>,
    /// Inputs the core refused, by kind, with the first reason (the live
    /// agent refused the same ones).
    #[serde(skip_serializing_if = "Option::is_none")]
    refused_inputs: Option<String>,
    #[serde(skip)]
    published: Vec<Published>,
}

/// The live agent's poses against the replay of its estimator.
#[derive(Debug, Clone, serde::Serialize)]
struct LiveCheck {
    estimator: String,
    live_poses: usize,
    replayed_poses: usize,
    /// Live poses with a replayed pose of the same stamp.
    paired: usize,
    /// Live poses equal bit for bit (as stored) to the replayed pose of the same stamp.
    identical: usize,
    /// Live poses within 1 um and 1 urad of the replayed one.
    within_1um: usize,
    /// Largest difference, metres or radians (position or heading).
    max_difference: f64,
    /// Index of the first live pose that differs, if any.
    first_difference: Option<usize>,
    reproduced: bool,
}

#[derive(Debug, serde::Serialize)]
struct RobotReport {
    id: String,
    inputs: usize,
    truth_samples: usize,
    join: Option<Join>,
    #[serde(skip_serializing_if = "Option::is_none")]
    note: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    live: Option<LiveCheck>,
    estimators: Vec<EstimatorResult>,
    /// The per-epoch least-squares baseline `ls` of `ickon replay tdoa`
    /// on the robot's arrivals (as `ickon convert mcap --to tdoa` writes
    /// them), scored as that replay scores it.
    #[serde(skip_serializing_if = "Option::is_none")]
    ls: Option<Baseline>,
    #[serde(skip)]
    truth: Vec<ickon_proto::msg::robot::Truth>,
}

/// Runs `ickon replay mcap`: replays, scores and prints what it found.
pub fn run(args: &McapArgs) -> Result<(), CommandError> {
    let started = Instant::now();
    let rec = read::read(&args.file).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let mut problems = rec.problems.clone();
    let (streams, more) = feed::streams(&rec);
    problems.extend(more);
    if streams.is_empty() {
        let why = if rec.messages.is_empty() {
            "it holds no ICKON message (a recording of another tool?)"
        } else {
            "it holds no robot's arrivals, odometry or gyro"
        };
        for p in &problems {
            eprintln!("error: {}: {}", args.file.display(), p.0);
        }
        return Err(CommandError::bad_input(format!(
            "{}: nothing to replay: {why}",
            args.file.display()
        )));
    }
    let site = recorded_site(&rec, &args.file, args.site.as_deref(), &mut problems)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let sim = rec.metadata.get(SIM_METADATA);
    let profile = sim
        .and_then(|m| m.get("profile"))
        .and_then(|p| NoiseProfile::load(p).ok());
    let live_name = sim
        .and_then(|m| m.get("estimator"))
        .cloned()
        .unwrap_or_else(|| "tdoa-ekf".to_string());
    let names: Vec<String> = match args.estimator.as_deref() {
        None => vec![live_name.clone()],
        Some("all") => estimator::names().iter().map(|s| s.to_string()).collect(),
        Some(n) => match EstimatorConfig::default_for(n) {
            Ok(_) => vec![n.to_string()],
            Err(e) => {
                return Err(CommandError::bad_input(format!("--estimator: {e}")));
            }
        },
    };
    let mut robots = Vec::new();
    for stream in &streams {
        let setup = agent_setup(&rec, &site, &stream.id, &mut problems);
        robots.push(replay_robot(
            stream,
            &setup,
            &site,
            profile.as_ref(),
            &live_name,
            &names,
            &mut problems,
        ));
    }
    let wall_s = started.elapsed().as_secs_f64();
    // A file that cannot be written fails the command; problems in the
    // recording make it bad input, once everything readable was replayed.
    let mut failure = None;
    if let Some(out) = &args.out {
        let tracks: Vec<(&str, &str, &[Published])> = robots
            .iter()
            .flat_map(|r| {
                r.estimators
                    .iter()
                    .map(|e| (r.id.as_str(), e.estimator.as_str(), e.published.as_slice()))
            })
            .collect();
        if let Err(e) = out::write(out, &rec.site, &tracks) {
            failure = Some(e.to_string());
        }
    }
    if let Some(dir) = &args.plot {
        for r in &robots {
            let tracks: Vec<(&str, &[Published])> = r
                .estimators
                .iter()
                .map(|e| (e.estimator.as_str(), e.published.as_slice()))
                .collect();
            if let Err(e) = plot::write(dir, &r.id, &r.truth, &tracks) {
                failure = Some(format!("cannot write plots to {}: {e}", dir.display()));
            }
        }
    }
    if args.json {
        let doc = serde_json::json!({
            "file": args.file.display().to_string(),
            "complete": rec.complete,
            "site": rec.site,
            "messages": rec.messages.len(),
            "last_log_time_ns": rec.messages.iter().map(|m| m.log_time_ns).max(),
            "problems": problems,
            "robots": robots,
            "wall_s": wall_s,
        });
        println!("{doc}");
    } else {
        print_text(args, &rec, &robots, &problems, profile.as_ref(), wall_s);
    }
    for p in &problems {
        eprintln!("error: {}: {}", args.file.display(), p.0);
    }
    if let Some(why) = failure {
        return Err(CommandError::failure(why));
    }
    match problems.len() {
        0 => Ok(()),
        n => Err(CommandError::bad_input(format!(
            "{}: {n} problem(s), listed above",
            args.file.display()
        ))),
    }
}

/// The site the recording holds (the central unit's answer), else the
/// one `site` names (`--site`) or the built-in one (noted as a problem
/// when the recording had none).
pub(crate) fn recorded_site(
    rec: &read::Recording,
    file: &std::path::Path,
    site: Option<&std::path::Path>,
    problems: &mut Vec<Problem>,
) -> Result<Site, String> {
    let info = rec
        .messages
        .iter()
        .filter(|m| m.key == Key::CentralSite)
        .find_map(|m| ickon_proto::decode::<SiteInfo>(&m.data).ok());
    match info {
        Some(info) => Site::from_toml(&info.site_toml, "<site in the recording>")
            .map_err(|e| format!("{}: the recorded site is invalid: {e}", file.display())),
        None => {
            if site.is_none() {
                problems.push(Problem(
                    "the recording holds no site (central/site): the built-in site is used"
                        .to_string(),
                ));
            }
            Site::load_or_default(site)
                .map(|(s, _, _)| s)
                .map_err(|e| e.to_string())
        }
    }
}

/// The timing sigma robot `robot`'s agent ran with (its recorded
/// configuration, else the MSU's default), seconds.
pub(crate) fn recorded_timing_sigma_s(rec: &read::Recording, robot: &str) -> f64 {
    // The problems of the estimator's configuration are the replay's
    // concern, not the conversion's.
    let mut problems = Vec::new();
    agent_setup(rec, &Site::default_site(), robot, &mut problems).timing_sigma_us * 1e-6
}

fn agent_setup(
    rec: &read::Recording,
    site: &Site,
    robot: &str,
    problems: &mut Vec<Problem>,
) -> AgentSetup {
    let start = site
        .robots
        .iter()
        .find(|r| r.id == robot)
        .map_or([0.0; 3], |r| r.start);
    let meta = rec.metadata.get(&format!("{MSU_METADATA_PREFIX}{robot}"));
    let num = |k: &str, default: f64| {
        meta.and_then(|m| m.get(k))
            .and_then(|v| v.parse::<f64>().ok())
            .filter(|v| v.is_finite() && *v > 0.0)
            .unwrap_or(default)
    };
    let m_per_tick = num("m_per_tick", ickon_msu::config_file::PIONEER_M_PER_TICK);
    let live_config = meta.and_then(|m| m.get("estimator_json")).and_then(|j| {
        serde_json::from_str::<EstimatorConfig>(j)
            .map_err(|e| {
                problems.push(Problem(format!(
                    "robot {robot}: the recorded estimator configuration does not parse ({e}); the defaults are used"
                )))
            })
            .ok()
    });
    AgentSetup {
        timing_sigma_us: num(
            "timing_sigma_us",
            ickon_msu::config_file::DEFAULT_TIMING_SIGMA_S * 1e6,
        ),
        wheels: WheelGeometry {
            wheel_base_m: num("wheel_base_m", ickon_msu::config_file::PIONEER_WHEEL_BASE_M),
            left_m_per_tick: m_per_tick,
            right_m_per_tick: m_per_tick,
        },
        live_config,
        start,
    }
}

/// The configuration of estimator `name` on this robot: what the agent ran
/// when it is the live estimator, else what `ickon sim` would start it with.
fn config_for(
    name: &str,
    live_name: &str,
    setup: &AgentSetup,
    site: &Site,
    profile: Option<&NoiseProfile>,
) -> Option<EstimatorConfig> {
    if name == live_name
        && let Some(c) = &setup.live_config
    {
        return Some(c.clone());
    }
    match profile {
        Some(p) => ickon_sim::engine::estimator_config(
            name,
            setup.start,
            site,
            p,
            ickon_sim::engine::FilterOptions::default(),
        )
        .ok(),
        None => ickon_msu::estimator_for_site(name, site, setup.start).ok(),
    }
}

fn make_core(setup: &AgentSetup, site: &Site, config: &EstimatorConfig) -> Option<MsuCore> {
    let estimator = estimator::build(config).ok()?;
    Some(MsuCore::new(
        // As the agent computes it from its flag.
        MsuConfig::for_site(site, setup.timing_sigma_us * 1e-6, setup.wheels),
        estimator,
    ))
}

fn replay_robot(
    stream: &RobotStream,
    setup: &AgentSetup,
    site: &Site,
    profile: Option<&NoiseProfile>,
    live_name: &str,
    names: &[String],
    problems: &mut Vec<Problem>,
) -> RobotReport {
    let live_config = config_for(live_name, live_name, setup, site, profile);
    let join = live_config.as_ref().and_then(|c| {
        let make = || make_core(setup, site, c);
        feed::join_point(&make, stream)
    });
    // Not bad input: a recorder that joined a running site cannot know the
    // agent's state, so the live run cannot be reproduced; said, not failed.
    let note = (join.is_none() && !stream.live_poses.is_empty()).then(|| {
        format!(
            "no recorded input reproduces the stamps of the agent's first {} poses with {live_name} (a recording begun after the agent, or another estimator set-up): the replay starts at the first input and is not the live run",
            feed::PROBE_POSES
        )
    });
    let start = join.unwrap_or_default();
    let mut live = None;
    let mut estimators = Vec::new();
    for name in names {
        let Some(config) = config_for(name, live_name, setup, site, profile) else {
            problems.push(Problem(format!(
                "robot {}: estimator {name} cannot be set up on this site",
                stream.id
            )));
            continue;
        };
        let Some(core) = make_core(setup, site, &config) else {
            problems.push(Problem(format!(
                "robot {}: estimator {name}'s configuration is invalid",
                stream.id
            )));
            continue;
        };
        let mut published = Vec::new();
        let mut msu = ickon_msu::MsuDriver::new(core);
        feed::run(&mut msu, &stream.inputs, start, |p| {
            published.push(p);
            true
        });
        if name == live_name && !stream.live_poses.is_empty() {
            live = Some(compare(name, &stream.live_poses, &published));
        }
        let scored = score::score(&published, &stream.truth);
        estimators.push(EstimatorResult {
            estimator: name.clone(),
            poses: published.len(),
            scored: scored.as_ref().map_or(0, |s| s.points),
            score: scored.map(|s| s.row),
            inside_95_pct: scored.and_then(|s| s.inside_95_pct),
            nees: scored.and_then(|s| s.nees),
            refused_inputs: msu.refusal_summary(),
            published,
        });
    }
    let (run, _) = feed::recording_of(stream, site);
    let ls = least_squares(site, setup.timing_sigma_us * 1e-6, &run);
    RobotReport {
        id: stream.id.clone(),
        inputs: stream.inputs.len(),
        ls,
        truth_samples: stream.truth.len(),
        join,
        note,
        live,
        estimators,
        truth: stream.truth.clone(),
    }
}

fn compare(name: &str, live: &[(u64, Vec<u8>)], replayed: &[Published]) -> LiveCheck {
    // Paired by stamp (a pose's stamp is its newest input's), so that a
    // sample the recorder missed shifts nothing.
    // A pose after an odometry sample and one after a fix can share a
    // stamp: the n-th of a stamp pairs with the n-th.
    let mut by_stamp: std::collections::HashMap<i64, Vec<&Published>> = Default::default();
    for p in replayed {
        by_stamp.entry(p.pose.stamp.as_nanos()).or_default().push(p);
    }
    let mut seen: std::collections::HashMap<i64, usize> = Default::default();
    let mut check = LiveCheck {
        estimator: name.to_string(),
        live_poses: live.len(),
        replayed_poses: replayed.len(),
        paired: 0,
        identical: 0,
        within_1um: 0,
        max_difference: 0.0,
        first_difference: None,
        reproduced: false,
    };
    for (i, (_, bytes)) in live.iter().enumerate() {
        let Some(lp) = feed::live_pose(bytes) else {
            continue;
        };
        let nth = seen.entry(lp.stamp_ns).or_insert(0);
        let Some(p) = by_stamp.get(&lp.stamp_ns).and_then(|v| v.get(*nth)) else {
            check.first_difference.get_or_insert(i);
            continue;
        };
        *nth += 1;
        check.paired += 1;
        let d = feed::difference(&lp, &p.pose);
        check.max_difference = check.max_difference.max(d);
        if feed::pose_bytes(&p.pose) == *bytes {
            check.identical += 1;
        } else {
            check.first_difference.get_or_insert(i);
        }
        if d <= 1e-6 {
            check.within_1um += 1;
        }
    }
    check.reproduced = check.identical == check.live_poses;
    check
}

/// The robot's note, and its `ls` line when it scored a fix.
fn print_note_and_baseline(r: &RobotReport) {
    if let Some(note) = &r.note {
        println!("{}: note: {note}", r.id);
    }
    let Some(b) = r.ls.as_ref().filter(|b| b.scored > 0) else {
        return;
    };
    let mm = |v: Option<f64>| v.map_or("-".into(), |v| format!("{:.2}", v * 1e3));
    println!(
        "{} ls (per-epoch least squares, as `ickon replay tdoa` on the converted log): {} of {} epochs fixed, {} scored, rmse {} mm, mean {} mm, median {} mm",
        r.id,
        b.fixes,
        b.epochs,
        b.scored,
        mm(b.rmse_m),
        mm(b.mean_m),
        mm(b.median_m)
    );
}

fn print_text(
    args: &McapArgs,
    rec: &read::Recording,
    robots: &[RobotReport],
    problems: &[Problem],
    profile: Option<&NoiseProfile>,
    wall_s: f64,
) {
    println!(
        "{}: {} messages of site {:?}{}, {} robots{}",
        args.file.display(),
        rec.messages.len(),
        rec.site,
        if rec.complete {
            ""
        } else {
            " (file incomplete)"
        },
        robots.len(),
        if problems.is_empty() {
            String::new()
        } else {
            format!(", {} problem(s), see below", problems.len())
        }
    );
    for r in robots {
        let join = r.join.map_or("start of the file".to_string(), |j| {
            format!("after {} inputs the agent did not hear", j.skipped_inputs)
        });
        print!("{}: {} inputs, replayed from {join}", r.id, r.inputs);
        match &r.live {
            Some(l) => println!(
                "; live {} poses: {} recorded, {} replayed with the same stamp, {} identical bit for bit, {} within 1 um/1 urad, largest difference {:.2e}{}",
                l.estimator,
                l.live_poses,
                l.paired,
                l.identical,
                l.within_1um,
                l.max_difference,
                l.first_difference.map_or(String::new(), |i| format!(
                    " (first difference at pose {i})"
                ))
            ),
            None => println!(),
        }
        print_note_and_baseline(r);
        for e in &r.estimators {
            if let Some(refused) = &e.refused_inputs {
                println!("{} {}: {refused}", r.id, e.estimator);
            }
        }
    }
    let scores: Vec<Score> = robots
        .iter()
        .flat_map(|r| {
            r.estimators.iter().filter_map(|e| {
                let row = e.score?;
                Some(Score {
                    estimator: e.estimator.clone(),
                    route: r.id.clone(),
                    tours: vec![Row {
                        tour: Some(1),
                        ..row
                    }],
                    mean: row,
                    fix_mean_mm: None,
                    fix_rmse_mm: None,
                    fix_heading_std_deg: None,
                    fix_heading_max_deg: None,
                    fix_rate_hz: None,
                    fix_latency_ms: None,
                    crlb_ratio: None,
                    crlb_mm: None,
                    inside_95_pct: e.inside_95_pct,
                    nees: e.nees,
                })
            })
        })
        .collect();
    if scores.is_empty() {
        println!("no truth in the recording: nothing to score");
        return;
    }
    println!(
        "every published pose after the first {} s scored against the truth at its time (`tour` 1 is the whole recording; routes are robots)",
        score::WARM_UP_S
    );
    let refs: Vec<&Score> = scores.iter().collect();
    let seed = rec
        .metadata
        .get(SIM_METADATA)
        .and_then(|m| m.get("seed"))
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    ickon_evaluation::print_estimator_table(
        &refs,
        profile.map_or("unknown", |p| p.name.as_str()),
        seed,
        std::time::Duration::from_secs_f64(wall_s),
    );
}
