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

use std::time::{Duration, Instant};

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
