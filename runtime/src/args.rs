//! The command-line flags every ICKON-rs process shares, and what they become:
//! a Zenoh configuration, a session, a device clock, a shutdown future.

use std::future::Future;
use std::path::PathBuf;

use clap::Args;
use zenoh::Session;

use crate::clock::{SimulatedClock, system_now};
use crate::error::NodeError;
use crate::shutdown::shutdown_signal;

/// The Zenoh connection flags, the same as Zenoh's own examples.
#[derive(Debug, Clone, Default, Args)]
pub struct ZenohArgs {
    /// A Zenoh configuration file (JSON5); the flags below override it.
    /// (Not `--config`: that names a node's own configuration, e.g. the
    /// MSU agent's.)
    #[arg(long = "zenoh-config", value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447` (repeatable).
    #[arg(short = 'e', long = "connect")]
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:0` (repeatable).
    #[arg(short = 'l', long = "listen")]
    pub listen: Vec<String>,
    /// Turn multicast scouting off (isolated meshes, tests).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// Zenoh mode: `client` (of a router, as on a site), `peer` or `router`;
    /// the config file's, else Zenoh's default (`peer`), when not given.
    #[arg(short = 'm', long, value_parser = ["client", "peer", "router"])]
    pub mode: Option<String>,
}

/// The `ZENOH_RUNTIME` setting that keeps a node's Zenoh thread pools small:
/// receiving, accepting and the network tasks are handed to the one-thread
/// application pool, so a node runs Zenoh on two threads (application and
/// transmission) instead of six. Read once by Zenoh when its first session
/// opens, so it is set in the environment of the process (`ickon sim` does so
/// for its nodes, the systemd units for a site). Zenoh's own default pools
/// are sized for one busy process per machine, not a hundred small ones.
pub const LEAN_ZENOH_RUNTIME: &str = "(app: (worker_threads: 1), tx: (worker_threads: 1), rx: (handover: app), acc: (handover: app), net: (handover: app))";

/// The environment variable Zenoh reads its thread pools' sizes from.
pub const ZENOH_RUNTIME_ENV: &str = "ZENOH_RUNTIME";

impl ZenohArgs {
    /// Whether the user said where to connect (a config file or an endpoint).
    pub fn names_a_peer(&self) -> bool {
        self.zenoh_config.is_some() || !self.connect.is_empty()
    }

    /// The Zenoh configuration the flags describe.
    pub fn zenoh_config(&self) -> Result<zenoh::Config, NodeError> {
        let mut config = match &self.zenoh_config {
            // Zenoh's own validation refuses half a credential; the
            // explanation names the missing field.
            Some(path) => zenoh::Config::from_file(path).map_err(|e| NodeError::Config {
                what: path.display().to_string(),
                reason: explain_refusal(path, &e.to_string()),
            })?,
            None => zenoh::Config::default(),
        };
        let mut set = |k: &str, v: String| {
            config.insert_json5(k, &v).map_err(|e| NodeError::Config {
                what: k.to_string(),
                reason: e.to_string(),
            })
        };
        // Serialising a list of strings cannot fail; were it to, the empty list says so.
        let list = |items: &[String]| serde_json::to_string(items).unwrap_or_else(|_| "[]".into());
        if !self.connect.is_empty() {
            set("connect/endpoints", list(&self.connect))?;
        }
        if !self.listen.is_empty() {
            set("listen/endpoints", list(&self.listen))?;
        }
        if self.no_multicast_scouting {
            set("scouting/multicast/enabled", "false".into())?;
        }
        if let Some(mode) = &self.mode {
            set("mode", format!("{mode:?}"))?;
        }
        check_tls_files(&config)?;
        Ok(config)
    }

    /// Opens the session the flags describe.
    pub async fn open(&self) -> Result<Session, NodeError> {
        zenoh::open(self.zenoh_config()?)
            .await
            .map_err(|e| NodeError::Zenoh(format!("cannot open the session: {e}")))
    }
}

/// Checks the TLS certificates and keys `config` names before any link
/// uses them ([`crate::certificate`]): a malformed, expired or not yet
/// valid one is refused (exit code 2, naming the file); one expiring soon
/// is a warning.
pub fn check_tls_files(config: &zenoh::Config) -> Result<(), NodeError> {
    let facts = crate::certificate::check_config_files(config, crate::certificate::unix_now_s())
        .map_err(|e| NodeError::Config {
            what: "transport.link.tls".into(),
            reason: e.to_string(),
        })?;
    for warning in facts.iter().filter_map(|f| f.expiry_warning()) {
        tracing::warn!("{warning}");
    }
    Ok(())
}

/// Zenoh's reason for refusing a configuration file, made readable: its
/// validation error prints the whole resolved configuration, so a
/// credential missing half of itself is named from the file's own text,
/// and otherwise the dump is cut off.
fn explain_refusal(path: &std::path::Path, zenoh_reason: &str) -> String {
    // A client file is a few hundred bytes; a huge one is not worth parsing twice.
    const MAX_EXPLAINED_BYTES: u64 = 1 << 20;
    let parsed = ickon_proto::text_file::read_bounded(path, MAX_EXPLAINED_BYTES)
        .ok()
        .and_then(|text| json5::from_str::<serde_json::Value>(&text).ok());
    if let Some(value) = parsed {
        let usrpwd = &value["transport"]["auth"]["usrpwd"];
        let set = |name: &str| usrpwd[name].as_str().is_some_and(|v| !v.is_empty());
        if let Err(reason) = credential_complete(set("user"), set("password")) {
            return reason;
        }
    }
    match zenoh_reason.find(": {") {
        Some(cut) => format!(
            "{} (a field has a value Zenoh does not accept)",
            &zenoh_reason[..cut]
        ),
        None => zenoh_reason.to_string(),
    }
}

/// `Err` names the missing half of a user/password credential.
fn credential_complete(user: bool, password: bool) -> Result<(), String> {
    match (user, password) {
        (true, false) => Err("transport.auth.usrpwd.password: missing (a user is given)".into()),
        (false, true) => Err("transport.auth.usrpwd.user: missing (a password is given)".into()),
        _ => Ok(()),
    }
}

/// Connection and simulation flags shared by every node.
#[derive(Debug, Clone, Args)]
pub struct NodeArgs {
    /// Zenoh connection flags.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Site name, the `<site>` of every key [default: lab]. The central
    /// unit takes it from its site file; given there too, it must match
    /// the file's `name`.
    #[arg(long, value_name = "SITE_NAME")]
    pub site_name: Option<String>,
    /// A built-in site (`lab`, `warehouse`, `hall`) or a site file (TOML); the central
    /// unit serves it, the built-in `lab` when omitted. Other nodes take the
    /// site from the central unit.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Simulation only: offset of this node's clock from the true time,
    /// microseconds (at most 1000 s either way).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = clock_offset_us)]
    pub clock_offset_us: f64,
    /// Simulation only: drift of this node's clock, parts per million (at most 1000 either way).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = clock_drift_ppm)]
    pub clock_drift_ppm: f64,
    /// Simulation only: steps of this node's clock, microseconds, one taken
    /// at each SIGUSR1 in this order (`ickon sim --faults clockstep:`; see
    /// `ickon_runtime::clock_steps`).
    #[arg(long, allow_hyphen_values = true, value_parser = crate::clock_steps::parse_step_list)]
    pub sim_clock_steps_us: Option<crate::clock_steps::StepList>,
    /// Stop when the parent process (the launcher) goes away.
    #[arg(long)]
    pub exit_with_parent: bool,
}

/// A finite number within `limit` either way.
fn bounded(text: &str, limit: f64, unit: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number"))?;
    if v.is_finite() && v.abs() <= limit {
        Ok(v)
    } else {
        Err(format!(
            "must be a finite number of at most {limit} {unit} either way"
        ))
    }
}

/// `--clock-offset-us`: a real clock is not 1000 s off once it runs NTP.
fn clock_offset_us(text: &str) -> Result<f64, String> {
    bounded(text, 1e9, "us")
}

/// `--clock-drift-ppm`: no crystal drifts by more than 1000 ppm.
fn clock_drift_ppm(text: &str) -> Result<f64, String> {
    bounded(text, 1_000.0, "ppm")
}

/// The site name a node uses when `--site-name` is not given: the built-in
/// `lab` site's.
pub const DEFAULT_SITE_NAME: &str = "lab";

impl NodeArgs {
    /// The site name: `--site-name`, or [`DEFAULT_SITE_NAME`].
    pub fn site_name(&self) -> &str {
        self.site_name.as_deref().unwrap_or(DEFAULT_SITE_NAME)
    }

    /// The Zenoh configuration the flags describe.
    pub fn zenoh_config(&self) -> Result<zenoh::Config, NodeError> {
        self.zenoh.zenoh_config()
    }

    /// Opens the session the flags describe, and watches its link to the
    /// router: a loss is logged at WARN, the return at INFO
    /// ([`crate::router_watch`]).
    pub async fn open(&self) -> Result<Session, NodeError> {
        let session = self.zenoh.open().await?;
        crate::router_watch::spawn(session.clone())
            .map_err(|e| NodeError::Setup(format!("cannot start the router watch: {e}")))?;
        Ok(session)
    }

    /// This node's clock: the system clock with the injected offset and drift.
    pub fn clock(&self) -> SimulatedClock {
        SimulatedClock::new(
            system_now(),
            (self.clock_offset_us * 1e3).round() as i64,
            self.clock_drift_ppm * 1e-6,
        )
    }

    /// Takes `--sim-clock-steps-us` on `clock` at each SIGUSR1 (nothing
    /// without the flag); call once, inside the node's Tokio runtime.
    pub fn listen_for_clock_steps(&self, clock: SimulatedClock) -> Result<(), NodeError> {
        let steps = self
            .sim_clock_steps_us
            .clone()
            .map_or_else(Vec::new, |s| s.0);
        crate::clock_steps::listen(steps, clock)
            .map_err(|e| NodeError::Setup(format!("--sim-clock-steps-us: {e}")))
    }

    /// Completes on Ctrl-C, SIGTERM, or (with `--exit-with-parent`) when the parent goes away.
    pub fn shutdown(&self) -> impl Future<Output = ()> + use<> {
        shutdown_signal(self.exit_with_parent)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clock_steps_are_one_flag_value() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            node: NodeArgs,
        }
        let cli = Cli::parse_from(["x", "--sim-clock-steps-us", "5000,-200"]);
        assert_eq!(
            cli.node.sim_clock_steps_us,
            Some(crate::clock_steps::StepList(vec![5_000_000, -200_000]))
        );
        assert!(Cli::try_parse_from(["x", "--sim-clock-steps-us", "NaN"]).is_err());
        assert_eq!(Cli::parse_from(["x"]).node.sim_clock_steps_us, None);
    }

    #[test]
    fn flags_become_a_zenoh_config() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            node: NodeArgs,
        }
        let cli = Cli::parse_from([
            "x",
            "--connect",
            "tcp/127.0.0.1:7447",
            "--listen",
            "tcp/127.0.0.1:0",
            "--no-multicast-scouting",
            "--clock-offset-us",
            "-20000",
            "--mode",
            "client",
        ]);
        let config = cli.node.zenoh_config().unwrap();
        assert_eq!(config.get_json("mode").unwrap(), "\"client\"");
        assert!(cli.node.zenoh.names_a_peer());
        assert_eq!(cli.node.clock_offset_us, -20_000.0);
    }

    #[test]
    fn clock_flags_refuse_nan_infinity_and_absurd_values() {
        use clap::Parser;
        #[derive(Parser, Debug)]
        struct Cli {
            #[command(flatten)]
            node: NodeArgs,
        }
        for (flag, value) in [
            ("--clock-offset-us", "NaN"),
            ("--clock-offset-us", "1e16"),
            ("--clock-offset-us", "inf"),
            ("--clock-drift-ppm", "-5000"),
            ("--clock-drift-ppm", "abc"),
        ] {
            let err = Cli::try_parse_from(["x", flag, value])
                .unwrap_err()
                .to_string();
            assert!(err.contains(flag), "{flag} {value}: {err}");
        }
        let ok = Cli::try_parse_from([
            "x",
            "--clock-offset-us",
            "-50000",
            "--clock-drift-ppm",
            "99.5",
        ])
        .unwrap();
        assert_eq!(
            (ok.node.clock_offset_us, ok.node.clock_drift_ppm),
            (-50_000.0, 99.5)
        );
    }

    #[test]
    fn a_credential_with_only_a_user_or_only_a_password_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, text: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, text).unwrap();
            ZenohArgs {
                zenoh_config: Some(path),
                ..ZenohArgs::default()
            }
        };
        let user_only = write(
            "user.json5",
            r#"{ mode: "client", transport: { auth: { usrpwd: { user: "cell-c1" } } } }"#,
        );
        let err = user_only.zenoh_config().unwrap_err();
        assert!(matches!(err, NodeError::Config { .. }), "{err}");
        let text = err.to_string();
        assert!(
            text.contains("user.json5") && text.contains("usrpwd.password"),
            "{text}"
        );
        let password_only = write(
            "password.json5",
            r#"{ mode: "client", transport: { auth: { usrpwd: { password: "x" } } } }"#,
        );
        let text = password_only.zenoh_config().unwrap_err().to_string();
        assert!(text.contains("usrpwd.user"), "{text}");
        let garbage = write(
            "garbage.json5",
            r#"{ mode: "client", transport: { link: { tx: { lease: "soon" } } } }"#,
        );
        let text = garbage.zenoh_config().unwrap_err().to_string();
        assert!(
            text.contains("garbage.json5") && text.len() < 400,
            "short and naming the file: {text}"
        );
        let both = write(
            "both.json5",
            r#"{ mode: "client", transport: { auth: { usrpwd: { user: "a", password: "b" } } } }"#,
        );
        assert!(both.zenoh_config().is_ok());
        let none = write("none.json5", r#"{ mode: "client" }"#);
        assert!(none.zenoh_config().is_ok());
    }

    #[test]
    fn a_missing_config_file_is_a_clear_error() {
        let mut args = ZenohArgs {
            zenoh_config: Some("/nonexistent/zenoh.json5".into()),
            ..ZenohArgs::default()
        };
        let err = args.zenoh_config().unwrap_err().to_string();
        assert!(err.contains("/nonexistent/zenoh.json5"), "{err}");
        args.zenoh_config = None;
        assert!(args.zenoh_config().is_ok());
        assert!(!args.names_a_peer());
    }

    #[test]
    fn every_deploy_config_file_parses() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/zenoh");
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            zenoh::Config::from_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
    }
}
