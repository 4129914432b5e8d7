//! `ickon admin`: asks the central unit of a running site, through its
//! `central/admin/<command>` queryables, and prints the answer as a table or,
//! with `--json`, as one JSON document on stdout.
//!
//! Where to connect: the same Zenoh flags as every node (`-c`, `-e`, `-l`,
//! `--no-multicast-scouting`); with neither `-c` nor `-e`, the run file of an
//! `ickon sim` of the site on this machine ([`ickon_runtime::RunDir`]).
//! Every step (opening the session, seeing the central unit's liveliness
//! token, the answer) shares one `--timeout-ms` budget.
//!
//! Exit codes: 0 done; 1 no central unit answered in time (or nothing to
//! connect to); 2 bad input: bad flags, an unreadable site file, or a site
//! file the central unit refused (its reasons are printed).

mod coverage_view;
mod format;
mod links_view;
mod png;

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Subcommand};
use ickon_proto::keys::Keys;
use ickon_proto::msg::admin::{
    AdminAck, CoverageReport, CoverageRequest, LinksReport, ReloadRequest, RobotPage,
    RobotsRequest, StatusReport, TransmittersReport,
};
use ickon_proto::msg::control::Schedule;
use ickon_runtime::{RunDir, ZenohArgs, query_once, wait_for_token};
use serde::de::DeserializeOwned;
use tokio::time::Instant;

use ickon_runtime::CommandError;

/// Flags every admin command takes.
#[derive(Debug, Clone, Args)]
pub struct Common {
    /// Zenoh connection flags; with neither `-c` nor `-e`, the run file of an
    /// `ickon sim` of the site on this machine says where to connect.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Site name, the `<site>` of every key.
    #[arg(long, default_value = "lab")]
    pub site_name: String,
    /// How long to wait for the central unit to answer, milliseconds.
    #[arg(long, default_value_t = 3_000)]
    pub timeout_ms: u64,
    /// Print one JSON document on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// The admin commands.
#[derive(Debug, Subcommand)]
pub enum AdminCommand {
    /// Site, cycle, schedule, and every cell and robot in one view.
    Status(Common),
    /// Cells: state, what they fired, sync.
    Cells(Common),
    /// Robots a page at a time: state, fixes per second, last pose,
    /// estimator; by id, or nearest first to a place, of one state or all,
    /// with the fleet's counts by state.
    Robots {
        /// Connection and output flags.
        #[command(flatten)]
        common: Common,
        /// The page, from 0; one beyond the last is refused with the last.
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        page: i64,
        /// Robots a page (1 to 1000).
        #[arg(long, default_value_t = ickon_proto::msg::admin::DEFAULT_PAGE_SIZE)]
        page_size: u32,
        /// Only the robots in this state: up, stale or down.
        #[arg(long)]
        state: Option<String>,
        /// Nearest first to this place, metres in the site frame.
        #[arg(long, value_name = "X,Y", value_parser = place)]
        near: Option<(f64, f64)>,
    },
    /// The schedule in force: cycle period, update rate, every emission.
    Schedule(Common),
    /// Clock synchronisation of every cell: estimate, uncertainty, and the
    /// residual error of its bursts against the true time base.
    Sync(Common),
    /// Every transmitter's health as the fleet's fixes show it (how often
    /// it is heard when a robot is near, its residuals, when it was last
    /// heard; dead, weak and moved ones flagged and left out of the
    /// fixes), and the speed of sound the robots solve with.
    Transmitters(Common),
    /// Transmitters in line of sight and HDOP over a grid of the floor.
    Coverage {
        /// Connection and output flags.
        #[command(flatten)]
        common: Common,
        /// Grid spacing, metres (0.05 to 5).
        #[arg(long, default_value_t = ickon_central::coverage::DEFAULT_RESOLUTION_M)]
        resolution_m: f64,
        /// Also write a PNG heat map of the HDOP to this file.
        #[arg(long)]
        png: Option<PathBuf>,
    },
    /// Stop triggering cycles (cycle numbers keep counting).
    Pause(Common),
    /// Trigger cycles again.
    Resume(Common),
    /// Replace the site with a new file; the central unit validates it first
    /// and refuses a bad one with the reasons, keeping the running site.
    Reload {
        /// The new site file (TOML).
        file: PathBuf,
        /// Connection and output flags.
        #[command(flatten)]
        common: Common,
    },
}

/// `--near X,Y`: two numbers in metres.
fn place(text: &str) -> Result<(f64, f64), String> {
    let parsed = text
        .split_once(',')
        .and_then(|(x, y)| Some((x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?)))
        .filter(|(x, y)| x.is_finite() && y.is_finite());
    parsed.ok_or_else(|| format!("{text:?} is not X,Y in metres (two numbers and a comma)"))
}

/// The user name of the admin identity that `ickon site secure` writes.
const ADMIN_USER: &str = "admin";

/// A query to send: the command chunk of the key and its payload.
struct Request {
    command: &'static str,
    payload: Option<Vec<u8>>,
    /// Whether asking twice is harmless (a read): then a query that got no
    /// answer is asked again while time is left.
    idempotent: bool,
}

/// Runs one admin command and prints its answer.
pub fn run(command: AdminCommand) -> Result<(), CommandError> {
    let (common, request) = prepare(&command).map_err(CommandError::bad_input)?;
    let answer = match ickon_runtime::block_on(1, answer(&command, common, request)) {
        Some(Ok(a)) => a,
        Some(Err(message)) => return Err(CommandError::failure(message)),
        None => return Err(CommandError::failure("cannot start the runtime")),
    };
    show(&command, common, answer)
}

impl Request {
    fn new(command: &'static str, payload: Option<Vec<u8>>, idempotent: bool) -> Self {
        Self {
            command,
            payload,
            idempotent,
        }
    }
}

/// Checks the flags and builds the query, before anything touches the network.
fn prepare(command: &AdminCommand) -> Result<(&Common, Request), String> {
    let (common, request) = match command {
        AdminCommand::Status(c) => (c, Request::new("status", None, true)),
        AdminCommand::Cells(c) => (c, Request::new("cells", None, true)),
        AdminCommand::Robots {
            common,
            page,
            page_size,
            state,
            near,
        } => {
            let request = RobotsRequest {
                page: *page,
                page_size: *page_size,
                state: state.clone().unwrap_or_default(),
                near: near.is_some(),
                near_x_m: near.map_or(0.0, |n| n.0),
                near_y_m: near.map_or(0.0, |n| n.1),
            };
            if let Some(problem) = request.problem() {
                return Err(problem);
            }
            let payload = ickon_proto::encode(&request).map_err(|e| e.to_string())?;
            (common, Request::new("robots", Some(payload), true))
        }
        AdminCommand::Schedule(c) => (c, Request::new("schedule", None, true)),
        AdminCommand::Sync(c) => (c, Request::new("sync", None, true)),
        AdminCommand::Transmitters(c) => (c, Request::new("transmitters", None, true)),
        AdminCommand::Coverage {
            common,
            resolution_m,
            ..
        } => {
            if !(0.05..=5.0).contains(resolution_m) {
                return Err(format!(
                    "--resolution-m {resolution_m} is out of range (0.05 to 5 m)"
                ));
            }
            let payload = ickon_proto::encode(&CoverageRequest {
                resolution_m: *resolution_m,
            })
            .map_err(|e| e.to_string())?;
            (common, Request::new("coverage", Some(payload), true))
        }
        AdminCommand::Pause(c) => (c, Request::new("pause", None, false)),
        AdminCommand::Resume(c) => (c, Request::new("resume", None, false)),
        AdminCommand::Reload { file, common } => {
            // Bounded like every site file: `reload /dev/zero` must not fill memory.
            let site_toml =
                ickon_proto::text_file::read_bounded(file, ickon_proto::site::MAX_SITE_FILE_BYTES)
                    .map_err(|e| format!("cannot read site file {}: {e}", file.display()))?;
            let payload = ickon_proto::encode(&ReloadRequest {
                file_name: file.display().to_string(),
                site_toml,
            })
            .map_err(|e| e.to_string())?;
            (common, Request::new("reload", Some(payload), false))
        }
    };
    ickon_proto::keys::validate_id(&common.site_name).map_err(|e| format!("--site-name: {e}"))?;
    if common.timeout_ms == 0 {
        return Err("--timeout-ms must be positive".into());
    }
    Ok((common, request))
}

/// Where to connect: the flags, or the run file of an `ickon sim` of the
/// site. Without a config file the admin is a Zenoh client: it talks to the
/// peer it connects to and nobody else (no gossip, no listening port).
fn zenoh_config(common: &Common) -> Result<(zenoh::Config, String), String> {
    let (flags, to) = if common.zenoh.names_a_peer() {
        let to = if common.zenoh.connect.is_empty() {
            "the peers of the Zenoh config".to_string()
        } else {
            common.zenoh.connect.join(", ")
        };
        (common.zenoh.clone(), to)
    } else {
        let dir = RunDir::standard();
        let run = dir.read(&common.site_name).map_err(|e| {
            let others: Vec<String> = dir
                .sites()
                .into_iter()
                .filter(|s| s != &common.site_name)
                .collect();
            let hint = if others.is_empty() {
                String::new()
            } else {
                format!(
                    "\n  run files for other sites: {} (use --site-name)",
                    others.join(", ")
                )
            };
            format!(
                "{e}{hint}\n  give -e/--connect ENDPOINT or --zenoh-config FILE to reach a site elsewhere"
            )
        })?;
        let to = format!(
            "{} (from the run file of `ickon sim`)",
            run.central.join(", ")
        );
        let flags = ZenohArgs {
            connect: run.central,
            no_multicast_scouting: true,
            ..common.zenoh.clone()
        };
        (flags, to)
    };
    let mut config = flags.zenoh_config().map_err(|e| format!("{e:#}"))?;
    if flags.zenoh_config.is_none() {
        config
            .insert_json5("mode", "\"client\"")
            .map_err(|e| format!("Zenoh config mode: {e}"))?;
    }
    Ok((config, to))
}

/// Connects, waits for the central unit, asks, and returns its answer.
async fn ask<T: DeserializeOwned>(common: &Common, request: Request) -> Result<T, String> {
    let (config, to) = zenoh_config(common)?;
    let keys = Keys::new(&common.site_name).map_err(|e| e.to_string())?;
    let key = keys
        .central_admin(request.command)
        .map_err(|e| e.to_string())?;
    let timeout = Duration::from_millis(common.timeout_ms);
    let deadline = Instant::now() + timeout;
    let no_answer = || {
        format!(
            "no central unit of site {:?} answered within {:.1} s (connecting to {to})",
            common.site_name,
            timeout.as_secs_f64()
        )
    };
    // Who this session authenticates as on a router with access control.
    let user: Option<String> = config
        .get_json("transport/auth/usrpwd/user")
        .ok()
        .and_then(|v| serde_json::from_str(&v).ok());
    let session = tokio::time::timeout_at(deadline, zenoh::open(config))
        .await
        .map_err(|_| no_answer())?
        .map_err(|e| {
            let why = match &user {
                None => "; a secured router refuses a client without the site's TLS certificates and a user and password (give the admin credential: --zenoh-config DIR/clients/admin.json5 of `ickon site secure`)".to_string(),
                Some(u) => format!("; the router may have refused the user {u:?} or its password"),
            };
            format!("{}: cannot connect: {e}{why}", no_answer())
        })?;
    // The central unit is live but no answer came: on a secured router that
    // is the access control dropping the query of anyone but the admin.
    let refused = || match user.as_deref() {
        Some(u) if u != ADMIN_USER => format!(
            "refused: the central unit of site {:?} is live but its admin queries are only for the admin identity, and this session authenticated as {u:?} (give the admin credential: --zenoh-config DIR/clients/admin.json5 of `ickon site secure`)",
            common.site_name
        ),
        _ => no_answer(),
    };
    let answer = async {
        let left = deadline.saturating_duration_since(Instant::now());
        if !wait_for_token(&session, &keys.alive_central(), left)
            .await
            .map_err(|e| e.to_string())?
        {
            return Err(no_answer());
        }
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(refused());
            }
            // An undecodable answer is logged by `query_once` and counts as none.
            let reply: Option<T> = query_once(&session, &key, request.payload.clone(), left)
                .await
                .map_err(|e| e.to_string())?;
            match reply {
                Some(value) => return Ok(value),
                None if request.idempotent => {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
                None => return Err(refused()),
            }
        }
    }
    .await;
    let _ = session.close().await;
    answer
}

/// What the central unit answered, by kind.
enum Answer {
    /// With `status`, each node's router link, when the central unit knows
    /// `links` (one that does not leaves the query unanswered).
    Status(StatusReport, Option<LinksReport>),
    Schedule(Schedule),
    Coverage(CoverageReport),
    Transmitters(TransmittersReport),
    Robots(RobotPage),
    Ack(AdminAck),
}

/// Asks for the answer type of `command`.
async fn answer(
    command: &AdminCommand,
    common: &Common,
    request: Request,
) -> Result<Answer, String> {
    Ok(match command {
        AdminCommand::Status(_) => {
            let status = ask(common, request).await?;
            // Not idempotent, so not asked again: no answer means none.
            let links = ask(common, Request::new("links", None, false)).await.ok();
            Answer::Status(status, links)
        }
        AdminCommand::Cells(_) | AdminCommand::Sync(_) => {
            Answer::Status(ask(common, request).await?, None)
        }
        AdminCommand::Robots { .. } => Answer::Robots(ask(common, request).await?),
        AdminCommand::Schedule(_) => Answer::Schedule(ask(common, request).await?),
        AdminCommand::Coverage { .. } => Answer::Coverage(ask(common, request).await?),
        AdminCommand::Transmitters(_) => Answer::Transmitters(ask(common, request).await?),
        AdminCommand::Pause(_) | AdminCommand::Resume(_) | AdminCommand::Reload { .. } => {
            Answer::Ack(ask(common, request).await?)
        }
    })
}

/// Prints the answer of `command`; a refusal is bad input.
fn show(command: &AdminCommand, common: &Common, answer: Answer) -> Result<(), CommandError> {
    let failed = |e: format::FormatError| CommandError::failure(e.to_string());
    let json = common.json;
    let text = match (command, answer) {
        (AdminCommand::Cells(_), Answer::Status(s, _)) => {
            format::cells(&s, json).map_err(failed)?
        }
        (AdminCommand::Sync(_), Answer::Status(s, _)) => format::sync(&s, json).map_err(failed)?,
        (_, Answer::Status(s, links)) => status_with_links(&s, links.as_ref(), json)?,
        (_, Answer::Schedule(s)) => format::schedule(&s, json).map_err(failed)?,
        (_, Answer::Transmitters(t)) => format::transmitters(&t, json).map_err(failed)?,
        (_, Answer::Robots(page)) => {
            if !page.error.is_empty() {
                return Err(CommandError::bad_input(format!("refused: {}", page.error)));
            }
            format::robot_page(&page, json).map_err(failed)?
        }
        (AdminCommand::Coverage { png: file, .. }, Answer::Coverage(report)) => {
            if let Some(file) = file {
                png::heat_map(file, &report).map_err(|e| {
                    CommandError::failure(format!("cannot write {}: {e}", file.display()))
                })?;
                if !json {
                    eprintln!("heat map written to {} ({})", file.display(), png::LEGEND);
                }
            }
            coverage_view::coverage(&report, json).map_err(failed)?
        }
        (_, Answer::Coverage(report)) => coverage_view::coverage(&report, json).map_err(failed)?,
        (_, Answer::Ack(ack)) => {
            let text = format::ack(&ack, json).map_err(failed)?;
            if !ack.ok {
                if json {
                    print!("{text}");
                    return Err(CommandError::bad_input("refused"));
                }
                return Err(CommandError::bad_input(format!(
                    "refused:\n{}",
                    text.trim_end()
                )));
            }
            text
        }
    };
    print!("{text}");
    Ok(())
}

/// `status`, and the nodes' router links under it when the central unit
/// answered `links` (in the JSON document: `router_links`).
fn status_with_links(
    s: &StatusReport,
    links: Option<&LinksReport>,
    json: bool,
) -> Result<String, CommandError> {
    let failed = |e: format::FormatError| CommandError::failure(e.to_string());
    let text = format::status(s, json).map_err(failed)?;
    let Some(links) = links else {
        return Ok(text);
    };
    if json {
        let mut doc: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| CommandError::failure(format!("cannot add the router links: {e}")))?;
        doc["router_links"] = links_view::to_json(links);
        return format::to_json(&doc).map_err(failed);
    }
    let now_unix_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX));
    Ok(text + &links_view::section(links, now_unix_ms))
}
