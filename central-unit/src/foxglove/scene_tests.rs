//! The scenes from a live view fed with forged messages: every cell, wall,
//! column and robot drawn, in the right state and place.

use ickon_proto::msg::admin::{CellHealth, CellState, RobotHealth, StatusReport};
use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::{PoseStatus, RobotPose, Truth};
use ickon_proto::site::Site;
use ickon_proto::time::Time;

use super::*;
use crate::http::view::LiveView;

fn site() -> Site {
    Site::load_or_default(None).expect("built-in site").0
}

fn report(site: &Site, down: &str) -> StatusReport {
    StatusReport {
        site: site.name.clone(),
        cycle: 40,
        stamp: Time(0),
        paused: false,
        schedule_version: 1,
        update_rate_hz: 10.0,
        cells: site
            .cells
            .iter()
            .map(|c| CellHealth {
                id: c.id.clone(),
                // The first transmitter's cell fired; the others were not due.
                state: if c.id == down {
                    CellState::Down
                } else if c.id == site.transmitters[0].cell {
                    CellState::Up
                } else {
                    CellState::Idle
                },
                state_since_cycle: 0,
                sync_sigma_ns: 0,
                offset_ns: 0,
                drift_ppb: 0,
                residual_samples: 0,
                residual_max_ns: 0,
                residual_rms_ns: 0,
                last_cycle_fired: 39,
                cycles_fired: 39,
                cycles_missed: 0,
                slots_skipped: 0,
                inputs_refused: 0,
                device: String::new(),
            })
            .collect(),
        robots: site
            .robots
            .iter()
            .map(|r| RobotHealth {
                id: r.id.clone(),
                up: true,
                fixes_per_s: 10.0,
                estimator: "tdoa-ekf".into(),
                pose_valid: true,
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: 0.0,
                stale: String::new(),
                fixes_over_rate: 0,
                survey_check: String::new(),
                fixes_quarantined: 0,
                survey_misfit_m: -1.0,
                survey_bound_m: -1.0,
                receivers: String::new(),
                summaries_dropped: 0,
            })
            .collect(),
        epoch: 1,
        foreign_control: 0,
        active: true,
        survey_publications: 3,
        survey_publish_mean_us: 410.0,
        survey_publish_max_us: 900.0,
        speed_of_sound_m_s: 345.1,
        speed_of_sound_sigma_m_s: 0.3,
        site_speed_of_sound_m_s: 343.2,
        transmitters_left_out: vec![],
        robot_counts: Default::default(),
        robots_posed: 0,
    }
}

fn pose(x_m: f64, y_m: f64, theta_rad: f64, status: PoseStatus) -> RobotPose {
    RobotPose {
        stamp: Time(1_000_000_000),
        x_m,
        y_m,
        theta_rad,
        covariance: [0.0004, 0.0, 0.0, 0.0, 0.0001, 0.0, 0.0, 0.0, 0.01],
        estimator: "tdoa-ekf".into(),
        fix_seq: 1,
        status,
    }
}

/// A view where the first robot tracks at (2, 3) with its truth 30 mm
/// away, the second is localising, and the first cell's transmitter fired
/// 20 ms ago.
fn snapshot(site: &Site, down: &str) -> Snapshot {
    let mut view = LiveView::new(site);
    let now = Time(10_000_000_000);
    let r1 = &site.robots[0].id;
    view.on_pose(r1, pose(2.0, 3.0, 0.5, PoseStatus::Tracking), now);
    view.on_truth(
        r1,
        Truth {
            stamp: Time(0),
            robot_clock: Time(1_000_000_000),
            x_m: 2.03,
            y_m: 3.0,
            theta_rad: 0.5,
            v_m_s: 0.0,
            omega_rad_s: 0.0,
        },
    );
    let r2 = &site.robots[1].id;
    view.on_pose(r2, pose(5.0, 1.0, 0.0, PoseStatus::Localising), now);
    let tx = &site.transmitters[0];
    view.on_burst(
        &Burst {
            cell_id: tx.cell.clone(),
            tx_id: tx.id,
            cycle: 40,
            scheduled: Time(0),
            actual: Time(0),
            epoch: 1,
        },
        Time(now.0 - 20_000_000),
    );
    view.snapshot(&report(site, down), now, 0, 0)
}

fn stamp() -> Timestamp {
    Timestamp::new(1, 0)
}

#[test]
fn the_site_scene_has_every_wall_and_column_and_routes_only_when_asked() {
    let site = site();
    let scene = site_scene(&site, false, stamp());
    let by_id = |s: &SceneUpdate, id: &str| s.entities.iter().find(|e| e.id == id).cloned();
    assert_eq!(
        by_id(&scene, "walls").unwrap().cubes.len(),
        site.walls.len()
    );
    let columns = by_id(&scene, "columns").unwrap();
    assert_eq!(columns.triangles.len(), site.columns.len());
    for (t, c) in columns.triangles.iter().zip(&site.columns) {
        // Two triangles per side, n - 2 on the top.
        let n = c.polygon.len();
        assert_eq!(t.points.len(), 3 * (2 * n + n - 2));
    }
    assert!(by_id(&scene, "routes").is_none());
    let with_routes = site_scene(&site, true, stamp());
    assert_eq!(
        by_id(&with_routes, "routes").unwrap().lines.len(),
        site.routes.len()
    );
    assert!(
        scene
            .entities
            .iter()
            .all(|e| e.frame_id == MAP_FRAME && e.lifetime.is_none())
    );
}

#[test]
fn every_cell_is_drawn_in_its_state_with_the_firing_transmitter_lit() {
    let site = site();
    let down = site.cells.last().unwrap().id.clone();
    let snap = snapshot(&site, &down);
    let scene = cells_scene(&site, &snap, stamp());
    assert_eq!(scene.entities.len(), site.cells.len());
    let fired = &site.transmitters[0];
    for (e, c) in scene.entities.iter().zip(&site.cells) {
        assert_eq!(e.id, format!("cell/{}", c.id));
        let state = &e.metadata[0].value;
        let want = if c.id == down {
            "down"
        } else if c.id == fired.cell {
            "up"
        } else {
            // No burst heard from it: up but quiet.
            "idle"
        };
        assert_eq!(state, want, "{}", c.id);
        assert_eq!(e.lines[0].points.len(), c.polygon.len());
        assert_eq!(e.lines[0].color, Some(cell_color(want)));
        let txs: Vec<_> = site
            .transmitters
            .iter()
            .filter(|t| t.cell == c.id)
            .collect();
        assert_eq!(e.spheres.len(), txs.len());
        for (s, t) in e.spheres.iter().zip(&txs) {
            let lit = t.id == fired.id;
            let size = s.size.as_ref().unwrap().x;
            assert_eq!(size > TX_SIZE_M, lit, "tx {}", t.id);
            let p = s.pose.as_ref().unwrap().position.as_ref().unwrap();
            assert_eq!([p.x, p.y, p.z], t.position_m);
        }
    }
}

#[test]
fn a_burst_older_than_a_cycle_is_not_firing() {
    let site = site();
    let snap = snapshot(&site, "");
    let cell = snap
        .cells
        .iter()
        .find(|c| c.health.id == site.transmitters[0].cell)
        .unwrap();
    assert!(fired_this_cycle(cell, 100.0));
    assert!(!fired_this_cycle(cell, 15.0));
    assert_eq!(cell_state(cell), "up");
    assert_eq!(cycle_period_ms(f64::NAN), 1e3);
    assert_eq!(cycle_period_ms(0.0), 1e3);
    assert_eq!(cycle_period_ms(4.0), 250.0);
}

#[test]
fn every_robot_with_a_pose_is_drawn_with_its_state_ellipse_and_truth() {
    let site = site();
    let snap = snapshot(&site, "");
    let scene = robots_scene(&snap, stamp());
    assert_eq!(scene.entities.len(), 2, "only robots with a pose");
    let r1 = &scene.entities[0];
    assert_eq!(r1.id, format!("robot/{}", site.robots[0].id));
    assert_eq!(r1.metadata[0].value, "tracking");
    // Fused arrow and the truth's.
    assert_eq!(r1.arrows.len(), 2);
    let p = r1.arrows[0].pose.as_ref().unwrap();
    let at = p.position.as_ref().unwrap();
    assert_eq!((at.x, at.y), (2.0, 3.0));
    let q = p.orientation.as_ref().unwrap();
    assert!((2.0 * q.z.atan2(q.w) - 0.5).abs() < 1e-12);
    // 2-sigma ellipse of a 20 mm x 10 mm one-sigma covariance.
    let ellipse = &r1.lines[0];
    let far = ellipse
        .points
        .iter()
        .map(|pt| (pt.x - 2.0).hypot(pt.y - 3.0))
        .fold(0.0, f64::max);
    assert!((far - 0.04).abs() < 1e-9, "{far}");
    assert_eq!(scene.entities[1].metadata[0].value, "localising");
    assert_eq!(snap.robots[0].err_mm, Some(30.0));
}
