//! A lost router is seen: every node watches its session's link to the
//! Zenoh router and says, at WARN, when the link goes down and, at INFO,
//! when it is back and after how long. Zenoh reconnects by itself and
//! says nothing at INFO meanwhile, so without this a node cut off from
//! its site looks healthy in its own log.
//!
//! The watch polls the routers the session is connected to
//! ([`WATCH_PERIOD`] apart; Zenoh's link events are not in its stable
//! API). A node that has never had a router (a peer mesh, a router of its
//! own) never warns. Losses and returns each go through a
//! [`LogLimiter`], so a link that flaps writes one line of each per window
//! with the number left unsaid.

use std::sync::Mutex;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use zenoh::{Session, Wait};

use crate::log_limit::{DEFAULT_WINDOW, LogLimiter};

/// How often the session's routers are looked at: a loss is seen within a
/// second, for the price of one lookup of an in-memory table.
pub const WATCH_PERIOD: Duration = Duration::from_secs(1);

/// What changed in the link to the router.
#[derive(Debug, Clone, PartialEq)]
pub enum RouterEvent {
    /// The last router went away.
    Lost {
        /// Losses left unsaid since the last line about one.
        held: u64,
    },
    /// A router is back.
    Back {
        /// How long the node was without one.
        down_for: Duration,
        /// Returns left unsaid since the last line about one.
        held: u64,
    },
}

/// The kinds of line the limiter counts apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Kind {
    Lost,
    Back,
}

/// The watch's state: fed the number of routers connected and `now`.
#[derive(Debug)]
pub struct RouterWatch {
    /// Whether a router was ever connected (a peer mesh never has one).
    seen: bool,
    /// Since when none is, while the link is down.
    down_since: Option<Instant>,
    /// When the link last came back.
    last_back: Option<Instant>,
    /// Losses since the watch started.
    losses: u64,
    limiter: LogLimiter<Kind>,
}

impl Default for RouterWatch {
    fn default() -> Self {
        Self::new(DEFAULT_WINDOW)
    }
}

impl RouterWatch {
    /// A watch that says at most one line of each kind per `window`.
    pub fn new(window: Duration) -> Self {
        Self {
            seen: false,
            down_since: None,
            last_back: None,
            losses: 0,
            limiter: LogLimiter::new(window),
        }
    }

    /// Takes the number of routers connected at `now`; returns what is to
    /// be said, if anything.
    pub fn observe(&mut self, routers: usize, now: Instant) -> Option<RouterEvent> {
        if routers > 0 {
            self.seen = true;
            let since = self.down_since.take()?;
            self.last_back = Some(now);
            let held = self.limiter.admit(Kind::Back, now)?;
            return Some(RouterEvent::Back {
                down_for: now.saturating_duration_since(since),
                held,
            });
        }
        if !self.seen || self.down_since.is_some() {
            return None;
        }
        self.down_since = Some(now);
        self.losses += 1;
        let held = self.limiter.admit(Kind::Lost, now)?;
        Some(RouterEvent::Lost { held })
    }

    /// Whether the link is down now.
    pub fn is_down(&self) -> bool {
        self.down_since.is_some()
    }

    /// When the link last came back after a loss.
    pub fn last_back(&self) -> Option<Instant> {
        self.last_back
    }

    /// Losses of the link since the watch started.
    pub fn losses(&self) -> u64 {
        self.losses
    }
}

/// The link as the node reports it: when it last came back, on the wall
/// clock (another host reads it), and how often it was lost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkRecord {
    /// When the link last came back after a loss, milliseconds since the
    /// Unix epoch (0: not lost since the process started).
    pub back_unix_ms: u64,
    /// Losses since the process started.
    pub losses: u64,
}

/// The record of this process's watch. One per process: a node opens one
/// session, and the watch runs on a thread of its own that the node's
/// reporting code does not hold.
static LINK: Mutex<LinkRecord> = Mutex::new(LinkRecord {
    back_unix_ms: 0,
    losses: 0,
});

/// The link as this process's watch last saw it ([`spawn`]); all zero
/// without a watch or before any loss.
pub fn link_record() -> LinkRecord {
    LINK.lock().map(|r| *r).unwrap_or_default()
}

/// Copies what `watch` knows into the process's record, stamping a new
/// return with the wall clock.
fn record(watch: &RouterWatch, seen_back: &mut Option<Instant>) {
    let back = watch.last_back();
    let mut fresh = link_record();
    if back != *seen_back {
        *seen_back = back;
        fresh.back_unix_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX));
    }
    fresh.losses = watch.losses();
    if let Ok(mut r) = LINK.lock() {
        *r = fresh;
    }
}

/// Writes `event` to the log: a loss at WARN, a return at INFO.
pub fn log_event(event: &RouterEvent) {
    let unsaid = |held: u64, what: &str| {
        if held > 0 {
            format!(" ({held} more {what} since the last line)")
        } else {
            String::new()
        }
    };
    match event {
        RouterEvent::Lost { held } => tracing::warn!(
            "lost the link to the Zenoh router; reconnecting{}",
            unsaid(*held, "losses")
        ),
        RouterEvent::Back { down_for, held } => tracing::info!(
            "link to the Zenoh router back after {:.1} s{}",
            down_for.as_secs_f64(),
            unsaid(*held, "returns")
        ),
    }
}

/// Watches `session`'s link to its router until the session closes,
/// logging each change ([`log_event`]).
///
/// The watch is a thread of its own, not a task: Zenoh answers the lookup
/// by blocking in its own runtime, which from a task of the node's runtime
/// can wait for ever on the very threads that re-establish the link.
pub fn spawn(session: Session) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("router-watch".into())
        .spawn(move || {
            let mut watch = RouterWatch::default();
            let mut seen_back = None;
            loop {
                std::thread::sleep(WATCH_PERIOD);
                if session.is_closed() {
                    return;
                }
                let routers = session.info().routers_zid().wait().count();
                // A session closed while being asked reports no router: not a loss.
                if session.is_closed() {
                    return;
                }
                if let Some(event) = watch.observe(routers, Instant::now()) {
                    log_event(&event);
                }
                record(&watch, &mut seen_back);
            }
        })
}

/// How often a node reports its link ([`report`]): a central unit started
/// after the node learns it within this.
pub const REPORT_PERIOD: Duration = Duration::from_secs(5);

/// Publishes this process's [`link_record`] as node `node_id`'s
/// [`RouterLink`](ickon_proto::msg::control::RouterLink) on `key` every
/// [`REPORT_PERIOD`], until the session closes. A thread of its own, for
/// the reason [`spawn`] gives; a report put while the link is down is lost,
/// and the next one says the same and more.
pub fn report(
    session: Session,
    key: String,
    node_id: String,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("router-link-report".into())
        .spawn(move || {
            let mut failures = LogLimiter::<()>::new(DEFAULT_WINDOW);
            loop {
                if session.is_closed() {
                    return;
                }
                let r = link_record();
                let message = ickon_proto::msg::control::RouterLink {
                    node_id: node_id.clone(),
                    back_unix_ms: r.back_unix_ms,
                    losses: r.losses,
                };
                let sent = ickon_proto::encode(&message)
                    .map_err(|e| e.to_string())
                    .and_then(|bytes| session.put(&key, bytes).wait().map_err(|e| e.to_string()));
                if let Err(e) = sent
                    && !session.is_closed()
                    && let Some(held) = failures.admit((), Instant::now())
                {
                    tracing::warn!("cannot report the router link on {key}: {e} ({held} more)");
                }
                std::thread::sleep(REPORT_PERIOD);
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_without_a_router_never_warns() {
        let mut w = RouterWatch::default();
        let t0 = Instant::now();
        for s in 0..100 {
            assert_eq!(w.observe(0, t0 + Duration::from_secs(s)), None);
        }
        assert!(!w.is_down());
    }

    #[test]
    fn a_loss_and_a_return_are_said_once_each() {
        let mut w = RouterWatch::default();
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        assert_eq!(w.observe(1, at(0)), None);
        assert_eq!(w.observe(0, at(1)), Some(RouterEvent::Lost { held: 0 }));
        assert!(w.is_down());
        assert_eq!(w.observe(0, at(2)), None);
        assert_eq!(w.observe(0, at(3)), None);
        assert_eq!(
            w.observe(1, at(5)),
            Some(RouterEvent::Back {
                down_for: Duration::from_secs(4),
                held: 0
            })
        );
        assert_eq!(w.last_back(), Some(at(5)));
        assert_eq!(w.losses(), 1);
        assert_eq!(w.observe(2, at(6)), None);
    }

    #[test]
    fn a_flapping_link_is_said_once_per_window_with_the_count_held_back() {
        let mut w = RouterWatch::new(Duration::from_secs(10));
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        w.observe(1, at(0));
        let mut said = Vec::new();
        // Down on odd seconds, up on even ones, for 12 s.
        for s in 1..=12 {
            if let Some(e) = w.observe(usize::from(s % 2 == 0), at(s)) {
                said.push((s, e));
            }
        }
        assert_eq!(
            said,
            vec![
                (1, RouterEvent::Lost { held: 0 }),
                (
                    2,
                    RouterEvent::Back {
                        down_for: Duration::from_secs(1),
                        held: 0
                    }
                ),
                (11, RouterEvent::Lost { held: 4 }),
                (
                    12,
                    RouterEvent::Back {
                        down_for: Duration::from_secs(1),
                        held: 4
                    }
                ),
            ]
        );
        // The link came back each time even when not said.
        assert_eq!(w.last_back(), Some(at(12)));
    }
}
