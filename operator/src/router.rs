//! `ickon router`: a Zenoh router, the hub of a floor.
//!
//! A thin process over Zenoh in router mode: on a site, every node (central
//! unit, cells, MSU agents, world, admin) is a client of its floor's router,
//! and the floors' routers connect to each other (`--connect`). `ickon sim`
//! runs one as its own supervised process. `zenohd` with
//! `deploy/zenoh/site-router.json5` does the same job; this one needs no other
//! build and takes the same flags as every ICKON-rs node.

use clap::Args;
use ickon_runtime::{NodeError, ZenohArgs};

use ickon_runtime::CommandError;

/// Arguments of `ickon router`.
#[derive(Debug, Args)]
pub struct RouterArgs {
    /// Zenoh flags: `-l` where clients and other routers reach this one
    /// (Zenoh's default `tcp/[::]:7447` when neither a file nor a flag says),
    /// `-e` the other floors' routers, `--zenoh-config` a router config file
    /// (`deploy/zenoh/site-router.json5`); the mode is always `router`.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Stop when the parent process (the launcher) goes away.
    #[arg(long)]
    pub exit_with_parent: bool,
}

/// The Zenoh configuration of the router the flags describe.
pub fn router_config(args: &RouterArgs) -> Result<zenoh::Config, NodeError> {
    let mut config = args.zenoh.zenoh_config()?;
    config
        .insert_json5("mode", "\"router\"")
        .map_err(|e| NodeError::Config {
            what: "mode".into(),
            reason: e.to_string(),
        })?;
    // A configuration with limits of its own (`ickon site secure` writes
    // them per site) keeps them; any other gets those of every site.
    let has_limits = config
        .get_json("low_pass_filter")
        .ok()
        .and_then(|v| serde_json::from_str::<serde_json::Value>(&v).ok())
        .is_some_and(|v| v.as_array().is_some_and(|a| !a.is_empty()));
    if !has_limits {
        let limits = crate::secure::limits::low_pass_filter_any_site().to_string();
        config
            .insert_json5("low_pass_filter", &limits)
            .map_err(|e| NodeError::Config {
                what: "low_pass_filter".into(),
                reason: e.to_string(),
            })?;
    }
    Ok(config)
}

/// Runs the router until Ctrl-C or SIGTERM (or the parent going away); exit
/// code 2 for a bad configuration (a bad access control list or user/password
/// dictionary included), 1 when Zenoh cannot start it.
pub fn run(args: RouterArgs) -> Result<(), CommandError> {
    let config = router_config(&args).map_err(|e| CommandError::bad_input(e.to_string()))?;
    // A broken ACL or dictionary: say which file and field, before Zenoh
    // refuses to start or, worse, starts and refuses every client.
    if let Some(file) = &args.zenoh.zenoh_config {
        crate::secure::check::router(file, &config)
            .map_err(|e| CommandError::bad_input(e.to_string()))?;
    }
    let outcome = ickon_runtime::block_on(1, async move {
        let session = zenoh::open(config)
            .await
            .map_err(|e| NodeError::Zenoh(format!("cannot start the router: {e}")))?;
        tracing::info!("router {} up", session.zid());
        ickon_runtime::shutdown_signal(args.exit_with_parent).await;
        session
            .close()
            .await
            .map_err(|e| NodeError::Zenoh(format!("closing the router: {e}")))
    });
    match outcome {
        Some(result) => result.map_err(CommandError::from),
        None => Err(CommandError::failure("cannot start the runtime")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_router_is_always_a_router() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            router: RouterArgs,
        }
        let cli = Cli::parse_from([
            "x",
            "--mode",
            "client",
            "-l",
            "tcp/127.0.0.1:0",
            "-e",
            "tcp/127.0.0.1:7447",
        ]);
        let config = router_config(&cli.router).unwrap();
        assert_eq!(config.get_json("mode").unwrap(), "\"router\"");
    }

    #[test]
    fn a_router_without_limits_of_its_own_gets_every_sites() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            router: RouterArgs,
        }
        let cli = Cli::parse_from(["x", "-l", "tcp/127.0.0.1:0"]);
        let config = router_config(&cli.router).unwrap();
        let limits: serde_json::Value =
            serde_json::from_str(&config.get_json("low_pass_filter").unwrap()).unwrap();
        // Zenoh fills the fields left out (as null): compare those written.
        let written = crate::secure::limits::low_pass_filter_any_site();
        let fields = ["id", "messages", "key_exprs", "size_limit"];
        let pick = |v: &serde_json::Value| -> Vec<serde_json::Value> {
            v.as_array()
                .into_iter()
                .flatten()
                .flat_map(|rule| fields.iter().map(|f| rule[f].clone()))
                .collect()
        };
        assert_eq!(pick(&limits), pick(&written));
        assert_eq!(limits.as_array().map(Vec::len), Some(2));
    }
}
