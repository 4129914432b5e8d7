//! What `ickon admin` prints: readable tables, or one JSON document.
//!
//! The JSON documents are [`ickon_central::admin_json`]'s, which the web
//! map's `/api/*` endpoints serve too.

use std::fmt::Write;

use ickon_central::admin_json::{CellJson, ScheduleJson, StatusJson};
use ickon_proto::msg::admin::{AdminAck, CellState, StatusReport};
use ickon_proto::msg::control::Schedule;
use serde::Serialize;

fn status_json(s: &StatusReport, cells: bool, robots: bool) -> StatusJson {
    StatusJson::new(s, cells, robots)
}

pub(super) fn to_json<T: Serialize>(value: &T) -> anyhow::Result<String> {
    Ok(serde_json::to_string_pretty(value)? + "\n")
}

fn us(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.1}"))
}

fn header(out: &mut String, s: &StatusReport) {
    let _ = writeln!(
        out,
        "site {}: cycle {}{}, schedule v{}, {:.2} cycles/s",
        s.site,
        s.cycle,
        if s.paused { " (paused)" } else { "" },
        s.schedule_version,
        s.update_rate_hz
    );
    let _ = writeln!(
        out,
        "central unit epoch {} ({}){}",
        s.epoch,
        if s.active { "active" } else { "standby" },
        if s.foreign_control > 0 {
            format!(", {} control messages it did not send", s.foreign_control)
        } else {
            String::new()
        }
    );
}

fn cell_table(out: &mut String, s: &StatusReport) {
    let _ = writeln!(
        out,
        "{:<8} {:<5} {:>7} {:>10} {:>8} {:>7} {:>8} {:>13}",
        "cell", "state", "since", "last fired", "fired", "missed", "skipped", "sync err us"
    );
    for c in s.cells.iter().map(CellJson::from) {
        let _ = writeln!(
            out,
            "{:<8} {:<5} {:>7} {:>10} {:>8} {:>7} {:>8} {:>13}",
            c.id,
            c.state,
            c.state_since_cycle,
            c.last_cycle_fired,
            c.cycles_fired,
            c.cycles_missed,
            c.slots_skipped,
            us(c.sync_error_us)
        );
        if !c.device.is_empty() {
            let _ = writeln!(out, "         device: {}", c.device);
        }
    }
    if s.cells.iter().any(|c| c.state == CellState::Idle) {
        let _ = writeln!(
            out,
            "idle: alive, and the last cycle did not ask it to fire (no robot near it); \
             missed counts only cycles a cell was due in"
        );
    }
}

fn robot_table(out: &mut String, s: &StatusReport) {
    if s.robots.is_empty() {
        let _ = writeln!(out, "no robot seen");
        return;
    }
    let _ = writeln!(
        out,
        "{:<8} {:<5} {:>7} {:>9} {:<12} {:>8} {:>8} {:>9}",
        "robot", "state", "fix/s", "over rate", "estimator", "x m", "y m", "theta deg"
    );
    for r in &s.robots {
        let (x, y, th) = if r.pose_valid {
            (
                format!("{:.3}", r.x_m),
                format!("{:.3}", r.y_m),
                format!("{:.1}", r.theta_rad.to_degrees()),
            )
        } else {
            ("-".into(), "-".into(), "-".into())
        };
        let _ = writeln!(
            out,
            "{:<8} {:<5} {:>7.1} {:>9} {:<12} {:>8} {:>8} {:>9}",
            r.id,
            match (r.up, r.stale.is_empty()) {
                (false, _) => "down",
                (true, true) => "up",
                (true, false) => "stale",
            },
            r.fixes_per_s,
            r.fixes_over_rate,
            if r.estimator.is_empty() {
                "-"
            } else {
                &r.estimator
            },
            x,
            y,
            th
        );
        if !r.stale.is_empty() {
            let _ = writeln!(out, "         stale: {}", r.stale);
        }
        if !r.receivers.is_empty() {
            let _ = writeln!(out, "         receivers: {}", r.receivers);
        }
    }
}

/// `status`: everything in one view.
pub fn status(s: &StatusReport, json: bool) -> anyhow::Result<String> {
    if json {
        return to_json(&status_json(s, true, true));
    }
    let mut out = String::new();
    header(&mut out, s);
    cell_table(&mut out, s);
    robot_table(&mut out, s);
    Ok(out)
}

/// `cells`.
pub fn cells(s: &StatusReport, json: bool) -> anyhow::Result<String> {
    if json {
        return to_json(&status_json(s, true, false));
    }
    let mut out = String::new();
    header(&mut out, s);
    cell_table(&mut out, s);
    Ok(out)
}

/// `robots`.
pub fn robots(s: &StatusReport, json: bool) -> anyhow::Result<String> {
    if json {
        return to_json(&status_json(s, false, true));
    }
    let mut out = String::new();
    header(&mut out, s);
    robot_table(&mut out, s);
    Ok(out)
}

/// `sync`: the cells' clock estimates and their residual error against truth.
pub fn sync(s: &StatusReport, json: bool) -> anyhow::Result<String> {
    if json {
        return to_json(&status_json(s, true, false));
    }
    let mut out = String::new();
    header(&mut out, s);
    let _ = writeln!(
        out,
        "{:<8} {:<5} {:>12} {:>10} {:>9} {:>13} {:>13} {:>8}",
        "cell", "state", "offset us", "drift ppm", "sigma us", "err max us", "err rms us", "bursts"
    );
    for c in s.cells.iter().map(CellJson::from) {
        let _ = writeln!(
            out,
            "{:<8} {:<5} {:>12.1} {:>10.2} {:>9.1} {:>13} {:>13} {:>8}",
            c.id,
            c.state,
            c.offset_us,
            c.drift_ppm,
            c.sync_sigma_us,
            us(c.sync_error_us),
            us(c.sync_error_rms_us),
            c.residual_samples
        );
    }
    let _ = writeln!(
        out,
        "err: actual minus scheduled emission time of the recent bursts (against the true time base in a simulation)"
    );
    Ok(out)
}

/// `schedule`.
pub fn schedule(s: &Schedule, json: bool) -> anyhow::Result<String> {
    let ms = |d: ickon_proto::time::Duration| d.as_secs_f64() * 1e3;
    let rate = ickon_central::update_rate_hz(s);
    if json {
        return to_json(&ScheduleJson::from(s));
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "schedule v{} from cycle {}: period {:.1} ms ({rate:.2} cycles/s), slot {:.1} ms, cells {}",
        s.version,
        s.effective_cycle,
        ms(s.cycle_period),
        ms(s.slot_length),
        s.active_cells.join(", ")
    );
    let _ = writeln!(
        out,
        "{:>4} {:>10} {:>6} {:<8}",
        "slot", "offset ms", "tx", "cell"
    );
    for e in &s.emissions {
        let _ = writeln!(
            out,
            "{:>4} {:>10.1} {:>6} {:<8}",
            e.slot,
            ms(e.offset),
            e.tx_id,
            e.cell_id
        );
    }
    Ok(out)
}

/// `pause`, `resume`, `reload`.
pub fn ack(a: &AdminAck, json: bool) -> anyhow::Result<String> {
    if json {
        return to_json(a);
    }
    Ok(a.messages.iter().map(|m| format!("  {m}\n")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::admin::{CellHealth, RobotHealth};
    use ickon_proto::time::Time;

    fn report() -> StatusReport {
        let cell = |id: &str, state: CellState, samples: u32| CellHealth {
            id: id.into(),
            state,
            state_since_cycle: if state == CellState::Down { 12 } else { 0 },
            sync_sigma_ns: 4_000,
            offset_ns: -50_000_000,
            drift_ppb: 100_000,
            residual_samples: samples,
            residual_max_ns: 61_500,
            residual_rms_ns: 20_000,
            last_cycle_fired: 11,
            cycles_fired: 11,
            cycles_missed: 0,
            slots_skipped: 0,
            inputs_refused: 0,
            device: "transmitter board on tcp:10.0.0.7:4000: link up, ready".into(),
        };
        StatusReport {
            site: "lab".into(),
            cycle: 13,
            stamp: Time(0),
            paused: false,
            schedule_version: 2,
            update_rate_hz: 3.4,
            cells: vec![
                cell("c1", CellState::Up, 64),
                cell("c2", CellState::Down, 0),
                cell("c3", CellState::Idle, 64),
            ],
            robots: vec![RobotHealth {
                id: "r1".into(),
                up: true,
                fixes_per_s: 3.5,
                estimator: "ickon-akf".into(),
                pose_valid: true,
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: 0.5,
                stale: String::new(),
                fixes_over_rate: 0,
                receivers: String::new(),
            }],
            epoch: 1,
            foreign_control: 0,
            active: true,
        }
    }

    #[test]
    fn status_json_has_the_documented_shape() {
        let v: serde_json::Value = serde_json::from_str(&status(&report(), true).unwrap()).unwrap();
        assert_eq!(v["site"], "lab");
        assert_eq!(v["cycle"], 13);
        let c = &v["cells"][0];
        assert_eq!(c["id"], "c1");
        assert_eq!(c["state"], "up");
        assert_eq!(c["sync_error_us"], 61.5);
        assert_eq!(c["cycles_fired"], 11);
        assert_eq!(
            c["device"],
            "transmitter board on tcp:10.0.0.7:4000: link up, ready"
        );
        assert_eq!(v["cells"][1]["state"], "down");
        assert_eq!(v["cells"][1]["state_since_cycle"], 12);
        assert_eq!(v["cells"][2]["state"], "idle");
        assert!(
            v["cells"][1]["sync_error_us"].is_null(),
            "no burst: unknown, not 0"
        );
        let r = &v["robots"][0];
        assert_eq!(
            (r["id"].as_str(), r["state"].as_str()),
            (Some("r1"), Some("up"))
        );
        assert_eq!(r["fixes_per_s"], 3.5);
        assert_eq!(r["pose"]["x_m"], 1.0);
    }

    #[test]
    fn cells_and_robots_views_show_only_their_part() {
        let cells: serde_json::Value =
            serde_json::from_str(&cells(&report(), true).unwrap()).unwrap();
        assert!(cells.get("robots").is_none() && cells["cells"].is_array());
        let robots: serde_json::Value =
            serde_json::from_str(&robots(&report(), true).unwrap()).unwrap();
        assert!(robots.get("cells").is_none() && robots["robots"].is_array());
        let table = status(&report(), false).unwrap();
        assert!(table.contains("c2       down"), "{table}");
        assert!(table.contains("c3       idle"), "{table}");
        assert!(table.contains("idle: alive"), "{table}");
        assert!(table.contains("61.5"), "{table}");
        assert!(
            table.contains("device: transmitter board on tcp:10.0.0.7:4000: link up, ready"),
            "{table}"
        );
        assert!(sync(&report(), false).unwrap().contains("-50000.0"));
    }
}
