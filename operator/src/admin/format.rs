//! What `ickon admin` prints: readable tables, or one JSON document.
//!
//! The JSON documents are [`ickon_central::admin_json`]'s, which the web
//! map's `/api/*` endpoints serve too.

use std::fmt::Write;

use ickon_central::admin_json::{
    CellJson, RobotPageJson, ScheduleJson, StatusJson, TransmittersJson,
};
use ickon_proto::msg::admin::{
    AdminAck, CellState, RobotHealth, RobotPage, StatusReport, TransmittersReport,
};
use ickon_proto::msg::control::Schedule;
use serde::Serialize;

fn status_json(s: &StatusReport, cells: bool, robots: bool) -> StatusJson {
    StatusJson::new(s, cells, robots)
}

/// Why an answer could not be printed: it does not serialise as JSON.
#[derive(Debug, thiserror::Error)]
#[error("cannot write the answer as JSON: {0}")]
pub struct FormatError(#[from] serde_json::Error);

pub(super) fn to_json<T: Serialize>(value: &T) -> Result<String, FormatError> {
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
    let _ = writeln!(out, "{}", air_line(s));
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

fn robot_table(out: &mut String, robots: &[RobotHealth]) {
    if robots.is_empty() {
        let _ = writeln!(out, "no robot seen");
        return;
    }
    let _ = writeln!(
        out,
        "{:<8} {:<5} {:>7} {:>9} {:<11} {:<12} {:>8} {:>8} {:>9}",
        "robot", "state", "fix/s", "over rate", "survey", "estimator", "x m", "y m", "theta deg"
    );
    for r in robots {
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
            "{:<8} {:<5} {:>7.1} {:>9} {:<11} {:<12} {:>8} {:>8} {:>9}",
            r.id,
            r.state(),
            r.fixes_per_s,
            r.fixes_over_rate,
            survey_word(&r.survey_check),
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
        if let Some(line) = survey_line(r) {
            let _ = writeln!(out, "         survey: {line}");
        }
        if !r.receivers.is_empty() {
            let _ = writeln!(out, "         receivers: {}", r.receivers);
        }
        if r.summaries_dropped > 0 {
            let _ = writeln!(
                out,
                "         summaries dropped: {} (floods, repeats, stamps from the future, another sender under its id)",
                r.summaries_dropped
            );
        }
    }
}

/// The fleet check's standing in one word, for the robot table.
fn survey_word(check: &str) -> &str {
    match check {
        "" => "-",
        c => c.split(':').next().unwrap_or(c),
    }
}

/// What the fleet's check says of a robot that is not simply agreeing,
/// in words: why it is unchecked, or how far a quarantined robot is from
/// being let in again.
fn survey_line(r: &RobotHealth) -> Option<String> {
    let mm = |m: f64| format!("{:.1} mm", m * 1000.0);
    if r.survey_check == "quarantined" {
        let measured = if r.survey_misfit_m >= 0.0 && r.survey_bound_m >= 0.0 {
            format!(
                "misfit {} against the fleet's calibration, released within {}; ",
                mm(r.survey_misfit_m),
                mm(r.survey_bound_m)
            )
        } else {
            String::new()
        };
        return Some(format!(
            "quarantined: {measured}{} fixes kept out of the calibration",
            r.fixes_quarantined
        ));
    }
    if r.survey_check.starts_with("unchecked") {
        return Some(r.survey_check.clone());
    }
    (r.fixes_quarantined > 0).then(|| {
        format!(
            "{}; {} fixes kept out of the calibration while it was quarantined",
            r.survey_check, r.fixes_quarantined
        )
    })
}

/// The speed of sound the robots solve with, and the transmitters left out.
fn air_line(s: &StatusReport) -> String {
    let speed = if s.speed_of_sound_m_s > 0.0 {
        format!(
            "speed of sound {:.2} +- {:.2} m/s learnt from the fleet's fixes (site file {:.2})",
            s.speed_of_sound_m_s, s.speed_of_sound_sigma_m_s, s.site_speed_of_sound_m_s
        )
    } else {
        format!(
            "speed of sound {:.2} m/s from the site file (none learnt)",
            s.site_speed_of_sound_m_s
        )
    };
    if s.transmitters_left_out.is_empty() {
        speed
    } else {
        let ids: Vec<String> = s.transmitters_left_out.iter().map(u32::to_string).collect();
        format!(
            "{speed}; transmitters left out: {} (ickon admin transmitters)",
            ids.join(", ")
        )
    }
}

/// `transmitters`: every transmitter's health and the air.
pub fn transmitters(r: &TransmittersReport, json: bool) -> Result<String, FormatError> {
    let doc = TransmittersJson::from(r);
    if json {
        return to_json(&doc);
    }
    let mut out = String::new();
    if !doc.learning {
        let _ = writeln!(
            out,
            "site {}: the central unit learns nothing from the fleet's fixes (--no-survey-calibration): no transmitter is judged",
            doc.site
        );
        return Ok(out);
    }
    let _ = writeln!(
        out,
        "site {}: speed of sound {:.2}{} m/s ({}), {} fixes learnt from",
        doc.site,
        doc.speed_of_sound_m_s,
        doc.speed_of_sound_sigma_m_s
            .map_or(String::new(), |s| format!(" +- {s:.2}")),
        if doc.speed_of_sound_learnt {
            format!("learnt; site file {:.2}", doc.site_speed_of_sound_m_s)
        } else {
            "the site file's".to_string()
        },
        doc.fixes_taken
    );
    let _ = writeln!(
        out,
        "{:>5} {:<8} {:<9} {:>6} {:>7} {:>8} {:>7} {:>9} {:>8} {:>10}",
        "tx",
        "cell",
        "condition",
        "due",
        "heard",
        "others",
        "reject",
        "resid mm",
        "std mm",
        "last heard"
    );
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0}%"));
    let mm = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    for t in &doc.transmitters {
        let _ = writeln!(
            out,
            "{:>5} {:<8} {:<9} {:>6.1} {:>7} {:>8} {:>7} {:>9} {:>8} {:>10}",
            t.id,
            t.cell,
            if t.left_out {
                format!("{}*", t.condition)
            } else {
                t.condition.clone()
            },
            t.due,
            pct(t.heard_pct),
            pct(t.expected_pct),
            pct(t.rejected_pct),
            mm(t.residual_mean_mm),
            mm(t.residual_std_mm),
            t.last_heard_s_ago
                .map_or("never".to_string(), |s| format!("{s:.1} s ago"))
        );
    }
    for t in doc.transmitters.iter().filter(|t| t.left_out) {
        let _ = writeln!(out, "tx {} {}: {}", t.id, t.condition, t.evidence);
    }
    let _ = writeln!(
        out,
        "*: left out of the robots' fixes. due: recent fixes within 6 m of it; heard: share of them that heard it; others: share that heard its cell's other transmitters"
    );
    air_sensor_table(&mut out, &doc);
    Ok(out)
}

/// The cell boards' air temperature sensors under the transmitters (only
/// when a board has reported).
fn air_sensor_table(out: &mut String, doc: &TransmittersJson) {
    if doc.air_sensors.iter().all(|b| b.state == "no sensor") {
        return;
    }
    let _ = writeln!(
        out,
        "air at the cells' boards{}:",
        doc.air_sensor_speed_m_s.map_or(String::new(), |v| format!(
            " (speed of sound {v:.2} m/s by their median)"
        ))
    );
    let _ = writeln!(
        out,
        "{:<8} {:<9} {:>8} {:>10} {:>8} {:>5} {:>6} {:>6} {:>5}",
        "cell", "sensor", "temp C", "reading", "accepted", "nan", "range", "stuck", "jump"
    );
    for b in &doc.air_sensors {
        let r = b.refused;
        let _ = writeln!(
            out,
            "{:<8} {:<9} {:>8} {:>10} {:>8} {:>5} {:>6} {:>6} {:>5}",
            b.cell,
            b.state,
            b.temperature_c
                .map_or("-".to_string(), |t| format!("{t:.2}")),
            b.accepted_s_ago
                .map_or("never".to_string(), |s| format!("{s:.1} s ago")),
            b.accepted,
            r.not_a_number,
            r.out_of_range,
            r.stuck,
            r.jump
        );
    }
    if doc.air_sensors.iter().any(|b| b.refused_any()) {
        let _ = writeln!(
            out,
            "refused readings: not a number, outside -40..85 C, stuck at one value, jumping more than 20 C in a second; never used"
        );
    }
}

/// `status`: everything in one view.
pub fn status(s: &StatusReport, json: bool) -> Result<String, FormatError> {
    if json {
        return to_json(&status_json(s, true, true));
    }
    let mut out = String::new();
    header(&mut out, s);
    cell_table(&mut out, s);
    fleet_summary(&mut out, s);
    Ok(out)
}

/// Robots `status` lists: the worst of the fleet (down, then stale, then
/// the fewest fixes a second).
pub const WORST_ROBOTS: usize = 10;

/// The fleet in a few lines: its counts by state and its worst robots.
fn fleet_summary(out: &mut String, s: &StatusReport) {
    let (robots, counts) = (&s.robots, s.robot_counts);
    let _ = writeln!(
        out,
        "robots: {} up, {} stale, {} down",
        counts.up, counts.stale, counts.down
    );
    let rank = |r: &RobotHealth| match r.state() {
        "down" => 0,
        "stale" => 1,
        _ => 2,
    };
    let mut worst: Vec<&RobotHealth> = robots.iter().collect();
    worst.sort_by(|a, b| {
        rank(a)
            .cmp(&rank(b))
            .then(a.fixes_per_s.total_cmp(&b.fixes_per_s))
            .then_with(|| a.id.cmp(&b.id))
    });
    let shown: Vec<RobotHealth> = worst.into_iter().take(WORST_ROBOTS).cloned().collect();
    robot_table(out, &shown);
    let total = counts.up + counts.stale + counts.down;
    if total > shown.len() as u64 {
        let _ = writeln!(
            out,
            "{} more: `ickon admin robots --page N` (or --state, --near X,Y)",
            total - shown.len() as u64
        );
    }
}

/// `cells`.
pub fn cells(s: &StatusReport, json: bool) -> Result<String, FormatError> {
    if json {
        return to_json(&status_json(s, true, false));
    }
    let mut out = String::new();
    header(&mut out, s);
    cell_table(&mut out, s);
    Ok(out)
}

/// `robots`: one page.
pub fn robot_page(p: &RobotPage, json: bool) -> Result<String, FormatError> {
    if json {
        return to_json(&RobotPageJson::from(p));
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "robots: {} up, {} stale, {} down; page {} of {} ({} matching)",
        p.counts.up, p.counts.stale, p.counts.down, p.page, p.pages, p.matching
    );
    robot_table(&mut out, &p.robots);
    Ok(out)
}

/// `sync`: the cells' clock estimates and their residual error against truth.
pub fn sync(s: &StatusReport, json: bool) -> Result<String, FormatError> {
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
pub fn schedule(s: &Schedule, json: bool) -> Result<String, FormatError> {
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
pub fn ack(a: &AdminAck, json: bool) -> Result<String, FormatError> {
    if json {
        return to_json(a);
    }
    Ok(a.messages.iter().map(|m| format!("  {m}\n")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::admin::CellHealth;
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
                survey_check: String::new(),
                fixes_quarantined: 0,
                survey_misfit_m: -1.0,
                survey_bound_m: -1.0,
                receivers: String::new(),
                summaries_dropped: 0,
            }],
            epoch: 1,
            foreign_control: 0,
            active: true,
            survey_publications: 0,
            survey_publish_mean_us: 0.0,
            survey_publish_max_us: 0.0,
            speed_of_sound_m_s: 345.1,
            speed_of_sound_sigma_m_s: 0.25,
            site_speed_of_sound_m_s: 343.21,
            transmitters_left_out: vec![12],
            robot_counts: ickon_proto::msg::admin::RobotCounts {
                up: 1,
                stale: 0,
                down: 0,
            },
            robots_posed: 1,
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
        let page = RobotPage {
            error: String::new(),
            page: 0,
            pages: 1,
            matching: 1,
            counts: ickon_proto::msg::admin::RobotCounts {
                up: 1,
                stale: 0,
                down: 0,
            },
            robots: report().robots,
        };
        let robots: serde_json::Value =
            serde_json::from_str(&robot_page(&page, true).unwrap()).unwrap();
        assert!(robots.get("cells").is_none() && robots["robots"].is_array());
        assert_eq!(
            (robots["pages"].as_u64(), robots["counts"]["up"].as_u64()),
            (Some(1), Some(1))
        );
        let text = robot_page(&page, false).unwrap();
        assert!(
            text.starts_with("robots: 1 up, 0 stale, 0 down; page 0 of 1"),
            "{text}"
        );
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

    #[test]
    fn status_summarises_a_large_fleet_by_state_and_its_worst_robots() {
        let mut report = report();
        let honest = report.robots[0].clone();
        report.robots = (0..500)
            .map(|k| RobotHealth {
                id: format!("r{k}"),
                up: k != 77,
                stale: if k == 300 {
                    "no pose for 2.0 s".into()
                } else {
                    String::new()
                },
                fixes_per_s: if k == 5 { 0.5 } else { 3.0 },
                ..honest.clone()
            })
            .collect();
        report.robot_counts = ickon_proto::msg::admin::RobotCounts {
            up: 498,
            stale: 1,
            down: 1,
        };
        let table = status(&report, false).unwrap();
        assert!(table.contains("robots: 498 up, 1 stale, 1 down"), "{table}");
        // The worst first: down, stale, then the fewest fixes.
        let listed: Vec<&str> = table
            .lines()
            .filter(|l| l.starts_with('r') && !l.starts_with("robot"))
            .map(|l| l.split_whitespace().next().unwrap())
            .collect();
        assert_eq!(listed.len(), WORST_ROBOTS, "{table}");
        assert_eq!(&listed[..3], ["r77", "r300", "r5"], "{table}");
        assert!(
            table.contains("490 more: `ickon admin robots --page N`"),
            "{table}"
        );
    }

    #[test]
    fn the_fleet_check_shows_quarantine_and_the_fleet_of_one() {
        let mut report = report();
        let honest = report.robots[0].clone();
        report.robots = vec![
            RobotHealth {
                id: "r2".into(),
                survey_check: "quarantined".into(),
                fixes_quarantined: 57,
                survey_misfit_m: 0.1412,
                survey_bound_m: 0.0311,
                ..honest.clone()
            },
            RobotHealth {
                id: "r3".into(),
                survey_check: "unchecked: no other robot to compare".into(),
                ..honest.clone()
            },
            RobotHealth {
                survey_check: "agrees".into(),
                survey_misfit_m: 0.012,
                survey_bound_m: 0.05,
                ..honest
            },
        ];
        let table = status(&report, false).unwrap();
        assert!(
            table.contains("survey: quarantined: misfit 141.2 mm against the fleet's calibration, released within 31.1 mm; 57 fixes kept out"),
            "{table}"
        );
        assert!(
            table.contains("survey: unchecked: no other robot to compare"),
            "{table}"
        );
        assert_eq!(table.matches("survey:").count(), 2, "{table}");
        assert!(table.contains(" agrees "), "{table}");
        let v: serde_json::Value = serde_json::from_str(&status(&report, true).unwrap()).unwrap();
        let r2 = &v["robots"][0];
        assert_eq!(r2["survey_check"], "quarantined");
        assert_eq!(r2["fixes_quarantined"], 57);
        assert_eq!(r2["survey_misfit_mm"], 141.2);
        assert_eq!(r2["survey_bound_mm"], 31.1);
        assert_eq!(
            v["robots"][1]["survey_check"],
            "unchecked: no other robot to compare"
        );
        assert!(v["robots"][1]["survey_misfit_mm"].is_null());
    }

    #[test]
    fn the_transmitters_view_shows_each_boards_air_and_its_refusals() {
        use ickon_proto::msg::admin::BoardAirStatus;
        let board = |cell: &str, state: &str, t: f64, stuck: u64| BoardAirStatus {
            cell_id: cell.into(),
            state: state.into(),
            temperature_c: t,
            accepted_s_ago: if t.is_nan() { -1.0 } else { 0.5 },
            accepted: 12,
            refused_not_a_number: 1,
            refused_out_of_range: 0,
            refused_stuck: stuck,
            refused_jump: 2,
        };
        let r = TransmittersReport {
            site: "lab".into(),
            stamp: Time(0),
            learning: true,
            fixes_taken: 5,
            speed_of_sound_m_s: 345.1,
            speed_of_sound_sigma_m_s: 0.3,
            site_speed_of_sound_m_s: 343.2,
            transmitters: Vec::new(),
            air_sensors: vec![
                board("c1", "used", 24.31, 0),
                board("c2", "stuck", 22.0, 7),
                board("c3", "no sensor", f64::NAN, 0),
            ],
            air_sensor_speed_m_s: 345.6,
        };
        let text = transmitters(&r, false).unwrap();
        assert!(
            text.contains("speed of sound 345.60 m/s by their median"),
            "{text}"
        );
        let c2 = text.lines().find(|l| l.starts_with("c2 ")).unwrap();
        assert_eq!(
            c2.split_whitespace().collect::<Vec<_>>(),
            [
                "c2", "stuck", "22.00", "0.5", "s", "ago", "12", "1", "0", "7", "2"
            ]
        );
        assert!(text.contains("refused readings"));
        let json: serde_json::Value =
            serde_json::from_str(&transmitters(&r, true).unwrap()).unwrap();
        assert_eq!(json["air_sensors"][1]["refused"]["stuck"], 7);
        assert_eq!(
            json["air_sensors"][2]["temperature_c"],
            serde_json::Value::Null
        );
        // Boards without a sensor: no table at all.
        let none = TransmittersReport {
            air_sensors: vec![board("c3", "no sensor", f64::NAN, 0)],
            ..r
        };
        assert!(
            !transmitters(&none, false)
                .unwrap()
                .contains("air at the cells' boards")
        );
    }
}
