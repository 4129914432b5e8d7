//! Several MSU agents in one process (`ickon node fleet`), as `ickon sim
//! --robots-per-process` starts them: each robot keeps its own core, keys,
//! configuration and outputs exactly as a lone agent ([`crate::node::run`]),
//! and they share the process's runtime and Zenoh session. A simulation of
//! a large fleet on one machine then costs a few processes instead of one
//! per robot; a deployed robot runs its own agent (`ickon node msu`).

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use ickon_runtime::{NodeArgs, NodeError};

use crate::node::{MsuArgs, MsuSettings, run, settings_from_args, settings_with_tuning};
use crate::receivers::ReceiverKind;
use crate::ros2::Ros2Options;

/// The most robots one process hosts (a bound on a command line that a
/// mistake could make absurd; a site has at most a few hundred robots).
pub const MAX_ROBOTS_PER_PROCESS: usize = 1024;

/// One robot's receiver source, `ROBOT=SOURCE`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RobotReceivers {
    /// The robot.
    pub robot: String,
    /// Where its arrivals come from.
    pub source: ReceiverKind,
}

impl std::str::FromStr for RobotReceivers {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (robot, source) = s
            .split_once('=')
            .ok_or_else(|| format!("{s:?} is not ROBOT=SOURCE"))?;
        if robot.is_empty() {
            return Err(format!("{s:?} names no robot"));
        }
        Ok(Self {
            robot: robot.to_string(),
            source: source.parse()?,
        })
    }
}

/// Arguments of `ickon node fleet`.
#[derive(Debug, Clone, Args)]
pub struct FleetArgs {
    /// Connection and simulation flags (one session for every robot).
    #[command(flatten)]
    pub mesh: NodeArgs,
    /// The robots this process serves, comma-separated: one agent each.
    #[arg(long, value_delimiter = ',', required = true)]
    pub robots: Vec<String>,
    /// The MSU configuration file every agent reads (as `ickon node msu --config`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Estimator name when there is no configuration file.
    #[arg(long, conflicts_with = "config")]
    pub estimator: Option<String>,
    /// Where one robot's arrivals come from, as ROBOT=SOURCE with the
    /// sources of `ickon node msu --receivers`; repeated, one per robot.
    /// Robots not named hear the simulated world.
    #[arg(long = "receivers", value_name = "ROBOT=SOURCE")]
    pub receivers: Vec<RobotReceivers>,
}

/// Every robot's settings, checked: robots named once each, a source only
/// for a robot of the list, at most [`MAX_ROBOTS_PER_PROCESS`].
pub fn fleet_settings(args: &FleetArgs) -> Result<(Vec<MsuSettings>, Vec<String>), String> {
    if args.robots.is_empty() || args.robots.iter().any(String::is_empty) {
        return Err("--robots needs one or more robot ids".into());
    }
    if args.robots.len() > MAX_ROBOTS_PER_PROCESS {
        return Err(format!(
            "--robots names {} robots; one process hosts at most {MAX_ROBOTS_PER_PROCESS}",
            args.robots.len()
        ));
    }
    let mut seen = BTreeSet::new();
    if let Some(twice) = args.robots.iter().find(|r| !seen.insert(r.as_str())) {
        return Err(format!("--robots names {twice:?} twice"));
    }
    let mut sourced = BTreeSet::new();
    for r in &args.receivers {
        if !seen.contains(r.robot.as_str()) {
            return Err(format!(
                "--receivers {}: {:?} is not one of --robots",
                r.source, r.robot
            ));
        }
        if !sourced.insert(r.robot.as_str()) {
            return Err(format!("--receivers names {:?} twice", r.robot));
        }
    }
    let lone = |robot: &str| MsuArgs {
        mesh: args.mesh.clone(),
        robot: robot.to_string(),
        config: args.config.clone(),
        estimator: args.estimator.clone(),
        timing_sigma_us: None,
        wheel_base_m: None,
        m_per_tick: None,
        receivers: args
            .receivers
            .iter()
            .find(|r| r.robot == robot)
            .map_or(ReceiverKind::Sim, |r| r.source.clone()),
        ros2: Box::new(Ros2Options::default()),
    };
    // Every agent reads the same file: read once, its warnings once.
    let (first, warnings) = settings_from_args(&lone(&args.robots[0]))?;
    let mut all = vec![first];
    for robot in &args.robots[1..] {
        all.push(settings_with_tuning(&lone(robot), all[0].tuning.clone())?);
    }
    Ok((all, warnings))
}

/// Runs every robot's agent until Ctrl-C/SIGTERM. One agent that fails
/// stops the process (exit 1, naming the robot): a fleet process is
/// reported as one node, and a half-served fleet would hide the failure.
/// Exit code 2 for bad arguments or configuration.
pub fn main_with(args: FleetArgs) -> ExitCode {
    let (all, warnings) = match fleet_settings(&args) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    for w in &warnings {
        tracing::warn!("{w}");
    }
    ickon_runtime::run_node(2, async {
        let session = args.mesh.open().await?;
        let r = serve(&session, all, args.mesh.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

/// Runs the agents on `session` until `shutdown` or the first failure.
async fn serve(
    session: &zenoh::Session,
    all: Vec<MsuSettings>,
    shutdown: impl std::future::Future<Output = ()>,
) -> Result<(), NodeError> {
    let (stop, stopped) = tokio::sync::watch::channel(false);
    let mut agents = tokio::task::JoinSet::new();
    for settings in all {
        let session = session.clone();
        let mut stopped = stopped.clone();
        agents.spawn(async move {
            let robot = settings.robot.clone();
            let until = async move {
                let _ = stopped.wait_for(|&s| s).await;
            };
            (robot, run(&session, settings, until).await)
        });
    }
    let mut shutdown = std::pin::pin!(shutdown);
    let mut stopping = false;
    let mut failure = None;
    loop {
        tokio::select! {
            () = &mut shutdown, if !stopping => {
                stopping = true;
                let _ = stop.send(true);
            }
            next = agents.join_next() => {
                let Some(next) = next else { break };
                let why = match next {
                    Ok((robot, Ok(n))) => {
                        tracing::debug!("robot {robot}: agent ended: {n:?}");
                        if stopping { continue }
                        format!("robot {robot}: its agent ended before the process was stopped")
                    }
                    Ok((robot, Err(e))) => format!("robot {robot}: {e}"),
                    Err(e) => format!("an agent's task failed: {e}"),
                };
                tracing::error!("{why}; stopping every robot of this process");
                failure.get_or_insert(NodeError::Setup(why));
                stopping = true;
                let _ = stop.send(true);
            }
        }
    }
    failure.map_or(Ok(()), Err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        fleet: FleetArgs,
    }

    fn parse(line: &[&str]) -> Result<FleetArgs, String> {
        Cli::try_parse_from(std::iter::once("fleet").chain(line.iter().copied()))
            .map(|c| c.fleet)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn every_robot_gets_its_own_settings_and_source() {
        let args = parse(&[
            "--robots",
            "r1,r2,r3",
            "--receivers",
            "r2=tcp:127.0.0.1:9000",
        ])
        .unwrap();
        let (all, _) = fleet_settings(&args).unwrap();
        let robots: Vec<&str> = all.iter().map(|s| s.robot.as_str()).collect();
        assert_eq!(robots, ["r1", "r2", "r3"]);
        assert_eq!(all[0].receivers, ReceiverKind::Sim);
        assert_eq!(all[1].receivers.to_string(), "tcp:127.0.0.1:9000");
        assert!(all.iter().all(|s| s.ros2.is_none()));
    }

    #[test]
    fn bad_fleets_are_refused_by_name() {
        let refusal = |line: &[&str]| match parse(line) {
            Err(e) => e,
            Ok(args) => fleet_settings(&args).map(|_| ()).unwrap_err(),
        };
        assert!(refusal(&["--robots", "r1,r1"]).contains("\"r1\" twice"));
        assert!(refusal(&["--robots", "r1,,r2"]).contains("robot ids"));
        assert!(
            refusal(&["--robots", "r1", "--receivers", "r9=sim"]).contains("\"r9\" is not one of")
        );
        assert!(
            refusal(&[
                "--robots",
                "r1",
                "--receivers",
                "r1=sim",
                "--receivers",
                "r1=sim"
            ])
            .contains("twice")
        );
        assert!(refusal(&["--robots", "r1", "--receivers", "nonsense"]).contains("ROBOT=SOURCE"));
        assert!(refusal(&["--robots", "r1", "--receivers", "r1=bogus:x"]).contains("bogus"));
        assert!(refusal(&["--robots", "r1", "--estimator", "nope"]).contains("nope"));
        let many: Vec<String> = (0..=MAX_ROBOTS_PER_PROCESS)
            .map(|k| format!("r{k}"))
            .collect();
        assert!(refusal(&["--robots", &many.join(",")]).contains("at most"));
    }
}
