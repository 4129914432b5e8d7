//! The live web map and JSON API of the central unit (`--http ADDR`).
//!
//! A page served from the binary (plain HTML, CSS and JavaScript drawing
//! SVG; nothing fetched from elsewhere) shows the floor plan with the cells
//! coloured by state and flashing as they fire, the transmitters, the
//! coverage as a layer, and every robot: fused pose, raw fix with its
//! 2-sigma ellipse, a fading trail and, in a simulation, the truth. It is
//! updated at 20 Hz over server-sent events, which browsers reconnect by
//! themselves when the central unit restarts.
//!
//! The central unit's loop publishes its status into a watch channel
//! ([`WebMap::publish`], a non-blocking replace) and hands the robots'
//! summaries, the bursts and the truth it received to a sans-IO
//! [`view::LiveView`] ([`WebMap::sink`]); everything else here runs beside
//! it: a ticker serialises one snapshot per tick and offers
//! it to every client's bounded queue ([`fanout`]), and the schedule,
//! coverage, site and control requests go to the central unit's admin
//! queryables like `ickon admin`'s ([`routes`]). Control (pause, resume,
//! reload) needs the token read from `--http-token-file`; without one the
//! server is read-only.

pub mod fanout;
pub mod feed;
pub mod routes;
pub mod site_view;
pub mod view;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::Args;
use ickon_proto::keys::Keys;
use ickon_proto::msg::admin::StatusReport;
use ickon_proto::site::Site;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use zenoh::Session;

use fanout::Hub;
use feed::{SharedView, Stopwatch, ViewSink};
use routes::AppState;
use view::LiveView;

/// The web flags of the central unit.
#[derive(Debug, Clone, Default, Args)]
pub struct HttpArgs {
    /// Serve the live web map and the JSON API on ADDR (e.g. 127.0.0.1:8080).
    #[arg(long, value_name = "ADDR")]
    pub http: Option<SocketAddr>,
    /// File holding the token that allows pause, resume and reload over
    /// HTTP (`Authorization: Bearer <token>`); without it the API is read-only.
    #[arg(long, value_name = "FILE", requires = "http")]
    pub http_token_file: Option<PathBuf>,
}

/// Why the web map could not start.
#[derive(Debug, thiserror::Error)]
pub enum HttpError {
    /// The address could not be bound.
    #[error("cannot serve the web map on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The token file is unreadable or empty.
    #[error("token file {path}: {reason}")]
    Token {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
}

/// Reads the control token: the file's text without surrounding white space.
pub fn read_token(path: &Path) -> Result<String, HttpError> {
    let err = |reason: String| HttpError::Token {
        path: path.to_path_buf(),
        reason,
    };
    // Bounded while reading, not by the file's stated size: a device such
    // as /dev/zero states none and never ends.
    let text = ickon_proto::text_file::read_bounded(path, 4096).map_err(err)?;
    let token = text.trim();
    if token.is_empty() {
        return Err(err("empty".into()));
    }
    Ok(token.to_string())
}

/// `addr` if it is free, else the next free port above it on the same
/// interface (up to 100 further), for `ickon sim --http` with no address.
pub fn first_free_addr(addr: SocketAddr) -> Option<SocketAddr> {
    (0..=100u16).find_map(|k| {
        let candidate = SocketAddr::new(addr.ip(), addr.port().checked_add(k)?);
        std::net::TcpListener::bind(candidate)
            .ok()
            .and_then(|l| l.local_addr().ok())
    })
}

/// The running web map. Dropping it stops the server and the feed.
pub struct WebMap {
    addr: SocketAddr,
    status: watch::Sender<Option<StatusReport>>,
    tasks: Vec<JoinHandle<()>>,
    sink: ViewSink,
}

impl WebMap {
    /// Starts serving `site` as `args` say (`None` when `--http` is absent).
    pub async fn start(
        session: &Session,
        keys: &Keys,
        site: &Site,
        args: &HttpArgs,
    ) -> Result<Option<Self>, HttpError> {
        let Some(addr) = args.http else {
            return Ok(None);
        };
        let token = args
            .http_token_file
            .as_deref()
            .map(read_token)
            .transpose()?;
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|source| HttpError::Bind { addr, source })?;
        let addr = listener
            .local_addr()
            .map_err(|source| HttpError::Bind { addr, source })?;
        let clock = Stopwatch::start();
        let view = SharedView::new(LiveView::new(site));
        let sink = ViewSink::new(view.clone(), clock);
        let hub = Hub::default();
        let (status_tx, status_rx) = watch::channel(None);
        let (latest_tx, latest_rx) = watch::channel(None);
        let state = AppState {
            session: session.clone(),
            keys: keys.clone(),
            hub: hub.clone(),
            view: view.clone(),
            status: status_rx.clone(),
            latest: latest_rx,
            token: token.map(Arc::from),
        };
        let app = routes::router(state);
        let server = tokio::spawn(async move {
            if let Err(e) = axum::serve(listener, app).await {
                tracing::warn!("web map server stopped: {e}");
            }
        });
        let ticker = tokio::spawn(feed::tick(view, hub, status_rx, latest_tx, clock));
        tracing::info!(
            "web map at http://{addr}/ ({})",
            if args.http_token_file.is_some() {
                "control with the token"
            } else {
                "read-only"
            }
        );
        Ok(Some(Self {
            addr,
            status: status_tx,
            tasks: vec![server, ticker],
            sink,
        }))
    }

    /// The address being served.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Hands the central unit's latest status to the map (never waits).
    pub fn publish(&self, status: StatusReport) {
        self.status.send_replace(Some(status));
    }

    /// Where the central unit's loop hands the map what it draws.
    pub fn sink(&self) -> &ViewSink {
        &self.sink
    }
}

impl Drop for WebMap {
    fn drop(&mut self) {
        for t in &self.tasks {
            t.abort();
        }
    }
}

#[cfg(test)]
mod tests;
