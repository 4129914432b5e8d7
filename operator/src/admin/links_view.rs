//! `ickon admin status`'s lines on each node's link to its Zenoh router,
//! as the nodes report it (the central unit's `links`): which nodes came
//! back after losing it, when, and how often they lost it.

use std::fmt::Write;

use ickon_proto::msg::admin::LinksReport;
use ickon_proto::msg::control::RouterLink;
use serde_json::{Value, json};

/// How far a node's clock may run ahead of this host's before a report
/// stamped by it is called ahead: NTP keeps a site's hosts well inside.
const CLOCK_TOLERANCE_MS: u64 = 1_000;

/// The section under the status, `now_unix_ms` being this host's clock.
pub fn section(links: &LinksReport, now_unix_ms: u64) -> String {
    let mut out = String::new();
    let lost: Vec<(&str, &RouterLink)> = links
        .cells
        .iter()
        .map(|l| ("cell", l))
        .chain(links.robots.iter().map(|l| ("robot", l)))
        .filter(|(_, l)| l.losses > 0)
        .collect();
    let _ = write!(
        out,
        "router links: {} cells and {} robots report theirs; ",
        links.cells.len(),
        links.robots.len()
    );
    if lost.is_empty() {
        let _ = writeln!(out, "none lost it since it started");
        return out;
    }
    let _ = writeln!(out, "reconnected since they started:");
    let _ = writeln!(
        out,
        "{:<8} {:<6} {:>14} {:>12} {:>7}",
        "node", "kind", "back (UTC)", "ago", "losses"
    );
    for (kind, l) in lost {
        let (back, ago) = if l.back_unix_ms == 0 {
            // Lost and not back when it last reported.
            ("not yet".to_string(), "-".to_string())
        } else if l.back_unix_ms > now_unix_ms + CLOCK_TOLERANCE_MS {
            // The node's clock is ahead of this host's, or the report
            // lies: say so rather than "0 s".
            (
                clock_time(l.back_unix_ms),
                format!("{} ahead", ago(l.back_unix_ms - now_unix_ms)),
            )
        } else {
            (
                clock_time(l.back_unix_ms),
                ago(now_unix_ms.saturating_sub(l.back_unix_ms)),
            )
        };
        let _ = writeln!(
            out,
            "{:<8} {:<6} {:>14} {:>12} {:>7}",
            l.node_id, kind, back, ago, l.losses
        );
    }
    out
}

/// The same for `--json`: per node its id, `back_unix_ms` (null: not lost
/// since it started) and `losses`.
pub fn to_json(links: &LinksReport) -> Value {
    let node = |l: &RouterLink| {
        json!({
            "id": l.node_id,
            "back_unix_ms": (l.back_unix_ms > 0).then_some(l.back_unix_ms),
            "losses": l.losses,
        })
    };
    json!({
        "cells": links.cells.iter().map(node).collect::<Vec<_>>(),
        "robots": links.robots.iter().map(node).collect::<Vec<_>>(),
    })
}

/// `HH:MM:SS` of a Unix time in milliseconds, UTC.
fn clock_time(unix_ms: u64) -> String {
    let s = (unix_ms / 1000) % 86_400;
    format!("{:02}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

/// A span in the largest whole units that say it: `42 s`, `3 min 5 s`,
/// `2 h 10 min`, `3 d 4 h`.
fn ago(ms: u64) -> String {
    let s = ms / 1000;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {} s", s / 60, s % 60),
        3600..86_400 => format!("{} h {} min", s / 3600, s / 60 % 60),
        _ => format!("{} d {} h", s / 86_400, s / 3600 % 24),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(id: &str, back: u64, losses: u64) -> RouterLink {
        RouterLink {
            node_id: id.into(),
            back_unix_ms: back,
            losses,
        }
    }

    /// 2026-12-07 15:03:12 UTC.
    const BACK: u64 = 1_796_655_792_000;

    #[test]
    fn nodes_that_came_back_are_listed_with_when_and_how_often() {
        let links = LinksReport {
            cells: vec![link("c1", 0, 0), link("c2", BACK, 2)],
            robots: vec![link("r1", 0, 1), link("r2", 0, 0)],
        };
        let text = section(&links, BACK + 125_000);
        assert!(text.starts_with("router links: 2 cells and 2 robots report theirs; reconnected"));
        assert!(
            text.contains("c2       cell         15:03:12    2 min 5 s       2"),
            "{text}"
        );
        assert!(
            text.contains("r1       robot         not yet            -       1"),
            "{text}"
        );
        assert!(!text.contains("c1 "), "{text}");
        assert!(!text.contains("r2 "), "{text}");
    }

    #[test]
    fn a_site_that_never_lost_a_link_says_so_in_one_line() {
        let links = LinksReport {
            cells: vec![link("c1", 0, 0)],
            robots: vec![],
        };
        assert_eq!(
            section(&links, BACK),
            "router links: 1 cells and 0 robots report theirs; none lost it since it started\n"
        );
        let v = to_json(&links);
        assert_eq!(v["cells"][0]["id"], "c1");
        assert!(v["cells"][0]["back_unix_ms"].is_null());
    }

    #[test]
    fn a_report_stamped_ahead_of_this_host_says_so() {
        let links = LinksReport {
            cells: vec![link("c1", BACK + 90_000, 1), link("c2", u64::MAX, 3)],
            robots: vec![link("r1", BACK + 500, 1)],
        };
        let text = section(&links, BACK);
        assert!(text.contains("1 min 30 s ahead"), "{text}");
        assert!(
            text.contains("c2 ") && text.contains(" ahead       3"),
            "{text}"
        );
        // Within the clocks' tolerance it is just now.
        assert!(
            text.contains("r1       robot        15:03:12          0 s       1"),
            "{text}"
        );
    }

    #[test]
    fn spans_read_in_their_largest_units() {
        assert_eq!(ago(42_900), "42 s");
        assert_eq!(ago(3_600_000 + 600_000), "1 h 10 min");
        assert_eq!(ago(3 * 86_400_000 + 4 * 3_600_000), "3 d 4 h");
        assert_eq!(clock_time(BACK), "15:03:12");
    }
}
