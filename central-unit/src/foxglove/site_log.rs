//! The site's log for the Foxglove log panel: what changed for the worse
//! (or got well again) between two snapshots, as `foxglove.Log` entries.
//!
//! A cell going down is an error, a robot going down or stale a warning
//! and error, a robot localising or dead reckoning a warning; coming back
//! is information. Only changes are logged, so the log stays readable
//! however long the site runs, and a flapping node is bounded by how often
//! snapshots are made. The central unit's own warnings and errors (those
//! of its log file) join them ([`process_warnings`]).

use std::collections::BTreeMap;

use foxglove::messages::{Log, Timestamp, log::Level};

use super::scene::{cell_state, robot_state};
use crate::http::view::Snapshot;

/// The `name` of the log entries about cells and robots.
pub const LOG_NAME: &str = "ickon-central";

/// The central unit's own warnings and errors as log entries, named by the
/// module that logged them; `lost` (lines let go before they could be
/// shown) becomes one warning of its own.
pub fn process_warnings(
    lines: &[ickon_runtime::warnings::Warning],
    lost: u64,
    stamp: Timestamp,
) -> Vec<Log> {
    let mut out: Vec<Log> = lines
        .iter()
        .map(|w| {
            let level = if w.level == tracing::Level::ERROR {
                Level::Error
            } else {
                Level::Warning
            };
            Log {
                timestamp: Some(Timestamp::new(
                    (w.at_ns / 1_000_000_000) as u32,
                    (w.at_ns % 1_000_000_000) as u32,
                )),
                level: level as i32,
                message: w.message.clone(),
                name: w.target.clone(),
                ..Default::default()
            }
        })
        .collect();
    if lost > 0 {
        out.push(entry(
            Level::Warning,
            format!("{lost} earlier warnings of the central unit are only in its log file"),
            stamp,
        ));
    }
    out
}

/// What the site looked like at the last snapshot (see the module doc).
#[derive(Debug, Default)]
pub struct SiteLog {
    cells: BTreeMap<String, &'static str>,
    robots: BTreeMap<String, &'static str>,
}

fn entry(level: Level, message: String, stamp: Timestamp) -> Log {
    Log {
        timestamp: Some(stamp),
        level: level as i32,
        message,
        name: LOG_NAME.to_string(),
        ..Default::default()
    }
}

impl SiteLog {
    /// The entries for what changed since the previous snapshot; the first
    /// snapshot logs only what is already wrong.
    pub fn update(&mut self, snapshot: &Snapshot, stamp: Timestamp) -> Vec<Log> {
        let mut out = Vec::new();
        for c in &snapshot.cells {
            // Idle is up and quiet: not worth a line.
            let state = match cell_state(c) {
                "down" => "down",
                _ => "up",
            };
            let before = self.cells.insert(c.health.id.clone(), state);
            if before == Some(state) {
                continue;
            }
            let id = &c.health.id;
            match (before, state) {
                (_, "down") => out.push(entry(
                    Level::Error,
                    format!(
                        "cell {id} is down (since cycle {}; {} cycles missed)",
                        c.health.state_since_cycle, c.health.cycles_missed
                    ),
                    stamp,
                )),
                (Some(_), _) => out.push(entry(Level::Info, format!("cell {id} is up"), stamp)),
                (None, _) => {}
            }
        }
        for r in &snapshot.robots {
            let state = robot_state(r);
            let before = self.robots.insert(r.health.id.clone(), state);
            if before == Some(state) {
                continue;
            }
            let id = &r.health.id;
            let why = r.health.stale.as_deref().unwrap_or("no pose lately");
            let line = match state {
                "down" => Some((Level::Error, format!("robot {id} is down"))),
                "stale" => Some((Level::Warning, format!("robot {id} is stale: {why}"))),
                "localising" => Some((
                    Level::Warning,
                    format!("robot {id} is localising: no fix has confirmed its pose yet"),
                )),
                "dead_reckoning" => Some((
                    Level::Warning,
                    format!("robot {id} is dead reckoning: no fix absorbed lately"),
                )),
                "tracking" if before.is_some_and(|b| b != "unknown") => {
                    Some((Level::Info, format!("robot {id} is tracking again")))
                }
                _ => None,
            };
            if let Some((level, message)) = line {
                out.push(entry(level, message, stamp));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::admin_json::{CellJson, RobotJson};
    use crate::http::view::{CellSnapshot, PoseView, RobotSnapshot};

    fn snapshot(cell_up: bool, robot: &'static str, pose_status: &'static str) -> Snapshot {
        let cell = CellSnapshot {
            health: CellJson {
                id: "c1".into(),
                state: if cell_up { "up" } else { "down" },
                state_since_cycle: 7,
                sync_error_us: None,
                sync_error_rms_us: None,
                residual_samples: 0,
                sync_sigma_us: 0.0,
                offset_us: 0.0,
                drift_ppm: 0.0,
                cycles_fired: 0,
                last_cycle_fired: 0,
                cycles_missed: 3,
                slots_skipped: 0,
                inputs_refused: 0,
                device: String::new(),
            },
            last_burst_ms: Some(10.0),
            last_tx: Some(1),
        };
        let robot = RobotSnapshot {
            health: RobotJson {
                id: "r1".into(),
                state: robot,
                stale: (robot == "stale").then(|| "no odometry for 2.0 s".to_string()),
                fixes_per_s: 0.0,
                fixes_over_rate: 0,
                survey_check: None,
                fixes_quarantined: 0,
                survey_misfit_mm: None,
                survey_bound_mm: None,
                receivers: None,
                estimator: None,
                pose: None,
                summaries_dropped: 0,
            },
            fused: Some(PoseView {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: 0.0,
            }),
            fused_ellipse: None,
            fused_heading_sigma_rad: None,
            pose_status: Some(pose_status),
            fix: None,
            truth: None,
            truth_at_pose: None,
            err_mm: None,
            staleness_ms: None,
            trail: Vec::new(),
        };
        Snapshot {
            site: "lab".into(),
            cycle: 1,
            paused: false,
            schedule_version: 1,
            update_rate_hz: 10.0,
            speed_of_sound_m_s: 343.2,
            speed_of_sound_learnt: false,
            transmitters_left_out: Vec::new(),
            cells: vec![cell],
            robots: vec![robot],
            ignored_messages: 0,
            clients: 0,
            clients_dropped: 0,
        }
    }

    fn lines(log: &mut SiteLog, s: &Snapshot) -> Vec<(i32, String)> {
        log.update(s, Timestamp::new(1, 0))
            .into_iter()
            .map(|l| (l.level, l.message))
            .collect()
    }

    #[test]
    fn only_changes_are_logged_with_their_level() {
        let mut log = SiteLog::default();
        assert!(lines(&mut log, &snapshot(true, "up", "tracking")).is_empty());
        assert!(lines(&mut log, &snapshot(true, "up", "tracking")).is_empty());
        let down = lines(&mut log, &snapshot(false, "stale", "tracking"));
        assert_eq!(down.len(), 2, "{down:?}");
        assert_eq!(down[0].0, Level::Error as i32);
        assert!(
            down[0]
                .1
                .contains("cell c1 is down (since cycle 7; 3 cycles missed)")
        );
        assert_eq!(down[1].0, Level::Warning as i32);
        assert!(down[1].1.contains("no odometry for 2.0 s"), "{down:?}");
        assert!(lines(&mut log, &snapshot(false, "stale", "tracking")).is_empty());
        let back = lines(&mut log, &snapshot(true, "up", "tracking"));
        assert_eq!(
            back,
            vec![
                (Level::Info as i32, "cell c1 is up".to_string()),
                (Level::Info as i32, "robot r1 is tracking again".to_string()),
            ]
        );
    }

    #[test]
    fn what_is_wrong_at_the_start_is_logged() {
        let mut log = SiteLog::default();
        let first = lines(&mut log, &snapshot(false, "up", "localising"));
        assert_eq!(first.len(), 2, "{first:?}");
        assert!(first[1].1.contains("localising"));
    }

    #[test]
    fn the_central_units_own_warnings_are_logged_by_their_module_and_losses_said() {
        use ickon_runtime::warnings::Warning;
        let warning = |level, message: &str| Warning {
            level,
            target: "ickon_central::node".to_string(),
            message: message.to_string(),
            at_ns: 1_700_000_000_123_456_789,
        };
        let lines = [
            warning(tracing::Level::WARN, "reload refused"),
            warning(tracing::Level::ERROR, "cannot publish"),
        ];
        let stamp = Timestamp::new(1_700_000_001, 0);
        let logged = process_warnings(&lines, 0, stamp);
        assert_eq!(logged.len(), 2);
        assert_eq!(logged[0].level, Level::Warning as i32);
        assert_eq!(logged[0].name, "ickon_central::node");
        assert_eq!(logged[0].message, "reload refused");
        assert_eq!(
            logged[0].timestamp,
            Some(Timestamp::new(1_700_000_000, 123_456_789))
        );
        assert_eq!(logged[1].level, Level::Error as i32);
        let with_loss = process_warnings(&lines[..1], 7, stamp);
        assert_eq!(with_loss.len(), 2);
        assert!(with_loss[1].message.starts_with("7 earlier warnings"));
        assert!(process_warnings(&[], 0, stamp).is_empty());
    }
}
