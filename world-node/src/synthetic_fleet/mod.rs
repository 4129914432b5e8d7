//! `ickon node synthetic-fleet`: a benchmark tool (`ickon bench central`)
//! that stands in, in one process, for the MSU agents of many robots. It
//! publishes what the central unit hears of each agent, on the agent's
//! keys and at its rates: its liveliness token, its summary every
//! [`SUMMARY_PERIOD`](ickon_proto::msg::robot::SUMMARY_PERIOD) (the
//! robots spread over the period) with the fix of the last cycle it heard
//! enough transmitters of, and its status once a
//! second. The agents' poses and fixes, which no central unit subscribes
//! to, are not made. The robots drive the site's routes ([`model`]), so
//! that the central unit's occupancy firing and survey calibration work
//! on them as on real agents. It has no world and no estimator: what it
//! costs is the messages, which is what the central unit sees of a fleet.
//!
//! A fix is solved only for a summary about to go (the last cycle's, at
//! the robot's place then), not for every robot every cycle: that keeps
//! 10,000 robots on one core. The generator counts the summaries it sent
//! late (a tick that came after the robot's turn had passed by more than
//! a period) and says so when it stops (in its log, and in the file
//! `--report` names), so that a benchmark can tell the generator falling
//! behind from the central unit. The robots' summaries and statuses are
//! puts on the session with no publisher declared, and only their tokens
//! are declarations ([`declare_all`]).

mod fleet_loop;
pub mod model;

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use zenoh::key_expr::KeyExpr;
use zenoh::liveliness::LivelinessToken;
use zenoh::{Session, Wait};

use ickon_proto::decode;
use ickon_proto::keys::Keys;
use ickon_proto::msg::control::{CycleTrigger, Schedule, SurveyCalibration};
use ickon_runtime::{JoinedSite, NodeError, SimulatedClock, SiteJoin, zerr};

use crate::fleet_args::SimulatedRobotsArgs;
use fleet_loop::FleetLoop;
use model::SyntheticFleet;

/// The fleet's timer: every tick publishes the summaries of the robots
/// whose turn it is, so that they are spread over each period as
/// independent robots' are, not sent in one burst.
const TICK: Duration = Duration::from_millis(1);
/// How often each agent publishes its status.
const STATUS_PERIOD: Duration = Duration::from_secs(1);

/// Arguments of `ickon node synthetic-fleet`.
#[derive(Debug, Clone, Args)]
pub struct SyntheticFleetArgs {
    /// The mesh, the robots to stand in for, the noise profile their fixes
    /// follow and the seed of that noise.
    #[command(flatten)]
    pub fleet: SimulatedRobotsArgs,
    /// Where to write, when it stops, whether it kept up: a JSON document
    /// of the summaries it sent and how many of them went late.
    #[arg(long)]
    pub report: Option<std::path::PathBuf>,
}

/// Whether the generator kept up over its run (`--report`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FleetKeptUp {
    /// Summaries published.
    pub summaries: u64,
    /// Robots' turns served more than a summary period late (or skipped):
    /// the generator, not the central unit, fell behind.
    pub late_turns: u64,
    /// Puts that failed.
    pub failed_puts: u64,
    /// Seconds from the first tick to the stop.
    pub elapsed_s: f64,
    /// Seconds the robots' tokens and publishers took to declare.
    pub declare_s: f64,
}

/// Runs the node and returns its exit code.
pub fn main_with(args: SyntheticFleetArgs) -> ExitCode {
    let profile = match ickon_sim::profile::NoiseProfile::load(&args.fleet.profile) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let timing_sigma_s = ickon_sim::engine::timing_sigma_s(&profile);
    let max_range_m = profile.ultrasound.max_range_m;
    let clock = args.fleet.mesh.clock();
    ickon_runtime::run_node(2, async {
        let session = args.fleet.mesh.open().await?;
        let settings = Settings {
            site_name: args.fleet.mesh.site_name().to_string(),
            robots: args.fleet.robots.clone(),
            timing_sigma_s,
            max_range_m,
            seed: args.fleet.seed,
            clock,
            report: args.report.clone(),
        };
        let r = run(&session, settings, args.fleet.mesh.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

/// What the fleet is made of.
struct Settings {
    site_name: String,
    robots: Vec<String>,
    timing_sigma_s: f64,
    max_range_m: f64,
    seed: u64,
    clock: SimulatedClock,
    report: Option<std::path::PathBuf>,
}

/// One robot's keys (checked once) and the count of its summaries.
struct RobotKeys {
    summary: KeyExpr<'static>,
    status: KeyExpr<'static>,
    seq: u64,
    /// The fleet's cycle count at its last summary: the fixes it solved
    /// since are the cycles since.
    cycles_at_last: u64,
}

/// Publishes for every robot until `shutdown`.
async fn run(
    session: &Session,
    settings: Settings,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NodeError> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&settings.site_name)?;
    let join = SiteJoin::new(session, &keys);
    let Some(JoinedSite { site, .. }) = join.site(&mut shutdown).await? else {
        return Ok(());
    };
    let fleet = SyntheticFleet::new(
        &site,
        &settings.robots,
        settings.timing_sigma_s,
        settings.max_range_m,
        settings.seed,
    )
    .map_err(|e| NodeError::Setup(e.to_string()))?;
    let triggers = join.subscribe(keys.central_cycle()).await?;
    let schedules = join.subscribe(keys.central_schedule()).await?;
    let surveys = join.subscribe(keys.central_survey()).await?;
    let Some(schedule) = join.schedule(&mut shutdown).await? else {
        return Ok(());
    };
    let declared = Instant::now();
    let ids: Vec<String> = (0..fleet.len()).map(|i| fleet.id(i).to_string()).collect();
    let (robot_keys, tokens) = declare_all(session, &keys, &ids)?;
    let declare_s = declared.elapsed().as_secs_f64();
    tracing::info!("{} robots' tokens declared in {declare_s:.1} s", ids.len());
    tracing::info!(
        "synthetic fleet of {} robots on site {:?}",
        fleet.len(),
        site.name
    );
    let mut fleet = FleetLoop::new(
        session.clone(),
        fleet,
        robot_keys,
        schedule,
        settings.clock,
        declare_s,
    );
    let mut ticks = tokio::time::interval(TICK);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            _ = &mut shutdown => break,
            _ = ticks.tick() => fleet.tick().await,
            Ok(s) = triggers.recv_async() => {
                if let Ok(trigger) = decode::<CycleTrigger>(&s.payload().to_bytes()) {
                    fleet.trigger(&trigger);
                }
            }
            Ok(s) = schedules.recv_async() => {
                if let Ok(next) = decode::<Schedule>(&s.payload().to_bytes()) {
                    fleet.schedule = next;
                }
            }
            Ok(s) = surveys.recv_async() => {
                if let Ok(survey) = decode::<SurveyCalibration>(&s.payload().to_bytes()) {
                    fleet.survey_version = survey.version;
                }
            }
        }
    }
    drop(tokens);
    fleet.kept_up.elapsed_s = fleet.started.elapsed().as_secs_f64();
    report(&fleet.kept_up, settings.report.as_deref());
    Ok(())
}

/// Says whether the generator kept up: in its log, and in the file
/// `--report` names.
fn report(kept_up: &FleetKeptUp, file: Option<&std::path::Path>) {
    let FleetKeptUp {
        summaries,
        late_turns,
        failed_puts,
        elapsed_s,
        ..
    } = *kept_up;
    tracing::info!(
        "synthetic fleet stopping after {elapsed_s:.0} s: {summaries} summaries ({:.0}/s), \
         {late_turns} sent more than a period late; {failed_puts} puts failed",
        summaries as f64 / elapsed_s.max(1e-9)
    );
    if let Some(path) = file {
        let text = serde_json::to_string(kept_up).unwrap_or_default();
        if let Err(e) = std::fs::write(path, text) {
            tracing::warn!("cannot write the fleet's report {}: {e}", path.display());
        }
    }
}

/// Every robot's summary and status keys, checked once, and its
/// liveliness token, in `ids`' order. The summaries and statuses go out as
/// puts on the session, with no publisher declared: in Zenoh 1.10 each
/// declared publisher looks through every publisher of the session for
/// one on its key and asks the router for its key's subscribers, so two
/// publishers a robot made the fleet's start-up grow with the square of
/// the fleet. Nothing subscribes to a publisher's matching status here,
/// so nothing is lost. A token is one declaration the session sends
/// without waiting for an answer, and the central unit needs it.
fn declare_all(
    session: &Session,
    keys: &Keys,
    ids: &[String],
) -> Result<(Vec<RobotKeys>, Vec<LivelinessToken>), NodeError> {
    let mut robots = Vec::with_capacity(ids.len());
    let mut tokens = Vec::with_capacity(ids.len());
    for id in ids {
        let key = |k: String| KeyExpr::try_from(k).map_err(zerr);
        robots.push(RobotKeys {
            summary: key(keys.robot_summary(id)?)?,
            status: key(keys.robot_status(id)?)?,
            seq: 0,
            cycles_at_last: 0,
        });
        let token = session
            .liveliness()
            .declare_token(keys.alive_robot(id)?)
            .wait()
            .map_err(zerr)?;
        tokens.push(token);
    }
    Ok((robots, tokens))
}

/// How many fleet ticks make `period`.
fn ticks_in(period: Duration) -> usize {
    (period.as_millis() / TICK.as_millis()).max(1) as usize
}
