//! `ickon node synthetic-fleet`: a benchmark tool (`ickon bench central`)
//! that stands in, in one process, for the MSU agents of many robots. It
//! publishes what each agent publishes, on the agent's keys and at its
//! rates: its liveliness token, a pose for every odometry input (50 Hz,
//! the robots spread over the 20 ms) and after every fix, a fix after
//! every cycle it heard enough transmitters of, and its status once a
//! second. The robots drive the site's routes ([`model`]), so that the
//! central unit's occupancy firing and survey calibration work on them
//! as on real agents. It has no world and no estimator: what it costs
//! is the messages, which is what the central unit sees of a fleet.

pub mod model;

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use zenoh::Session;
use zenoh::pubsub::Publisher;

use ickon_proto::decode;
use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::control::{CycleTrigger, Schedule, SiteInfo, SurveyCalibration};
use ickon_proto::msg::robot::MsuStatus;
use ickon_proto::site::Site;
use ickon_runtime::{NodeArgs, NodeError, SimulatedClock, fetch, put_counted, zerr};

use model::SyntheticFleet;

/// How often each robot's odometry comes, and with it a pose: the
/// simulated robots' encoders (whole ticks at 50 Hz).
const ODOMETRY_PERIOD: Duration = Duration::from_millis(20);
/// The fleet's timer: every tick publishes the poses of the robots whose
/// turn it is, so that the robots' odometry is spread over each period
/// as independent robots' is, not sent in one burst.
const TICK: Duration = Duration::from_millis(1);
/// How often each agent publishes its status.
const STATUS_PERIOD: Duration = Duration::from_secs(1);
/// How long to wait between asking the central unit again at start-up.
const FETCH_RETRY: Duration = Duration::from_millis(500);

/// Arguments of `ickon node synthetic-fleet`.
#[derive(Debug, Clone, Args)]
pub struct SyntheticFleetArgs {
    /// Connection flags.
    #[command(flatten)]
    pub mesh: NodeArgs,
    /// Robots to stand in for, comma-separated ids of the site.
    #[arg(long, value_delimiter = ',', required = true)]
    pub robots: Vec<String>,
    /// Noise profile whose timing noise and range the fixes follow: ideal,
    /// paper, harsh, or a TOML file.
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Seed of the fixes' noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs the node and returns its exit code.
pub fn main_with(args: SyntheticFleetArgs) -> ExitCode {
    let profile = match ickon_sim::profile::NoiseProfile::load(&args.profile) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let timing_sigma_s = ickon_sim::engine::timing_sigma_s(&profile);
    let max_range_m = profile.ultrasound.max_range_m;
    let clock = args.mesh.clock();
    ickon_runtime::run_node(2, async {
        let session = args.mesh.open().await?;
        let settings = Settings {
            site_name: args.mesh.site_name().to_string(),
            robots: args.robots.clone(),
            timing_sigma_s,
            max_range_m,
            seed: args.seed,
            clock,
        };
        let r = run(&session, settings, args.mesh.shutdown()).await;
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
}

/// One robot's publishers.
struct RobotPublishers {
    pose: Publisher<'static>,
    fix: Publisher<'static>,
    status: Publisher<'static>,
}

/// Publishes for every robot until `shutdown`.
async fn run(
    session: &Session,
    settings: Settings,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NodeError> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&settings.site_name)?;
    let Some(info) = fetch::<SiteInfo>(
        session,
        &keys.central_site(),
        None,
        FETCH_RETRY,
        &mut shutdown,
    )
    .await?
    else {
        return Ok(());
    };
    let site = Site::from_toml(&info.site_toml, "<site from the central unit>")?;
    let mut fleet = SyntheticFleet::new(
        &site,
        &settings.robots,
        settings.timing_sigma_s,
        settings.max_range_m,
        settings.seed,
    )
    .map_err(|e| NodeError::Setup(e.to_string()))?;
    let triggers = session
        .declare_subscriber(keys.central_cycle())
        .await
        .map_err(zerr)?;
    let schedules = session
        .declare_subscriber(keys.central_schedule())
        .await
        .map_err(zerr)?;
    let surveys = session
        .declare_subscriber(keys.central_survey())
        .await
        .map_err(zerr)?;
    let Some(mut schedule) = fetch::<Schedule>(
        session,
        &keys.central_schedule(),
        None,
        FETCH_RETRY,
        &mut shutdown,
    )
    .await?
    else {
        return Ok(());
    };
    let mut publishers = Vec::with_capacity(fleet.len());
    let mut tokens = Vec::with_capacity(fleet.len());
    for i in 0..fleet.len() {
        let id = fleet.id(i).to_string();
        publishers.push(RobotPublishers {
            pose: session
                .declare_publisher(keys.robot(&id, RobotTopic::Pose)?)
                .await
                .map_err(zerr)?,
            fix: session
                .declare_publisher(keys.robot(&id, RobotTopic::Fix)?)
                .await
                .map_err(zerr)?,
            status: session
                .declare_publisher(keys.robot_status(&id)?)
                .await
                .map_err(zerr)?,
        });
        tokens.push(
            session
                .liveliness()
                .declare_token(keys.alive_robot(&id)?)
                .await
                .map_err(zerr)?,
        );
    }
    tracing::info!(
        "synthetic fleet of {} robots on site {:?}",
        fleet.len(),
        site.name
    );
    let started = Instant::now();
    let mut ticks = tokio::time::interval(TICK);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let per_odometry = ticks_in(ODOMETRY_PERIOD);
    let per_status = ticks_in(STATUS_PERIOD);
    let mut survey_version = 0u32;
    // The transmitters of the last cycle: its fixes go out when the next
    // cycle is triggered, as an agent's do once the cycle's arrivals are in.
    let mut last_fired: Option<Vec<u32>> = None;
    let mut failed_puts = 0u64;
    loop {
        tokio::select! {
            _ = &mut shutdown => break,
            _ = ticks.tick() => {
                // By the time gone, so that a late tick serves the robots
                // whose turn it is now.
                let k = started.elapsed().as_millis() as usize;
                let t_s = started.elapsed().as_secs_f64();
                for i in (k % per_odometry..fleet.len()).step_by(per_odometry) {
                    let pose = fleet.pose(i, t_s, settings.clock.now());
                    failed_puts += u64::from(!put_counted(&publishers[i].pose, &pose).await);
                }
                for i in (k % per_status..fleet.len()).step_by(per_status) {
                    let status = MsuStatus { stamp: settings.clock.now(), receivers: String::new() };
                    failed_puts += u64::from(!put_counted(&publishers[i].status, &status).await);
                }
            }
            Ok(s) = triggers.recv_async() => {
                let Ok(trigger) = decode::<CycleTrigger>(&s.payload().to_bytes()) else { continue };
                if let Some(fired) = last_fired.take() {
                    let t_s = started.elapsed().as_secs_f64();
                    for (i, p) in publishers.iter().enumerate() {
                        let stamp = settings.clock.now();
                        if let Some(fix) = fleet.fix(i, t_s, stamp, &fired, survey_version) {
                            failed_puts += u64::from(!put_counted(&p.fix, &fix).await);
                            let pose = fleet.pose(i, t_s, stamp);
                            failed_puts += u64::from(!put_counted(&p.pose, &pose).await);
                        }
                    }
                }
                if trigger.schedule_version == schedule.version {
                    last_fired = Some(trigger.emissions(&schedule).iter().map(|e| e.tx_id).collect());
                }
            }
            Ok(s) = schedules.recv_async() => {
                if let Ok(next) = decode::<Schedule>(&s.payload().to_bytes()) {
                    schedule = next;
                }
            }
            Ok(s) = surveys.recv_async() => {
                if let Ok(survey) = decode::<SurveyCalibration>(&s.payload().to_bytes()) {
                    survey_version = survey.version;
                }
            }
        }
    }
    drop(tokens);
    tracing::info!(
        "synthetic fleet stopping after {:.0} s; {failed_puts} puts failed",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// How many fleet ticks make `period`.
fn ticks_in(period: Duration) -> usize {
    (period.as_millis() / TICK.as_millis()).max(1) as usize
}
