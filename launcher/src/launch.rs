//! Starting the nodes of `ickon sim`: ports, command lines, injected clock errors.

use std::process::Command;

use ickon_proto::site::Site;
use rand::Rng;

use crate::args::{Mesh, SimArgs};
use crate::error::LaunchError;

/// Injected clock errors of cells and robots: up to this offset...
const MAX_CLOCK_OFFSET_US: f64 = 50_000.0;
/// ...and this drift.
const MAX_CLOCK_DRIFT_PPM: f64 = 100.0;

/// The `ickon node <role>` command line shared by every node of the mesh:
/// a client of the router at `hub` (`Mesh::Router`), or a peer listening on
/// `listen` and connected to `hub` (`Mesh::Peer`; no `hub` for the first),
/// reading the site from `site_file` (the built-in `lab` when `None`).
pub(crate) fn node_command(
    args: &SimArgs,
    site: &Site,
    site_file: Option<&std::path::Path>,
    role: &str,
    hub: &str,
    listen: &str,
) -> Result<Command, LaunchError> {
    let mut cmd = lean_command()?;
    cmd.args(["node", role, "--no-multicast-scouting"]);
    match args.mesh {
        Mesh::Router => {
            cmd.args(["--mode", "client"]);
        }
        Mesh::Peer => {
            cmd.args(["--mode", "peer", "--listen", listen]);
        }
    }
    cmd.args(["--site-name", &site.name]);
    if !hub.is_empty() {
        cmd.args(["--connect", hub]);
    }
    if let Some(file) = site_file {
        cmd.arg("--site").arg(file);
    }
    cmd.arg("--exit-with-parent");
    Ok(cmd)
}

/// The `ickon router` command line of a run's router, listening on
/// `endpoint` and linked to the router at `link`, if any.
pub(crate) fn router_command(endpoint: &str, link: Option<&str>) -> Result<Command, LaunchError> {
    let mut cmd = lean_command()?;
    cmd.args(["router", "--no-multicast-scouting", "--listen", endpoint]);
    if let Some(link) = link {
        cmd.args(["--connect", link]);
    }
    cmd.arg("--exit-with-parent");
    Ok(cmd)
}

/// This executable, with Zenoh's thread pools kept small (unless the user
/// chose their own `ZENOH_RUNTIME`): a hundred processes on two cores.
fn lean_command() -> Result<Command, LaunchError> {
    let mut cmd = Command::new(std::env::current_exe().map_err(LaunchError::Executable)?);
    if std::env::var_os(ickon_runtime::ZENOH_RUNTIME_ENV).is_none() {
        cmd.env(
            ickon_runtime::ZENOH_RUNTIME_ENV,
            ickon_runtime::LEAN_ZENOH_RUNTIME,
        );
    }
    Ok(cmd)
}

/// Waits until something accepts TCP connections on the loopback `port`
/// (the router listens), the router dies, or `timeout` passes.
pub(crate) async fn wait_for_listener(
    port: u16,
    sup: &mut crate::supervisor::Supervisor,
    timeout: std::time::Duration,
) -> Result<(), LaunchError> {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        // A loopback connect is answered at once: accepted or refused.
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return Ok(());
        }
        if let Some(dead) = sup.first_dead() {
            return Err(LaunchError::DiedAtStart {
                name: dead.name.clone(),
                status: dead.status.to_string(),
            });
        }
        if tokio::time::Instant::now() > deadline {
            return Err(LaunchError::RouterSilent {
                port,
                after_s: timeout.as_secs(),
            });
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
}

/// Stream of the injected clock errors, so that changing the world's noise
/// streams never changes the clocks.
pub(crate) const CLOCK_STREAM: u64 = 0xC10C_C10C;

pub(crate) fn clock_flags(rng: &mut rand_chacha::ChaCha8Rng) -> [String; 4] {
    let offset_us = rng.random_range(-MAX_CLOCK_OFFSET_US..=MAX_CLOCK_OFFSET_US);
    let drift_ppm = rng.random_range(-MAX_CLOCK_DRIFT_PPM..=MAX_CLOCK_DRIFT_PPM);
    [
        "--clock-offset-us".into(),
        format!("{offset_us:.0}"),
        "--clock-drift-ppm".into(),
        format!("{drift_ppm:.1}"),
    ]
}

/// Adds `--foxglove` of `ickon sim --foxglove` to the central unit's
/// command; the address it will serve, if any: the one asked for, or the
/// next free port above it when it is taken (the address is printed).
pub(crate) fn foxglove_flag(
    args: &SimArgs,
    central: &mut Command,
) -> Result<Option<std::net::SocketAddr>, LaunchError> {
    let Some(wanted) = args.foxglove else {
        return Ok(None);
    };
    let addr = ickon_central::http::first_free_addr(wanted).ok_or(LaunchError::NoFreeAddress {
        server: "Foxglove server",
        from: wanted,
    })?;
    central.arg("--foxglove").arg(addr.to_string());
    Ok(Some(addr))
}

/// Adds the web map's flags of `ickon sim --http` to the central unit's
/// command; the address it will serve, if any: the one asked for, or the
/// next free port above it when it is taken (the URL is printed).
pub(crate) fn http_flags(
    args: &SimArgs,
    central: &mut Command,
) -> Result<Option<std::net::SocketAddr>, LaunchError> {
    let Some(wanted) = args.http else {
        return Ok(None);
    };
    let addr = ickon_central::http::first_free_addr(wanted).ok_or(LaunchError::NoFreeAddress {
        server: "web map",
        from: wanted,
    })?;
    central.arg("--http").arg(addr.to_string());
    if let Some(token) = &args.http_token_file {
        central.arg("--http-token-file").arg(token);
    }
    Ok(Some(addr))
}
