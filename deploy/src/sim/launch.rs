//! Starting the nodes of `ickon sim`: ports, command lines, injected clock errors.

use std::process::Command;

use ickon_proto::site::Site;
use rand::Rng;

use super::{MAX_CLOCK_DRIFT_PPM, MAX_CLOCK_OFFSET_US, SimArgs};

/// A free loopback TCP port (bound and released; the node binds it right after).
pub(super) fn free_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// The `ickon node <role>` command line shared by every node of the mesh.
pub(super) fn node_command(
    args: &SimArgs,
    site: &Site,
    role: &str,
    central: &str,
    listen: &str,
) -> anyhow::Result<Command> {
    let exe = std::env::current_exe()?;
    let mut cmd = Command::new(exe);
    cmd.args(["node", role, "--no-multicast-scouting", "--listen", listen]);
    cmd.args(["--site-name", &site.name]);
    if !central.is_empty() {
        cmd.args(["--connect", central]);
    }
    if let Some(site) = &args.site {
        cmd.arg("--site").arg(site);
    }
    cmd.arg("--exit-with-parent");
    Ok(cmd)
}

/// Stream of the injected clock errors, so that changing the world's noise
/// streams never changes the clocks.
pub(super) const CLOCK_STREAM: u64 = 0xC10C_C10C;

pub(super) fn clock_flags(rng: &mut rand_chacha::ChaCha8Rng) -> [String; 4] {
    let offset_us = rng.random_range(-MAX_CLOCK_OFFSET_US..=MAX_CLOCK_OFFSET_US);
    let drift_ppm = rng.random_range(-MAX_CLOCK_DRIFT_PPM..=MAX_CLOCK_DRIFT_PPM);
    [
        "--clock-offset-us".into(),
        format!("{offset_us:.0}"),
        "--clock-drift-ppm".into(),
        format!("{drift_ppm:.1}"),
    ]
}
