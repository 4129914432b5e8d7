//! The central unit as a Zenoh node: serves the site, the schedule and the
//! master clock, publishes cycle triggers, watches liveliness, bursts, cell
//! status and the robots' summaries, and answers the admin queryables. All
//! decisions are the [`CentralCore`]'s; this loop only moves bytes. Its
//! parts, by job: the command line (`args`), the survey calibration's
//! file (`survey_file`), the endpoints on the mesh (`endpoints`), what a
//! sample means to the core (`samples`), the queries the loop answers
//! itself (`admin`, `reload`), the viewers it feeds (`viewers`) and the
//! loop itself (`event_loop`).

use std::future::Future;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use ickon_proto::keys::Keys;
use ickon_proto::msg::control::Schedule;
use ickon_proto::site::Site;
use ickon_runtime::{LogLimiter, NodeError, SimulatedClock, zerr};
use zenoh::Session;
use zenoh::liveliness::LivelinessToken;

use crate::core::{CentralConfig, CentralCore};
use endpoints::Endpoints;
use survey_file::{SURVEY_SAVE_PERIOD, restore_survey};
use viewers::VIEWER_STATUS_PERIOD;

mod admin;
mod args;
mod endpoints;
mod event_loop;
mod latest_inbox;
mod reload;
mod samples;
mod survey_file;
mod viewers;

pub use args::{CentralArgs, Firing, check_site_name};
pub use survey_file::{SurveyFile, load_survey_file};
pub use viewers::Viewers;

/// Runs the central unit as a process: loads the site, opens the session,
/// serves until Ctrl-C/SIGTERM. Exit code 2 for a bad site file.
pub fn main_with(args: CentralArgs) -> ExitCode {
    let (site, text, name) = match Site::load_or_default(args.node.site.as_deref()) {
        Ok(loaded) => loaded,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = check_site_name(args.node.site_name.as_deref(), &site.name, &name) {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let config = args.core_config(&site);
    let saved = match (&args.survey_file, config.survey) {
        (Some(path), Some(survey)) => match load_survey_file(path, &site, survey) {
            Ok(saved) => saved,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        },
        _ => None,
    };
    ickon_runtime::run_node(2, async {
        let session = args.node.open().await?;
        tracing::info!(
            "central unit for site {:?} from {name}, listening on {:?}",
            site.name,
            args.node.zenoh.listen
        );
        let keys = Keys::new(&site.name)?;
        let web = crate::http::WebMap::start(&session, &keys, &site, &args.http)
            .await
            .map_err(|e| NodeError::Setup(e.to_string()))?;
        let foxglove = crate::foxglove::FoxgloveLive::start(&site, &args.foxglove)
            .await
            .map_err(|e| NodeError::Setup(e.to_string()))?;
        let viewers = Viewers { web, foxglove };
        let clock = args.node.clock();
        args.node.listen_for_clock_steps(clock)?;
        let serving = Serving {
            site,
            site_toml: text,
            clock,
            viewers: &viewers,
            standby: args.standby,
            config,
            survey_file: SurveyFile {
                path: args.survey_file.clone(),
                saved,
            },
        };
        let r = run(&session, serving, args.node.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

/// The longest a central unit waits at start to learn whether another is
/// active (the routers answer a liveliness query at once; this bounds a
/// router that does not).
const ACTIVE_QUERY_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(1_000);

/// What a central unit serves, and how: everything [`run`] takes but the
/// session and the shutdown.
pub struct Serving<'a> {
    /// The site.
    pub site: Site,
    /// The site file's text, as the nodes fetch it.
    pub site_toml: String,
    /// The master time base: the system clock, with an injected offset
    /// and drift in a simulation.
    pub clock: SimulatedClock,
    /// The web map and the Foxglove server, handed the status twice a
    /// second and what the loop receives as it comes.
    pub viewers: &'a Viewers,
    /// Start as a hot standby (`--standby`).
    pub standby: bool,
    /// The core's configuration.
    pub config: CentralConfig,
    /// Where the survey calibration is kept, and what was read from it.
    pub survey_file: SurveyFile,
}

/// Serves the site until `shutdown` completes. As a standby, or when
/// another central unit is active at its start, it follows the active
/// central unit until it takes over: until then it answers no clock or
/// schedule query and holds no `alive/central` token, so that no cell
/// follows it by mistake.
pub async fn run(
    session: &Session,
    serving: Serving<'_>,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NodeError> {
    let Serving {
        site,
        site_toml,
        clock,
        viewers,
        standby,
        config,
        survey_file,
    } = serving;
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&site.name)?;
    let active_seen = active_elsewhere(session, &keys, standby).await?;
    let mut core =
        CentralCore::starting(site, site_toml, config, clock.now(), standby, active_seen)
            .map_err(|e| NodeError::Setup(e.to_string()))?;
    restore_survey(&mut core, &survey_file);
    let mut survey_saves = tokio::time::interval(SURVEY_SAVE_PERIOD);
    survey_saves.tick().await;
    log_schedule(core.latest_schedule());
    // 0: a standby, which does not answer clock requests.
    let epoch = Arc::new(AtomicU64::new(if core.is_active() {
        core.epoch()
    } else {
        0
    }));
    let ends = Endpoints::declare(session, &keys, clock, epoch.clone(), viewers.any()).await?;
    // Declared last: whoever sees the token can query every queryable
    // above. A standby declares it when it takes over.
    let token = if core.is_active() {
        Some(
            session
                .liveliness()
                .declare_token(keys.alive_central())
                .await
                .map_err(zerr)?,
        )
    } else {
        tracing::info!("standing by: following the active central unit");
        None
    };

    let mut node = event_loop::NodeLoop {
        session,
        keys,
        clock,
        viewers,
        core,
        ends,
        survey_file,
        epoch,
        token,
        reloads: reload::Reloads::new(),
        unknown_admin: LogLimiter::default(),
        links: crate::router_links::RouterLinks::default(),
        survey_saves,
        web_ticks: tokio::time::interval(VIEWER_STATUS_PERIOD),
        failed_puts: 0,
        undecodable: 0,
    };
    loop {
        let input = tokio::select! {
            _ = &mut shutdown => break,
            input = node.next_input() => input,
        };
        node.take(input).await;
    }
    node.survey_file.save(&node.core);
    let (failed_puts, undecodable) = (node.failed_puts, node.undecodable);
    if failed_puts + undecodable > 0 {
        tracing::info!(
            "central unit stopped; {failed_puts} triggers or schedules not sent, {undecodable} reports undecodable or refused"
        );
    }
    let (superseded, refused) = node.ends.summaries.dropped();
    if superseded + refused > 0 {
        tracing::info!(
            "{superseded} robot summaries superseded by a newer one of the same robot before they \
             were taken, {refused} refused with too many robots waiting"
        );
    }
    Ok(())
}

/// After the core took an event: the clock answers name its epoch (0 when
/// it stands by), and the `alive/central` token is held exactly while it
/// is active.
async fn follow_role(
    session: &Session,
    keys: &Keys,
    core: &CentralCore,
    epoch: &AtomicU64,
    token: &mut Option<LivelinessToken>,
) {
    epoch.store(
        if core.is_active() { core.epoch() } else { 0 },
        Ordering::Relaxed,
    );
    if core.is_active() != token.is_some() {
        *token = if core.is_active() {
            session
                .liveliness()
                .declare_token(keys.alive_central())
                .await
                .ok()
        } else {
            None
        };
    }
}

/// Whether another central unit is active already (this one was restarted
/// after the standby took over): then this one stands by instead of taking
/// the site back. Not asked when starting as a standby anyway.
async fn active_elsewhere(
    session: &Session,
    keys: &Keys,
    standby: bool,
) -> Result<bool, NodeError> {
    let active_seen = !standby
        && ickon_runtime::token_present(session, &keys.alive_central(), ACTIVE_QUERY_TIMEOUT)
            .await?;
    if active_seen {
        tracing::info!("another central unit is active: starting as its standby");
    }
    Ok(active_seen)
}

/// Logs the schedule the central unit starts with.
fn log_schedule(s: &Schedule) {
    tracing::info!(
        "schedule v{}: {} emissions, slot {}, cycle {} ({:.2} Hz)",
        s.version,
        s.emissions.len(),
        s.slot_length,
        s.cycle_period,
        crate::schedule::update_rate_hz(s)
    );
}

#[cfg(test)]
mod survey_file_tests;

#[cfg(test)]
mod site_name_tests;
