//! Why a run of the mesh could not be set up or started: a bad input (the
//! faults plan, the estimator), this machine (no port, no executable, one
//! CPU), or the mesh itself (a node died, the router never listened, the
//! observer's Zenoh session failed).

use std::net::SocketAddr;
use std::path::PathBuf;

use crate::core_split::SplitError;
use crate::faults::FaultPlanError;

/// Why a run of the mesh could not be set up or started.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// This executable, which every node is started as, cannot be found.
    #[error("cannot find this executable to start the nodes as: {0}")]
    Executable(std::io::Error),
    /// No loopback port could be had for a node.
    #[error("no free loopback port: {0}")]
    Port(std::io::Error),
    /// A process of the run could not be started.
    #[error("cannot start {name}: {error}")]
    Spawn {
        /// The process as the run names it.
        name: String,
        /// What the system said.
        error: std::io::Error,
    },
    /// No port was free at or above the one asked for a server.
    #[error("no free port for the {server} from {from}")]
    NoFreeAddress {
        /// The server (`Foxglove server`, `web map`).
        server: &'static str,
        /// The address asked for.
        from: SocketAddr,
    },
    /// The agents' estimator cannot be set up from `--estimator` and the
    /// site.
    #[error(transparent)]
    Estimator(#[from] ickon_sim::RunError),
    /// The agents' configuration file could not be written.
    #[error("cannot write the agents' configuration file: {0}")]
    MsuFile(String),
    /// `--faults` is not a plan.
    #[error(transparent)]
    Faults(#[from] FaultPlanError),
    /// `--split-cores` cannot split this machine.
    #[error(transparent)]
    Split(#[from] SplitError),
    /// A credential or Zenoh configuration file is unusable.
    #[error(transparent)]
    Node(#[from] ickon_runtime::NodeError),
    /// A Zenoh configuration file does not load.
    #[error("zenoh config {}: {message}", file.display())]
    ZenohConfigFile {
        /// The file.
        file: PathBuf,
        /// What Zenoh said.
        message: String,
    },
    /// A setting of the observer's Zenoh configuration was refused.
    #[error("zenoh config {key}: {message}")]
    ZenohConfig {
        /// The setting's key.
        key: String,
        /// What Zenoh said.
        message: String,
    },
    /// The launcher's own Zenoh session could not be opened.
    #[error("cannot open the observer's Zenoh session: {0}")]
    Session(String),
    /// The launcher's session could not subscribe or publish.
    #[error("the observer's Zenoh session: {0}")]
    Declare(String),
    /// A node died while the mesh was coming up.
    #[error("node {name} {status} during start-up")]
    DiedAtStart {
        /// The node.
        name: String,
        /// How it ended.
        status: String,
    },
    /// A node died before the launcher's second session could connect.
    #[error("node {name} {status} while the simulation was starting ({why})")]
    DiedBeforeProbe {
        /// The node.
        name: String,
        /// How it ended.
        status: String,
        /// What the session said.
        why: Box<LaunchError>,
    },
    /// The router never accepted connections.
    #[error("the router does not listen on port {port} after {after_s} s")]
    RouterSilent {
        /// Its loopback port.
        port: u16,
        /// How long it was waited for, seconds.
        after_s: u64,
    },
}

impl LaunchError {
    /// A Zenoh error of the observer's session as a [`LaunchError::Declare`].
    pub(crate) fn declare(e: zenoh::Error) -> Self {
        Self::Declare(e.to_string())
    }
}
