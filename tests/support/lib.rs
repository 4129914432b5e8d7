//! What the end-to-end test binaries (`mesh`, `cli`, `data`, `tools`)
//! share: the `ickon` binary under test ([`ICKON`]), headless Chromium
//! ([`browser`]), a client of Foxglove's protocol ([`foxglove_client`]),
//! a running `ickon sim` ([`sim_run`]), a static file server for the
//! browser ([`static_http`]), and running the binary and reading its JSON
//! ([`run`]). The loopback kit itself (ports,
//! process guards, bounded waits, the observer session) is `ickon-testkit`.

pub mod browser;
pub mod foxglove_client;
pub mod ickon;
pub mod run;
pub mod sim_run;
pub mod static_http;

pub use ickon::ICKON;
