//! The live stream's fan-out: one bounded queue per web client. A snapshot
//! is serialised once and offered to every queue without waiting; a client
//! whose queue is full has stopped reading (or reads slower than the
//! updates come), and is dropped and counted, so that it can never slow the
//! central unit or the other clients.

use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::mpsc;

/// Snapshots queued per client before it counts as too slow: 0.4 s of
/// updates at 20 Hz, beyond what the socket buffers already hold.
pub const QUEUE_PER_CLIENT: usize = 8;
/// Clients served at once; more are refused (503) rather than let a
/// crowd of browsers cost the central unit without bound.
pub const MAX_CLIENTS: usize = 64;

#[derive(Debug, Default)]
struct Inner {
    clients: Vec<mpsc::Sender<Arc<str>>>,
    dropped: u64,
}

/// The set of connected live-stream clients (cheap to clone, shared).
#[derive(Debug, Clone, Default)]
pub struct Hub {
    inner: Arc<Mutex<Inner>>,
}

impl Hub {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // A panic while holding this lock leaves nothing half-done worth
        // refusing service for: the list is valid after every statement.
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A queue for a new client, or `None` when [`MAX_CLIENTS`] are connected.
    pub fn join(&self) -> Option<mpsc::Receiver<Arc<str>>> {
        let mut inner = self.lock();
        inner.clients.retain(|c| !c.is_closed());
        if inner.clients.len() >= MAX_CLIENTS {
            return None;
        }
        let (tx, rx) = mpsc::channel(QUEUE_PER_CLIENT);
        inner.clients.push(tx);
        Some(rx)
    }

    /// Offers `message` to every client; drops those whose queue is full.
    pub fn broadcast(&self, message: &Arc<str>) {
        let mut inner = self.lock();
        let mut dropped = 0;
        inner
            .clients
            .retain(|c| match c.try_send(Arc::clone(message)) {
                Ok(()) => true,
                Err(mpsc::error::TrySendError::Full(_)) => {
                    dropped += 1;
                    false
                }
                Err(mpsc::error::TrySendError::Closed(_)) => false,
            });
        if dropped > 0 {
            tracing::info!("{dropped} slow web clients dropped");
        }
        inner.dropped += dropped;
    }

    /// Clients connected now and clients dropped so far for being slow.
    pub fn counts(&self) -> (usize, u64) {
        let inner = self.lock();
        (
            inner.clients.iter().filter(|c| !c.is_closed()).count(),
            inner.dropped,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_client_that_stops_reading_is_dropped_and_counted_while_the_others_get_everything() {
        let hub = Hub::default();
        let mut reader = hub.join().expect("room");
        let _stalled = hub.join().expect("room");
        for k in 0..QUEUE_PER_CLIENT + 3 {
            hub.broadcast(&Arc::from(format!("m{k}")));
            assert_eq!(
                reader.try_recv().expect("delivered").as_ref(),
                format!("m{k}")
            );
        }
        assert_eq!(hub.counts(), (1, 1));
    }

    #[test]
    fn a_client_that_left_is_forgotten_without_counting_it_as_slow() {
        let hub = Hub::default();
        drop(hub.join().expect("room"));
        hub.broadcast(&Arc::from("x"));
        assert_eq!(hub.counts(), (0, 0));
    }

    #[test]
    fn clients_beyond_the_limit_are_refused() {
        let hub = Hub::default();
        let held: Vec<_> = (0..MAX_CLIENTS)
            .map(|_| hub.join().expect("room"))
            .collect();
        assert!(hub.join().is_none());
        drop(held);
        assert!(hub.join().is_some());
    }
}
