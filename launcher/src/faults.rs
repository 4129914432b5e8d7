//! `ickon sim --faults PLAN`: faults to inject into a running simulation,
//! so that resilience is measured, not claimed.
//!
//! A plan is a comma-separated list of `ACTION:NODE@AT[+ARG]`:
//!
//! - `kill:NODE@10s`: SIGKILL the node at 10 s (with `--restart` it is
//!   started again, as systemd would);
//! - `stop:NODE@15s+3s`: SIGSTOP it at 15 s, SIGCONT 3 s later (a hung node);
//! - `clockstep:NODE@20s+5ms`: step its clock by 5 ms (a cell or a central
//!   unit: the nodes that keep a clock). The node is started with
//!   `--sim-clock-steps-us` listing its steps in time order, and takes the
//!   next one at each SIGUSR1 the supervisor sends (see
//!   `ickon_runtime::clock_steps` for why this way).
//!
//! `NODE` is `central` (the first central unit), `central/standby` (the
//! second, with `--standby`), `world`, `router` (with `--routers N`, the
//! router of a zone: `router/z2`), `cell/<id>` or `msu/<id>`;
//! times take `s` or `ms` (`@2500ms`), a clock step `ms` or `us` and may be
//! negative. Every problem is reported with the item it is in.

use std::time::Duration;

/// What to do to a node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultAction {
    /// SIGKILL.
    Kill,
    /// SIGSTOP, then SIGCONT after this long.
    Stop(Duration),
    /// Step the node's clock by this many nanoseconds.
    ClockStep(i64),
}

/// One planned fault.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    /// What to do.
    pub action: FaultAction,
    /// The node, as the supervisor names it (`cell c2`, `msu r1`, `central`).
    pub node: String,
    /// When, from the moment every node is live.
    pub at: Duration,
    /// The item as written, for reports.
    pub text: String,
}

/// Why a plan could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--faults: {item:?}: {why}")]
pub struct FaultPlanError {
    /// The item the problem is in.
    pub item: String,
    /// What is wrong with it.
    pub why: String,
}

/// The longest a plan may reach (a day): a typo like `@100000s` is an error.
const LONGEST: Duration = Duration::from_secs(86_400);

/// Reads a plan's faults of processes, sorted by time; its transmitter
/// faults (`dead:`, `weak:`, `moved:`, [`ickon_sim::tx_faults`]) are the
/// world's and are left out here ([`transmitter_items`]).
pub fn parse_plan(plan: &str) -> Result<Vec<Fault>, FaultPlanError> {
    let items = ickon_sim::tx_faults::split_plan(plan);
    let mut faults = items
        .iter()
        .filter(|item| !ickon_sim::tx_faults::TransmitterFault::is_one(item))
        .map(|item| parse_item(item))
        .collect::<Result<Vec<_>, _>>()?;
    if items.is_empty() {
        return Err(FaultPlanError {
            item: plan.to_string(),
            why: "no fault in the plan".into(),
        });
    }
    faults.sort_by_key(|f| f.at);
    Ok(faults)
}

/// The transmitter faults of a plan, as the world node takes them
/// (`None`: there is none).
pub fn transmitter_items(plan: &str) -> Option<String> {
    let items: Vec<String> = ickon_sim::tx_faults::split_plan(plan)
        .into_iter()
        .filter(|item| ickon_sim::tx_faults::TransmitterFault::is_one(item))
        .collect();
    (!items.is_empty()).then(|| items.join(","))
}

fn parse_item(item: &str) -> Result<Fault, FaultPlanError> {
    let bad = |why: &str| FaultPlanError {
        item: item.to_string(),
        why: why.to_string(),
    };
    let (action, rest) = item
        .split_once(':')
        .ok_or_else(|| bad("expected ACTION:NODE@TIME (e.g. kill:central@10s)"))?;
    let (node, when) = rest
        .split_once('@')
        .ok_or_else(|| bad("expected @TIME after the node (e.g. @10s)"))?;
    let node = node_name(node).ok_or_else(|| {
        bad("unknown node: expected central, world, router, router/<zone>, cell/<id> or msu/<id>")
    })?;
    let (at, arg) = match when.split_once('+') {
        Some((at, arg)) => (at, Some(arg)),
        None => (when, None),
    };
    let at = duration(at).ok_or_else(|| bad("the time must be like 10s or 2500ms"))?;
    let action = match (action, arg) {
        ("kill", None) => FaultAction::Kill,
        ("kill", Some(_)) => return Err(bad("kill takes no +ARG")),
        ("stop", Some(arg)) => {
            FaultAction::Stop(duration(arg).ok_or_else(|| bad("stop needs how long, like +3s"))?)
        }
        ("stop", None) => return Err(bad("stop needs how long, like stop:cell/c2@15s+3s")),
        ("clockstep", Some(arg)) => FaultAction::ClockStep(
            step_ns(arg).ok_or_else(|| bad("clockstep needs a step, like +5ms or +-200us"))?,
        ),
        ("clockstep", None) => {
            return Err(bad(
                "clockstep needs a step, like clockstep:cell/c3@20s+5ms",
            ));
        }
        _ => return Err(bad("unknown action: expected kill, stop or clockstep")),
    };
    Ok(Fault {
        action,
        node,
        at,
        text: item.to_string(),
    })
}

/// `cell/c2` -> `cell c2`, as the supervisor names its children.
fn node_name(node: &str) -> Option<String> {
    match node {
        "central" | "world" | "router" => Some(node.to_string()),
        "central/standby" => Some("central standby".to_string()),
        _ => {
            let (kind, id) = node.split_once('/')?;
            let ok = matches!(kind, "cell" | "msu" | "router")
                && ickon_proto::keys::validate_id(id).is_ok();
            ok.then(|| format!("{kind} {id}"))
        }
    }
}

/// `10s`, `2.5s`, `2500ms`, bounded by a day.
fn duration(text: &str) -> Option<Duration> {
    let (value, scale) = if let Some(v) = text.strip_suffix("ms") {
        (v, 1e-3)
    } else {
        (text.strip_suffix('s')?, 1.0)
    };
    let s = value.parse::<f64>().ok()? * scale;
    (s.is_finite() && s >= 0.0 && s <= LONGEST.as_secs_f64()).then(|| Duration::from_secs_f64(s))
}

/// `5ms`, `-200us`: a clock step of at most 1000 s either way (the bound
/// of `--clock-offset-us`), nanoseconds.
fn step_ns(text: &str) -> Option<i64> {
    let (value, scale) = if let Some(v) = text.strip_suffix("ms") {
        (v, 1e6)
    } else {
        (text.strip_suffix("us")?, 1e3)
    };
    let ns = value.parse::<f64>().ok()? * scale;
    (ns.is_finite() && ns.abs() <= 1e12).then_some(ns.round() as i64)
}

/// Whether `node` (as the supervisor names it) keeps a clock a
/// `clockstep` can step: a cell or a central unit.
pub fn keeps_a_clock(node: &str) -> bool {
    node == "central" || node == "central standby" || node.starts_with("cell ")
}

/// The `--sim-clock-steps-us` value for `node`: its clock steps in time
/// order, microseconds; `None` when the plan steps no clock of it.
pub fn clock_steps_flag(plan: &[Fault], node: &str) -> Option<String> {
    let steps: Vec<String> = plan
        .iter()
        .filter(|f| f.node == node)
        .filter_map(|f| match f.action {
            FaultAction::ClockStep(ns) => Some(format!("{}", ns as f64 / 1e3)),
            _ => None,
        })
        .collect();
    (!steps.is_empty()).then(|| steps.join(","))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_gets_its_clock_steps_in_time_order() {
        let plan = parse_plan(
            "clockstep:cell/c3@30s+-200us,clockstep:cell/c3@20s+5ms,kill:cell/c3@25s,clockstep:central@1s+1ms",
        )
        .unwrap();
        assert_eq!(
            clock_steps_flag(&plan, "cell c3").as_deref(),
            Some("5000,-200")
        );
        assert_eq!(clock_steps_flag(&plan, "central").as_deref(), Some("1000"));
        assert_eq!(clock_steps_flag(&plan, "cell c1"), None);
        assert!(keeps_a_clock("cell c3") && keeps_a_clock("central standby"));
        assert!(!keeps_a_clock("msu r1") && !keeps_a_clock("world"));
        // The node parses what the supervisor writes.
        assert_eq!(
            ickon_runtime::clock_steps::parse_steps_us("5000,-200"),
            Ok(vec![5_000_000, -200_000])
        );
        assert!(parse_plan("clockstep:cell/c1@1s+2000s").is_err());
    }

    #[test]
    fn the_issues_plan_reads_in_time_order() {
        let plan = parse_plan(
            "kill:central@10s,stop:cell/c2@15s+3s,clockstep:cell/c3@20s+5ms,kill:msu/r1@25s",
        )
        .unwrap();
        assert_eq!(plan.len(), 4);
        assert_eq!(plan[0].action, FaultAction::Kill);
        assert_eq!(plan[0].node, "central");
        assert_eq!(plan[1].action, FaultAction::Stop(Duration::from_secs(3)));
        assert_eq!(plan[1].node, "cell c2");
        assert_eq!(plan[2].action, FaultAction::ClockStep(5_000_000));
        assert_eq!(plan[3].node, "msu r1");
        assert_eq!(plan[3].at, Duration::from_secs(25));
        let later_first = parse_plan("kill:world@2500ms, kill:router@1s").unwrap();
        assert_eq!(later_first[0].node, "router");
        assert_eq!(
            parse_plan("kill:router/z2@1s").unwrap()[0].node,
            "router z2"
        );
        assert_eq!(
            parse_plan("clockstep:cell/c1@1s+-200us").unwrap()[0].action,
            FaultAction::ClockStep(-200_000)
        );
    }

    #[test]
    fn every_mistake_names_the_item_and_what_is_wrong() {
        for (plan, says) in [
            ("", "no fault"),
            ("kill", "ACTION:NODE@TIME"),
            ("kill:central", "@TIME"),
            ("kill:cellar@1s", "unknown node"),
            ("kill:cell/c 2@1s", "unknown node"),
            ("kill:central@soon", "10s or 2500ms"),
            ("kill:central@-1s", "10s or 2500ms"),
            ("kill:central@1e9s", "10s or 2500ms"),
            ("kill:central@NaNs", "10s or 2500ms"),
            ("kill:central@1s+2s", "no +ARG"),
            ("stop:cell/c2@15s", "how long"),
            ("stop:cell/c2@15s+x", "how long"),
            ("clockstep:cell/c3@20s", "a step"),
            ("clockstep:cell/c3@20s+5h", "a step"),
            ("reboot:central@1s", "unknown action"),
            ("kill:central@1s,,oops", "ACTION:NODE@TIME"),
        ] {
            let e = parse_plan(plan).unwrap_err();
            assert!(e.to_string().contains(says), "{plan:?}: {e}");
        }
    }
}
