//! # ickon-runtime
//!
//! What every ICKON-rs node shares at its Zenoh edge: one set of connection
//! flags ([`NodeArgs`], the same as Zenoh's own examples) turned into a
//! `zenoh::Config`, a shutdown future (Ctrl-C, SIGTERM, or the parent process
//! going away), the system clock as a [`Time`], a query that retries until
//! the central unit answers, and the simulated device clock that lets a node
//! run with an injected offset and drift.

use std::future::Future;
use std::path::PathBuf;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use clap::Args;
use ickon_proto::time::Time;
use serde::de::DeserializeOwned;
use zenoh::Session;

/// Connection and simulation flags shared by every node.
#[derive(Debug, Clone, Args)]
pub struct NodeArgs {
    /// A Zenoh configuration file (JSON5); the flags below override it.
    #[arg(short = 'c', long = "config")]
    pub config: Option<PathBuf>,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447` (repeatable).
    #[arg(short = 'e', long = "connect")]
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:0` (repeatable).
    #[arg(short = 'l', long = "listen")]
    pub listen: Vec<String>,
    /// Turn multicast scouting off (isolated meshes, tests).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// Site name, the `<site>` of every key.
    #[arg(long, default_value = "lab")]
    pub site_name: String,
    /// Site file (TOML); the central unit serves it, the built-in site when
    /// omitted. Other nodes take the site from the central unit.
    #[arg(long)]
    pub site: Option<PathBuf>,
    /// Simulation only: offset of this node's clock from the true time, microseconds.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub clock_offset_us: f64,
    /// Simulation only: drift of this node's clock, parts per million.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub clock_drift_ppm: f64,
    /// Stop when the parent process (the launcher) goes away.
    #[arg(long)]
    pub exit_with_parent: bool,
}

/// Turns a Zenoh error into an `anyhow` one (zenoh's error type is boxed).
pub fn zerr(e: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

impl NodeArgs {
    /// The Zenoh configuration the flags describe.
    pub fn zenoh_config(&self) -> anyhow::Result<zenoh::Config> {
        let mut config = match &self.config {
            Some(path) => zenoh::Config::from_file(path)
                .map_err(|e| anyhow::anyhow!("Zenoh config {}: {e}", path.display()))?,
            None => zenoh::Config::default(),
        };
        let mut set = |k: &str, v: String| {
            config
                .insert_json5(k, &v)
                .map_err(|e| anyhow::anyhow!("Zenoh config {k}: {e}"))
        };
        if !self.connect.is_empty() {
            set("connect/endpoints", serde_json::to_string(&self.connect)?)?;
        }
        if !self.listen.is_empty() {
            set("listen/endpoints", serde_json::to_string(&self.listen)?)?;
        }
        if self.no_multicast_scouting {
            set("scouting/multicast/enabled", "false".into())?;
        }
        Ok(config)
    }

    /// Opens the session the flags describe.
    pub async fn open(&self) -> anyhow::Result<Session> {
        zenoh::open(self.zenoh_config()?)
            .await
            .map_err(|e| anyhow::anyhow!("cannot open the Zenoh session: {e}"))
    }

    /// This node's clock: the system clock with the injected offset and drift.
    pub fn clock(&self) -> SimulatedClock {
        SimulatedClock::new(
            system_now(),
            (self.clock_offset_us * 1e3).round() as i64,
            self.clock_drift_ppm * 1e-6,
        )
    }

    /// Completes on Ctrl-C, SIGTERM, or (with `--exit-with-parent`) when the parent goes away.
    pub fn shutdown(&self) -> impl Future<Output = ()> + use<> {
        shutdown_signal(self.exit_with_parent)
    }
}

/// Completes on Ctrl-C, SIGTERM, or (with `exit_with_parent`) when the parent goes away.
pub async fn shutdown_signal(exit_with_parent: bool) {
    let parent = std::os::unix::process::parent_id();
    let orphaned = async move {
        loop {
            tokio::time::sleep(Duration::from_millis(250)).await;
            if exit_with_parent && std::os::unix::process::parent_id() != parent {
                return;
            }
        }
    };
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
        _ = orphaned => {}
    }
}

/// The system clock as a [`Time`] since the Unix epoch. In a real-time
/// simulation this is the true time base; on a real site the master's.
pub fn system_now() -> Time {
    let ns = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    Time::from_nanos(i64::try_from(ns).unwrap_or(i64::MAX))
}

/// A device clock: true time plus an offset and a drift from a reference instant.
/// `local = true + offset + drift * (true - reference)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedClock {
    reference: Time,
    offset_ns: i64,
    drift: f64,
}

impl SimulatedClock {
    /// A clock that reads `true + offset_ns` at `reference` and gains `drift` seconds per second.
    pub fn new(reference: Time, offset_ns: i64, drift: f64) -> Self {
        Self {
            reference,
            offset_ns,
            drift: if drift.is_finite() { drift } else { 0.0 },
        }
    }

    /// The local reading at true time `t`.
    pub fn local(&self, t: Time) -> Time {
        let since = t.since(self.reference).as_nanos() as f64;
        Time::from_nanos(t.as_nanos() + self.offset_ns + (self.drift * since).round() as i64)
    }

    /// The true time at which the clock reads `local`.
    pub fn true_time(&self, local: Time) -> Time {
        let base = local.as_nanos() - self.offset_ns - self.reference.as_nanos();
        let since = (base as f64 / (1.0 + self.drift)).round() as i64;
        Time::from_nanos(self.reference.as_nanos() + since)
    }

    /// The local reading now (from the system clock).
    pub fn now(&self) -> Time {
        self.local(system_now())
    }
}

/// Asks `key` (with an optional CDR payload) until a decodable reply of type
/// `T` arrives; `None` if `shutdown` completes first. Undecodable replies are
/// logged and skipped.
pub async fn fetch<T: DeserializeOwned>(
    session: &Session,
    key: &str,
    payload: Option<Vec<u8>>,
    retry: Duration,
    shutdown: &mut (impl Future<Output = ()> + Unpin),
) -> anyhow::Result<Option<T>> {
    loop {
        if let Some(v) = query_once(session, key, payload.clone(), Duration::from_secs(2)).await? {
            return Ok(Some(v));
        }
        tracing::info!("waiting for an answer on {key}");
        tokio::select! {
            _ = &mut *shutdown => return Ok(None),
            _ = tokio::time::sleep(retry) => {}
        }
    }
}

/// One query: the first decodable reply, or `None` when nobody answered in time.
pub async fn query_once<T: DeserializeOwned>(
    session: &Session,
    key: &str,
    payload: Option<Vec<u8>>,
    timeout: Duration,
) -> anyhow::Result<Option<T>> {
    let mut get = session.get(key).timeout(timeout);
    if let Some(p) = payload {
        get = get.payload(p);
    }
    let replies = get.await.map_err(zerr)?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            match ickon_proto::decode::<T>(&sample.payload().to_bytes()) {
                Ok(v) => return Ok(Some(v)),
                Err(e) => tracing::warn!("undecodable reply on {key}: {e}"),
            }
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulated_clock_inverts_exactly_enough() {
        let c = SimulatedClock::new(Time(1_000_000_000_000), -50_000_000, 100e-6);
        for t in [1_000_000_000_000i64, 1_030_000_000_000, 1_100_000_000_000] {
            let local = c.local(Time(t));
            assert!((c.true_time(local).as_nanos() - t).abs() <= 1, "{t}");
        }
        // 30 s after the reference the clock has gained 3 ms on top of its -50 ms.
        let l = c.local(Time(1_030_000_000_000));
        assert_eq!(l.as_nanos() - 1_030_000_000_000, -50_000_000 + 3_000_000);
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
        ]);
        assert!(cli.node.zenoh_config().is_ok());
        assert_eq!(cli.node.clock_offset_us, -20_000.0);
    }

    #[test]
    fn a_missing_config_file_is_a_clear_error() {
        let mut args = NodeArgs {
            config: Some("/nonexistent/zenoh.json5".into()),
            connect: vec![],
            listen: vec![],
            no_multicast_scouting: true,
            site_name: "lab".into(),
            site: None,
            clock_offset_us: 0.0,
            clock_drift_ppm: 0.0,
            exit_with_parent: false,
        };
        let err = args.zenoh_config().unwrap_err().to_string();
        assert!(err.contains("/nonexistent/zenoh.json5"), "{err}");
        args.config = None;
        assert!(args.zenoh_config().is_ok());
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
