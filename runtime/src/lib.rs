//! # ickon-runtime
//!
//! What every ICKON-rs node shares at its Zenoh edge:
//!
//! - [`args`]: one set of connection flags ([`ZenohArgs`], the same as
//!   Zenoh's own examples) inside the node flags ([`NodeArgs`]), turned into
//!   a `zenoh::Config`;
//! - [`shutdown`]: a shutdown future (Ctrl-C, SIGTERM, or the parent process
//!   going away);
//! - [`error`]: [`NodeError`], the typed error of every node's edge, and
//!   [`command`]: [`CommandError`], the outcome of an `ickon` subcommand;
//! - [`clock`]: the system clock as a [`Time`](ickon_proto::time::Time), and
//!   the simulated device clock that lets a node run with an injected offset
//!   and drift, and [`clock_steps`]: its steps at run time in a simulation;
//! - [`query`]: a query with a timeout, one that retries until the central
//!   unit answers, and a wait for a liveliness token;
//! - [`site_join`]: what every node does to join a site ([`SiteJoin`]): its
//!   liveliness token, the site fetched and parsed, its subscribers;
//! - [`publish`]: a put whose failure is counted, never fatal;
//! - [`link`]: serial and TCP links to devices that reconnect by
//!   themselves, and pseudo-terminal pairs;
//! - [`log_limit`]: logs of bad input bounded to one line per kind per window;
//! - [`router_watch`]: the link to the Zenoh router watched, its loss and
//!   return logged (every node, through [`NodeArgs::open`]);
//! - [`certificate`]: the node's own TLS certificates and keys, checked at
//!   start (malformed, expired, expiring soon);
//! - [`cpus`]: the CPUs a process runs on, and pinning it to a set;
//! - [`runfile`]: the run file through which `ickon admin` finds an
//!   `ickon sim` running on the same machine.

pub mod args;
pub mod certificate;
pub mod clock;
pub mod clock_steps;
pub mod command;
pub mod cpus;
pub mod error;
pub mod link;
pub mod log_limit;
pub mod process;
pub mod publish;
pub mod query;
pub mod router_watch;
pub mod runfile;
pub mod shutdown;
pub mod site_join;
pub mod warnings;

pub use args::{LEAN_ZENOH_RUNTIME, NodeArgs, ZENOH_RUNTIME_ENV, ZenohArgs};
pub use clock::{SimulatedClock, system_now};
pub use command::CommandError;
pub use error::{NodeError, zerr};
pub use log_limit::LogLimiter;
pub use process::{block_on, init_tracing, run_node, stderr_is_terminal};
pub use publish::put_counted;
pub use query::{Stamped, fetch, query_once, query_stamped, token_present, wait_for_token};
pub use runfile::{RunDir, RunFile, RunFileError};
pub use shutdown::shutdown_signal;
pub use site_join::{JoinedSite, SiteJoin};

#[cfg(test)]
mod device_link_tests;
