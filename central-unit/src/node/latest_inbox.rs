//! A queue that keeps, per key, only the newest sample the loop has not
//! taken yet. The robots' summaries and statuses are states, not events:
//! a robot's newer summary says all its older one said that still holds.
//! Zenoh's default queue (a bounded FIFO) blocks Zenoh's receive path
//! when the loop falls behind, and the link then stops for everything on
//! it, admin queries included, until the router gives up and closes it.
//! This queue never blocks the receive path: a robot's summary that a
//! newer one overtakes before the loop took it is superseded (counted),
//! so that what waits is at most one sample per robot, whatever the
//! fleet sends.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};

use zenoh::sample::Sample;

/// Most keys with a sample waiting: a sender inventing keys by the
/// million cannot grow the queue without bound (the site lists at most
/// 10,000 robots). Samples of further keys are refused, and counted.
pub(super) const MAX_WAITING_KEYS: usize = 65_536;

/// Keys' room kept when the queue empties: a few batches' worth, so that
/// a queue that empties after every batch does not allocate anew each
/// time.
const KEPT_CAPACITY: usize = 1_024;

/// The newest not-yet-taken item per key, in the order the keys first
/// came: pure, so that it is tested without a mesh.
#[derive(Debug)]
pub(super) struct Latest<T> {
    waiting: HashMap<String, T>,
    order: VecDeque<String>,
    max_keys: usize,
    /// Items a newer one of the same key replaced before they were taken.
    pub superseded: u64,
    /// Items refused because as many keys as allowed were waiting.
    pub refused: u64,
}

impl<T> Latest<T> {
    /// An empty queue holding at most `max_keys` keys.
    pub(super) fn new(max_keys: usize) -> Self {
        Self {
            waiting: HashMap::new(),
            order: VecDeque::new(),
            max_keys,
            superseded: 0,
            refused: 0,
        }
    }

    /// Keeps `item` as `key`'s newest: it replaces a waiting one (which
    /// keeps its place in the order) or waits behind the others.
    pub(super) fn push(&mut self, key: &str, item: T) {
        if let Some(waiting) = self.waiting.get_mut(key) {
            *waiting = item;
            self.superseded += 1;
        } else if self.waiting.len() >= self.max_keys {
            self.refused += 1;
        } else {
            self.waiting.insert(key.to_owned(), item);
            self.order.push_back(key.to_owned());
        }
    }

    /// Up to `max` waiting items, oldest key first.
    pub(super) fn take(&mut self, max: usize) -> Vec<T> {
        let mut taken = Vec::with_capacity(max.min(self.order.len()));
        while taken.len() < max {
            let Some(key) = self.order.pop_front() else {
                break;
            };
            if let Some(item) = self.waiting.remove(&key) {
                taken.push(item);
            }
        }
        if self.order.is_empty() && self.waiting.capacity() > KEPT_CAPACITY {
            // A burst of 10,000 robots would leave its capacity behind.
            self.waiting.shrink_to(KEPT_CAPACITY);
            self.order.shrink_to(KEPT_CAPACITY);
        }
        taken
    }
}

/// [`Latest`] between Zenoh's receive path (the callback) and the loop.
#[derive(Clone)]
pub(super) struct LatestInbox {
    shared: Arc<Shared>,
}

struct Shared {
    latest: Mutex<Latest<Sample>>,
    ready: tokio::sync::Notify,
}

impl LatestInbox {
    /// An empty inbox of at most [`MAX_WAITING_KEYS`] keys.
    pub(super) fn new() -> Self {
        Self {
            shared: Arc::new(Shared {
                latest: Mutex::new(Latest::new(MAX_WAITING_KEYS)),
                ready: tokio::sync::Notify::new(),
            }),
        }
    }

    /// Takes a sample in Zenoh's receive path: never waits for the loop.
    pub(super) fn put(&self, sample: Sample) {
        let key = sample.key_expr().as_str().to_owned();
        self.latest().push(&key, sample);
        self.shared.ready.notify_one();
    }

    /// Up to `max` samples, waiting for one if none waits. Cancel-safe:
    /// the samples stay in the inbox until taken.
    pub(super) async fn next_batch(&self, max: usize) -> Vec<Sample> {
        loop {
            let batch = self.latest().take(max);
            if !batch.is_empty() {
                return batch;
            }
            self.shared.ready.notified().await;
        }
    }

    /// Samples superseded and refused so far.
    pub(super) fn dropped(&self) -> (u64, u64) {
        let latest = self.latest();
        (latest.superseded, latest.refused)
    }

    fn latest(&self) -> std::sync::MutexGuard<'_, Latest<Sample>> {
        // A panic while holding it leaves a queue still whole.
        self.shared
            .latest
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::Latest;

    #[test]
    fn a_newer_item_replaces_the_waiting_one_of_its_key_in_its_place() {
        let mut q = Latest::new(10);
        q.push("r1", 1);
        q.push("r2", 2);
        q.push("r1", 3);
        assert_eq!(q.superseded, 1);
        assert_eq!(q.take(10), vec![3, 2]);
        assert!(q.take(10).is_empty());
    }

    #[test]
    fn take_hands_at_most_max_and_keeps_the_rest_in_order() {
        let mut q = Latest::new(10);
        for (k, key) in ["a", "b", "c"].into_iter().enumerate() {
            q.push(key, k);
        }
        assert_eq!(q.take(2), vec![0, 1]);
        q.push("a", 5);
        assert_eq!(q.take(2), vec![2, 5]);
        assert_eq!(q.superseded, 0);
    }

    #[test]
    fn keys_beyond_the_bound_are_refused_and_counted() {
        let mut q = Latest::new(2);
        q.push("a", 0);
        q.push("b", 1);
        q.push("c", 2);
        q.push("a", 3);
        assert_eq!((q.superseded, q.refused), (1, 1));
        assert_eq!(q.take(10), vec![3, 1]);
        q.push("c", 4);
        assert_eq!(q.take(10), vec![4]);
    }
}
