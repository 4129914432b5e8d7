//! The HTTP routes: the page and its assets, the live stream (server-sent
//! events), and the JSON API that mirrors `ickon admin --json`.
//!
//! Status, cells and robots come from the status the node publishes; the
//! schedule, the coverage, the site and the control commands are asked of
//! the central unit over its own admin queryables, exactly as `ickon admin`
//! asks them, so that there is one path into the core for both.

use std::convert::Infallible;
use std::sync::Arc;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use futures_util::Stream;
use ickon_proto::keys::Keys;
use ickon_proto::msg::admin::{
    AdminAck, CoverageReport, CoverageRequest, DEFAULT_PAGE_SIZE, ReloadRequest, RobotsRequest,
    StatusReport, TransmittersReport,
};
use ickon_proto::msg::control::{Schedule, SiteInfo};
use ickon_proto::site::Site;
use ickon_proto::{decode, encode};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use tokio::sync::watch;
use zenoh::Session;

use super::fanout::Hub;
use super::feed::SharedView;
use super::site_view::SiteView;
use crate::admin_json::{CoverageJson, RobotPageJson, ScheduleJson, StatusJson, TransmittersJson};

/// How long the central unit gets to answer an admin query from a page.
const ADMIN_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(3);
/// Browsers reconnect this soon after the stream breaks (a restarted central unit).
const RECONNECT: std::time::Duration = std::time::Duration::from_millis(1_000);
/// Finest and coarsest coverage grid a page may ask for, metres.
const COVERAGE_RESOLUTION_M: std::ops::RangeInclusive<f64> = 0.05..=5.0;

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    /// The central unit's session (for admin queries to itself).
    pub session: Session,
    /// The site's keys.
    pub keys: Keys,
    /// Live-stream clients.
    pub hub: Hub,
    /// The map's view, told about a reloaded site.
    pub view: SharedView,
    /// The latest status the node published.
    pub status: watch::Receiver<Option<StatusReport>>,
    /// The latest snapshot, as sent.
    pub latest: watch::Receiver<Option<Arc<str>>>,
    /// The control token; `None`: read-only.
    pub token: Option<Arc<str>>,
}

/// Why a request failed, each with its HTTP status.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// No such page.
    #[error("no such path: {0}")]
    NotFound(String),
    /// The request is malformed.
    #[error("bad request: {0}")]
    BadRequest(String),
    /// Control needs the token, and this one is missing or wrong.
    #[error("control needs `Authorization: Bearer <token>` with the token given at start")]
    Unauthorized,
    /// No token was given at start: the server is read-only.
    #[error("read-only: the central unit was started without --http-token-file")]
    ReadOnly,
    /// The central unit did not answer, or has nothing yet.
    #[error("unavailable: {0}")]
    Unavailable(String),
}

#[derive(Serialize)]
struct ErrorJson {
    error: String,
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = match &self {
            ApiError::NotFound(_) => StatusCode::NOT_FOUND,
            ApiError::BadRequest(_) => StatusCode::BAD_REQUEST,
            ApiError::Unauthorized => StatusCode::UNAUTHORIZED,
            ApiError::ReadOnly => StatusCode::FORBIDDEN,
            ApiError::Unavailable(_) => StatusCode::SERVICE_UNAVAILABLE,
        };
        let body = axum::Json(ErrorJson {
            error: self.to_string(),
        });
        (status, body).into_response()
    }
}

/// The router of the web map.
pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/app.js", get(app_js))
        .route("/style.css", get(style_css))
        .route("/events", get(events))
        .route("/api/live", get(live))
        .route("/api/site", get(site))
        .route("/api/status", get(status))
        .route("/api/cells", get(cells))
        .route("/api/robots", get(robots))
        .route("/api/schedule", get(schedule))
        .route("/api/transmitters", get(transmitters))
        .route("/api/coverage", get(coverage))
        .route("/api/pause", post(pause))
        .route("/api/resume", post(resume))
        .route("/api/reload", post(reload))
        .fallback(|uri: axum::http::Uri| async move { ApiError::NotFound(uri.path().to_string()) })
        .with_state(state)
}

fn asset(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn index() -> Response {
    asset(
        "text/html; charset=utf-8",
        include_str!("assets/index.html"),
    )
}

async fn app_js() -> Response {
    asset(
        "text/javascript; charset=utf-8",
        include_str!("assets/app.js"),
    )
}

async fn style_css() -> Response {
    asset("text/css; charset=utf-8", include_str!("assets/style.css"))
}

/// The live stream: the newest snapshot at once, then every new one.
async fn events(
    State(st): State<AppState>,
) -> Result<Sse<impl Stream<Item = Result<SseEvent, Infallible>>>, ApiError> {
    let rx = st
        .hub
        .join()
        .ok_or_else(|| ApiError::Unavailable("too many live clients".into()))?;
    let first = st.latest.borrow().clone();
    let stream =
        futures_util::stream::unfold((true, first, rx), |(opening, first, mut rx)| async move {
            let data = match first {
                Some(f) => f,
                None => rx.recv().await?,
            };
            let mut event = SseEvent::default().data(&*data);
            if opening {
                event = event.retry(RECONNECT);
            }
            Some((Ok(event), (false, None, rx)))
        });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

fn json_text(text: Arc<str>) -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        text.to_string(),
    )
        .into_response()
}

async fn live(State(st): State<AppState>) -> Result<Response, ApiError> {
    let latest = st.latest.borrow().clone();
    latest
        .map(json_text)
        .ok_or_else(|| ApiError::Unavailable("no snapshot yet".into()))
}

fn latest_status(st: &AppState) -> Result<StatusReport, ApiError> {
    st.status
        .borrow()
        .clone()
        .ok_or_else(|| ApiError::Unavailable("no status yet".into()))
}

async fn status(State(st): State<AppState>) -> Result<axum::Json<StatusJson>, ApiError> {
    Ok(axum::Json(StatusJson::new(
        &latest_status(&st)?,
        true,
        true,
    )))
}

async fn cells(State(st): State<AppState>) -> Result<axum::Json<StatusJson>, ApiError> {
    Ok(axum::Json(StatusJson::new(
        &latest_status(&st)?,
        true,
        false,
    )))
}

/// The query of `/api/robots`: with any of it, a page of the robots.
#[derive(Debug, Deserialize)]
struct RobotsQuery {
    page: Option<i64>,
    page_size: Option<u32>,
    state: Option<String>,
    /// `X,Y` in metres.
    near: Option<String>,
}

/// `/api/robots`: every robot of the latest status, or with a query a
/// page of them (as `ickon admin robots --json`); a bad page is a 400.
async fn robots(
    State(st): State<AppState>,
    query: Result<Query<RobotsQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query.map_err(|e| ApiError::BadRequest(e.body_text()))?;
    let status = latest_status(&st)?;
    if q.page.is_none() && q.page_size.is_none() && q.state.is_none() && q.near.is_none() {
        return Ok(axum::Json(StatusJson::new(&status, false, true)).into_response());
    }
    let near = match q.near.as_deref() {
        Some(text) => Some(
            text.split_once(',')
                .and_then(|(x, y)| {
                    Some((x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?))
                })
                .ok_or_else(|| {
                    ApiError::BadRequest(format!("near {text:?} is not X,Y in metres"))
                })?,
        ),
        None => None,
    };
    let request = RobotsRequest {
        page: q.page.unwrap_or(0),
        page_size: q.page_size.unwrap_or(DEFAULT_PAGE_SIZE),
        state: q.state.unwrap_or_default(),
        near: near.is_some(),
        near_x_m: near.map_or(0.0, |n| n.0),
        near_y_m: near.map_or(0.0, |n| n.1),
    };
    let page = crate::robot_pages::page(status.robots, &request);
    if !page.error.is_empty() {
        return Err(ApiError::BadRequest(page.error));
    }
    Ok(axum::Json(RobotPageJson::from(&page)).into_response())
}

/// Asks the central unit `key` (with `payload`) and decodes its first answer.
async fn ask<T: DeserializeOwned>(
    st: &AppState,
    key: String,
    payload: Option<Vec<u8>>,
) -> Result<T, ApiError> {
    let unavailable = |e: String| ApiError::Unavailable(format!("{key}: {e}"));
    let mut get = st.session.get(&key).timeout(ADMIN_TIMEOUT);
    if let Some(p) = payload {
        get = get.payload(p);
    }
    let replies = get.await.map_err(|e| unavailable(e.to_string()))?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            return decode(&sample.payload().to_bytes()).map_err(|e| unavailable(e.to_string()));
        }
    }
    Err(unavailable("no answer".into()))
}

fn admin_key(st: &AppState, command: &str) -> Result<String, ApiError> {
    st.keys
        .central_admin(command)
        .map_err(|e| ApiError::Unavailable(e.to_string()))
}

async fn schedule(State(st): State<AppState>) -> Result<axum::Json<ScheduleJson>, ApiError> {
    let key = admin_key(&st, "schedule")?;
    let s: Schedule = ask(&st, key, None).await?;
    Ok(axum::Json(ScheduleJson::from(&s)))
}

async fn transmitters(
    State(st): State<AppState>,
) -> Result<axum::Json<TransmittersJson>, ApiError> {
    let key = admin_key(&st, "transmitters")?;
    let r: TransmittersReport = ask(&st, key, None).await?;
    Ok(axum::Json(TransmittersJson::from(&r)))
}

/// The query of `/api/coverage`.
#[derive(Debug, Deserialize)]
struct CoverageQuery {
    resolution_m: Option<f64>,
}

async fn coverage(
    State(st): State<AppState>,
    query: Result<Query<CoverageQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query.map_err(|e| ApiError::BadRequest(e.body_text()))?;
    let resolution_m = q
        .resolution_m
        .unwrap_or(crate::coverage::DEFAULT_RESOLUTION_M);
    if !COVERAGE_RESOLUTION_M.contains(&resolution_m) {
        return Err(ApiError::BadRequest(format!(
            "resolution_m must be between {} and {} m",
            COVERAGE_RESOLUTION_M.start(),
            COVERAGE_RESOLUTION_M.end()
        )));
    }
    let payload = encode(&CoverageRequest { resolution_m })
        .map_err(|e| ApiError::Unavailable(e.to_string()))?;
    let report: CoverageReport = ask(&st, admin_key(&st, "coverage")?, Some(payload)).await?;
    Ok(axum::Json(CoverageJson::from(&report)).into_response())
}

/// The site being served (asked of the central unit, so a reload shows).
async fn site(State(st): State<AppState>) -> Result<axum::Json<SiteView>, ApiError> {
    let info: SiteInfo = ask(&st, st.keys.central_site(), None).await?;
    let site = Site::from_toml(&info.site_toml, "central/site")
        .map_err(|e| ApiError::Unavailable(e.to_string()))?;
    st.view.lock().set_site(&site);
    Ok(axum::Json(SiteView::from(&site)))
}

/// Compares without an early exit, so the time taken says nothing of the token.
fn same_token(given: &[u8], expected: &[u8]) -> bool {
    given.len() == expected.len()
        && given
            .iter()
            .zip(expected)
            .fold(0u8, |acc, (a, b)| acc | (a ^ b))
            == 0
}

fn authorise(st: &AppState, headers: &HeaderMap) -> Result<(), ApiError> {
    let token = st.token.as_deref().ok_or(ApiError::ReadOnly)?;
    let given = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .ok_or(ApiError::Unauthorized)?;
    if same_token(given.trim().as_bytes(), token.as_bytes()) {
        Ok(())
    } else {
        Err(ApiError::Unauthorized)
    }
}

async fn command(
    st: &AppState,
    headers: &HeaderMap,
    name: &str,
) -> Result<axum::Json<AdminAck>, ApiError> {
    authorise(st, headers)?;
    Ok(axum::Json(ask(st, admin_key(st, name)?, None).await?))
}

async fn pause(
    State(st): State<AppState>,
    headers: HeaderMap,
) -> Result<axum::Json<AdminAck>, ApiError> {
    command(&st, &headers, "pause").await
}

async fn resume(
    State(st): State<AppState>,
    headers: HeaderMap,
) -> Result<axum::Json<AdminAck>, ApiError> {
    command(&st, &headers, "resume").await
}

/// The body of `/api/reload`.
#[derive(Debug, Deserialize)]
struct ReloadBody {
    file_name: String,
    site_toml: String,
}

async fn reload(
    State(st): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<axum::Json<AdminAck>, ApiError> {
    authorise(&st, &headers)?;
    let body: ReloadBody =
        serde_json::from_slice(&body).map_err(|e| ApiError::BadRequest(format!("body: {e}")))?;
    let payload = encode(&ReloadRequest {
        file_name: body.file_name,
        site_toml: body.site_toml,
    })
    .map_err(|e| ApiError::BadRequest(e.to_string()))?;
    Ok(axum::Json(
        ask(&st, admin_key(&st, "reload")?, Some(payload)).await?,
    ))
}
