//! Queries to the central unit: once with a timeout, or again until it answers.

use std::future::Future;
use std::time::Duration;

use serde::de::DeserializeOwned;
use zenoh::Session;

use crate::zerr;

/// Asks `key` (with an optional CDR payload) until a decodable reply of type
/// `T` arrives; `None` if `shutdown` completes first. Undecodable replies are
/// logged and skipped.
pub async fn fetch<T: DeserializeOwned>(
    session: &Session,
    key: &str,
    payload: Option<Vec<u8>>,
    retry: Duration,
    shutdown: &mut (impl Future<Output = ()> + Unpin),
) -> anyhow::Result<Option<T>> {
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
) -> anyhow::Result<Option<T>> {
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
) -> anyhow::Result<bool> {
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
