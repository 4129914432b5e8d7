//! Queries to the central unit: once with a timeout, or again until it answers.

use std::future::Future;
use std::time::Duration;

use serde::de::DeserializeOwned;
use zenoh::Session;

use crate::{NodeError, zerr};

/// Asks `key` (with an optional CDR payload) until a decodable reply of type
/// `T` arrives; `None` if `shutdown` completes first. Undecodable replies are
/// logged and skipped.
pub async fn fetch<T: DeserializeOwned>(
    session: &Session,
    key: &str,
    payload: Option<Vec<u8>>,
    retry: Duration,
    shutdown: &mut (impl Future<Output = ()> + Unpin),
) -> Result<Option<T>, NodeError> {
    loop {
        if let Some(v) = query_once(session, key, payload.clone(), Duration::from_secs(2)).await? {
            return Ok(Some(v));
        }
        tracing::info!("waiting for an answer on {key}");
        tokio::select! {
            _ = &mut *shutdown => return Ok(None),
            _ = tokio::time::sleep(retry) => {}
        }
    }
}

/// One query: the first decodable reply, or `None` when nobody answered in time.
pub async fn query_once<T: DeserializeOwned>(
    session: &Session,
    key: &str,
    payload: Option<Vec<u8>>,
    timeout: Duration,
) -> Result<Option<T>, NodeError> {
    let mut get = session.get(key).timeout(timeout);
    if let Some(p) = payload {
        get = get.payload(p);
    }
    let replies = get.await.map_err(zerr)?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            match ickon_proto::decode::<T>(&sample.payload().to_bytes()) {
                Ok(v) => return Ok(Some(v)),
                Err(e) => tracing::warn!("undecodable reply on {key}: {e}"),
            }
        }
    }
    Ok(None)
}

/// Waits until the liveliness token `key` is present (up to `timeout`):
/// `true` when it is. A peer answers queries only once the link to it is up
/// and its declarations have arrived, which the token shows.
pub async fn wait_for_token(
    session: &Session,
    key: &str,
    timeout: Duration,
) -> Result<bool, NodeError> {
    let subscriber = session
        .liveliness()
        .declare_subscriber(key)
        .history(true)
        .await
        .map_err(zerr)?;
    let seen = tokio::time::timeout(timeout, async {
        while let Ok(sample) = subscriber.recv_async().await {
            if sample.kind() == zenoh::sample::SampleKind::Put {
                return true;
            }
        }
        false
    })
    .await;
    Ok(seen.unwrap_or(false))
}

/// Whether a liveliness token matching `key` is declared now, as far as
/// the session's routers know: `false` when none answers within `timeout`.
/// Unlike [`wait_for_token`] it does not wait for a token to come: the
/// liveliness query ends as soon as every router has answered.
pub async fn token_present(
    session: &Session,
    key: &str,
    timeout: Duration,
) -> Result<bool, NodeError> {
    let replies = session
        .liveliness()
        .get(key)
        .timeout(timeout)
        .await
        .map_err(zerr)?;
    while let Ok(reply) = replies.recv_async().await {
        if reply.result().is_ok() {
            return Ok(true);
        }
    }
    Ok(false)
}

/// An answer with the instants around it, read from the caller's clock.
#[derive(Debug, Clone, PartialEq)]
pub struct Stamped<T> {
    /// The answer.
    pub value: T,
    /// When Zenoh had taken the query (it was routed and queued to send).
    pub sent: ickon_proto::time::Time,
    /// When Zenoh handed the answer over.
    pub received: ickon_proto::time::Time,
}

/// One query whose first answer that `wanted` accepts is stamped with
/// `stamp()` the moment Zenoh hands it over (in its receive path, before
/// any task wakes up), or `None` when no such answer came in time. Clock
/// exchanges need this: every microsecond a reply waits for a busy task to
/// run would count as network asymmetry. Every queryable is asked and each
/// answer handed over as it comes (no consolidation), so that an unwanted
/// answer (another central unit's) neither hides nor delays the wanted one.
pub async fn query_stamped<T: DeserializeOwned>(
    session: &Session,
    key: &str,
    payload: Vec<u8>,
    timeout: Duration,
    stamp: impl Fn() -> ickon_proto::time::Time + Clone + Send + Sync + 'static,
    wanted: impl Fn(&T) -> bool,
) -> Result<Option<Stamped<T>>, NodeError> {
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let on_reply = stamp.clone();
    session
        .get(key)
        .payload(payload)
        .timeout(timeout)
        .target(zenoh::query::QueryTarget::All)
        .consolidation(zenoh::query::ConsolidationMode::None)
        // Unbatched and first in line: queueing adds delay to one leg only.
        .express(true)
        .priority(zenoh::qos::Priority::RealTime)
        .callback(move |reply| {
            let at = on_reply();
            // The receiver is gone only when the caller has given up.
            let _ = tx.send((reply, at));
        })
        .await
        .map_err(zerr)?;
    let sent = stamp();
    // Zenoh drops the callback (and so the sender) when the query ends; the
    // outer timeout only guards against a reply path that never ends it.
    let end = tokio::time::Instant::now() + timeout + Duration::from_millis(100);
    while let Ok(Some((reply, received))) = tokio::time::timeout_at(end, rx.recv()).await {
        if let Ok(sample) = reply.result() {
            match ickon_proto::decode::<T>(&sample.payload().to_bytes()) {
                Ok(value) if wanted(&value) => {
                    return Ok(Some(Stamped {
                        value,
                        sent,
                        received,
                    }));
                }
                Ok(_) => tracing::debug!("unwanted reply on {key} skipped"),
                Err(e) => tracing::warn!("undecodable reply on {key}: {e}"),
            }
        }
    }
    Ok(None)
}
