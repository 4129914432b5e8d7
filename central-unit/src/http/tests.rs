//! The router in-process (no socket): paths, errors, the token, and the
//! view's snapshot from forged and garbage inputs.

use std::sync::Arc;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use ickon_proto::msg::admin::{CellHealth, CellState, RobotHealth, StatusReport};
use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::{Fix, FixQuality, RobotPose, Truth};
use ickon_proto::time::Time;
use tower::ServiceExt;

use super::view::{Ellipse, LiveView};
use super::*;

fn site() -> Site {
    Site::load_or_default(None).expect("built-in site").0
}

/// A session of its own (no peers: admin queries go unanswered).
async fn lone_session() -> Session {
    let mut config = zenoh::Config::default();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .expect("config");
    config
        .insert_json5("listen/endpoints", "[]")
        .expect("config");
    zenoh::open(config).await.expect("session")
}

fn report(site: &Site) -> StatusReport {
    StatusReport {
        site: site.name.clone(),
        cycle: 12,
        stamp: Time(0),
        paused: false,
        schedule_version: 1,
        update_rate_hz: 2.6,
        cells: site
            .cells
            .iter()
            .map(|c| CellHealth {
                id: c.id.clone(),
                state: if c.id == "c2" {
                    CellState::Down
                } else {
                    CellState::Up
                },
                state_since_cycle: 0,
                sync_sigma_ns: 0,
                offset_ns: 0,
                drift_ppb: 0,
                residual_samples: 0,
                residual_max_ns: 0,
                residual_rms_ns: 0,
                last_cycle_fired: 11,
                cycles_fired: 11,
                cycles_missed: 0,
                slots_skipped: 0,
                inputs_refused: 0,
                device: String::new(),
            })
            .collect(),
        robots: vec![RobotHealth {
            id: site.robots[0].id.clone(),
            up: true,
            fixes_per_s: 2.5,
            estimator: "tdoa-ekf".into(),
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

async fn app(token: Option<&str>) -> (axum::Router, watch::Sender<Option<StatusReport>>) {
    let site = site();
    let (status_tx, status_rx) = watch::channel(None);
    let (_latest_tx, latest_rx) = watch::channel(None);
    let state = AppState {
        session: lone_session().await,
        keys: Keys::new(&site.name).expect("keys"),
        hub: Hub::default(),
        view: SharedView::new(LiveView::new(&site)),
        status: status_rx,
        latest: latest_rx,
        token: token.map(Arc::from),
    };
    (routes::router(state), status_tx)
}

async fn call(app: &axum::Router, req: Request<Body>) -> (StatusCode, String) {
    let resp = app.clone().oneshot(req).await.expect("infallible");
    let status = resp.status();
    let body = axum::body::to_bytes(resp.into_body(), 1 << 20)
        .await
        .expect("body");
    (status, String::from_utf8_lossy(&body).into_owned())
}

fn get(path: &str) -> Request<Body> {
    Request::get(path).body(Body::empty()).expect("request")
}

fn post(path: &str, token: Option<&str>, body: &str) -> Request<Body> {
    let mut b = Request::post(path).header("content-type", "application/json");
    if let Some(t) = token {
        b = b.header("authorization", format!("Bearer {t}"));
    }
    b.body(Body::from(body.to_string())).expect("request")
}

#[tokio::test(flavor = "multi_thread")]
async fn the_page_and_its_assets_are_served_from_the_binary() {
    let (app, _) = app(None).await;
    let (code, html) = call(&app, get("/")).await;
    assert_eq!(code, StatusCode::OK);
    assert!(
        html.contains("app.js") && html.contains("style.css"),
        "{html}"
    );
    assert!(
        !html.contains("http://") && !html.contains("https://"),
        "nothing from elsewhere"
    );
    for path in ["/app.js", "/style.css"] {
        let (code, body) = call(&app, get(path)).await;
        assert_eq!(code, StatusCode::OK);
        assert!(body.len() > 200, "{path}");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn unknown_paths_are_404_with_a_json_reason() {
    let (app, _) = app(None).await;
    for path in ["/nope", "/api/nope", "/api/status/extra", "/%00%ff"] {
        let (code, body) = call(&app, get(path)).await;
        assert_eq!(code, StatusCode::NOT_FOUND, "{path}");
        let v: serde_json::Value = serde_json::from_str(&body).expect("json");
        assert!(
            v["error"]
                .as_str()
                .is_some_and(|e| e.contains("no such path"))
        );
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn status_mirrors_the_admin_json_and_is_503_before_the_first() {
    let (app, status_tx) = app(None).await;
    assert_eq!(
        call(&app, get("/api/status")).await.0,
        StatusCode::SERVICE_UNAVAILABLE
    );
    status_tx.send_replace(Some(report(&site())));
    let (code, body) = call(&app, get("/api/status")).await;
    assert_eq!(code, StatusCode::OK);
    let v: serde_json::Value = serde_json::from_str(&body).expect("json");
    assert_eq!(v["cycle"], 12);
    assert_eq!(v["cells"][1]["state"], "down");
    assert_eq!(v["robots"][0]["state"], "up");
    let cells: serde_json::Value =
        serde_json::from_str(&call(&app, get("/api/cells")).await.1).expect("json");
    assert!(cells.get("robots").is_none() && cells["cells"].is_array());
    let robots: serde_json::Value =
        serde_json::from_str(&call(&app, get("/api/robots")).await.1).expect("json");
    assert!(robots.get("cells").is_none() && robots["robots"].is_array());
    let (code, body) = call(&app, get("/api/robots?page=0&page_size=1&near=1,1")).await;
    assert_eq!(code, StatusCode::OK, "{body}");
    let page: serde_json::Value = serde_json::from_str(&body).expect("json");
    assert_eq!(page["page"], 0);
    assert_eq!(page["robots"].as_array().map(Vec::len), Some(1));
    for q in ["page=1000000000", "page=-1", "state=lost", "near=x"] {
        let (code, body) = call(&app, get(&format!("/api/robots?{q}"))).await;
        assert_eq!(code, StatusCode::BAD_REQUEST, "{q}: {body}");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn bad_queries_and_bodies_are_400() {
    let (app, _) = app(Some("s3cret")).await;
    for q in [
        "resolution_m=abc",
        "resolution_m=0",
        "resolution_m=NaN",
        "resolution_m=1e300",
    ] {
        let (code, _) = call(&app, get(&format!("/api/coverage?{q}"))).await;
        assert_eq!(code, StatusCode::BAD_REQUEST, "{q}");
    }
    for body in ["", "{", "[1,2]", "{\"file_name\": 3}", &"x".repeat(100_000)] {
        let (code, _) = call(&app, post("/api/reload", Some("s3cret"), body)).await;
        assert_eq!(
            code,
            StatusCode::BAD_REQUEST,
            "{}",
            &body[..body.len().min(20)]
        );
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn control_needs_the_token_given_at_start() {
    let (read_only, _) = app(None).await;
    assert_eq!(
        call(&read_only, post("/api/pause", Some("x"), "")).await.0,
        StatusCode::FORBIDDEN
    );
    let (app, _) = app(Some("s3cret")).await;
    for token in [None, Some("wrong"), Some("s3cre"), Some("s3cret2")] {
        for path in ["/api/pause", "/api/resume", "/api/reload"] {
            assert_eq!(
                call(&app, post(path, token, "{}")).await.0,
                StatusCode::UNAUTHORIZED,
                "{path} {token:?}"
            );
        }
    }
    // The right token gets through to the central unit, which is absent here.
    assert_eq!(
        call(&app, post("/api/pause", Some("s3cret"), "")).await.0,
        StatusCode::SERVICE_UNAVAILABLE
    );
    // Control is POST only.
    assert_eq!(
        call(&app, get("/api/pause")).await.0,
        StatusCode::METHOD_NOT_ALLOWED
    );
}

#[test]
fn token_files_must_hold_a_token() {
    let dir = std::env::temp_dir().join(format!("ickon-token-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let file = dir.join("t");
    std::fs::write(&file, "  abc\n").expect("write");
    assert_eq!(read_token(&file).expect("token"), "abc");
    std::fs::write(&file, " \n").expect("write");
    assert!(matches!(read_token(&file), Err(HttpError::Token { .. })));
    std::fs::write(&file, "x".repeat(5000)).expect("write");
    assert!(matches!(read_token(&file), Err(HttpError::Token { .. })));
    assert!(read_token(&dir.join("missing")).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

fn pose(x_m: f64, stamp_ns: i64) -> RobotPose {
    RobotPose {
        stamp: Time(stamp_ns),
        x_m,
        y_m: 2.0,
        theta_rad: 0.1,
        covariance: [0.0; 9],
        estimator: "tdoa-ekf".into(),
        fix_seq: 0,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    }
}

#[test]
fn the_snapshot_compares_a_pose_with_the_truth_at_its_own_time() {
    let site = site();
    let id = site.robots[0].id.clone();
    let mut v = LiveView::new(&site);
    for k in 0..10 {
        v.on_truth(
            &id,
            Truth {
                stamp: Time(k * 10_000_000),
                robot_clock: Time(5_000_000_000 + k * 10_000_000),
                x_m: 1.0 + 0.01 * k as f64,
                y_m: 2.0,
                theta_rad: 0.0,
                v_m_s: 1.0,
                omega_rad_s: 0.0,
            },
        );
    }
    // The pose is of the time of the 4th truth sample and 3 mm off it.
    v.on_pose(&id, pose(1.033, 5_030_000_000), Time(1_000_000_000));
    let s = v.snapshot(&report(&site), Time(1_250_000_000), 2, 1);
    let r = &s.robots[0];
    assert_eq!(r.err_mm, Some(3.0));
    assert_eq!(r.staleness_ms, Some(250.0));
    assert_eq!(r.trail.len(), 1);
    assert_eq!((s.clients, s.clients_dropped), (2, 1));
    let text = serde_json::to_string(&s).expect("json");
    assert!(
        text.contains("\"fixes_per_s\":2.5"),
        "the admin fields are flattened in"
    );
}

#[test]
fn forged_and_broken_messages_are_counted_not_kept() {
    let site = site();
    let id = site.robots[0].id.clone();
    let mut v = LiveView::new(&site);
    v.on_pose("intruder", pose(1.0, 0), Time(0));
    v.on_pose(&id, pose(f64::NAN, 0), Time(0));
    v.on_pose(&id, pose(f64::INFINITY, i64::MIN), Time(0));
    v.on_burst(
        &Burst {
            cell_id: "nowhere".into(),
            tx_id: 1,
            cycle: u64::MAX,
            scheduled: Time(i64::MAX),
            actual: Time(i64::MIN),
            epoch: u64::MAX,
        },
        Time(0),
    );
    let fix = Fix {
        stamp: Time(i64::MAX),
        arrivals_seq: 0,
        x_m: 1.0,
        y_m: 1.0,
        z_m: 0.0,
        covariance: [f64::NAN; 9],
        heading_rad: 0.0,
        heading_valid: false,
        used: vec![],
        rejected: vec![],
        residuals_m: vec![],
        quality: FixQuality::Suspect,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    };
    v.on_fix(&id, fix, Time(0));
    // A forged far-future pose still compares without overflow.
    v.on_truth(
        &id,
        Truth {
            stamp: Time(i64::MIN),
            robot_clock: Time(i64::MIN),
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            v_m_s: 0.0,
            omega_rad_s: 0.0,
        },
    );
    v.on_pose(&id, pose(1.0, i64::MAX), Time(0));
    let s = v.snapshot(&report(&site), Time(0), 0, 0);
    assert_eq!(s.ignored_messages, 4);
    let r = &s.robots[0];
    assert!(r.fix.as_ref().is_some_and(|f| f.ellipse.is_none()));
    assert_eq!(r.err_mm, None);
    assert_eq!(r.trail.len(), 1);
}

#[test]
fn the_two_sigma_ellipse_follows_the_covariance() {
    let e = Ellipse::two_sigma(0.04, 0.0, 0.01).expect("ellipse");
    assert!((e.a_m - 0.4).abs() < 1e-12 && (e.b_m - 0.2).abs() < 1e-12);
    assert!(e.angle_rad.abs() < 1e-12);
    let rotated = Ellipse::two_sigma(0.025, 0.015, 0.025).expect("ellipse");
    assert!((rotated.angle_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
    assert!((rotated.a_m - 0.4).abs() < 1e-12 && (rotated.b_m - 0.2).abs() < 1e-12);
    assert!(Ellipse::two_sigma(-1.0, 0.0, 1.0).is_none());
    assert!(
        Ellipse::two_sigma(1.0, 5.0, 1.0).is_none(),
        "not positive semi-definite"
    );
}
