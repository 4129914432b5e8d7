//! Publishing that never ends a node: a put that fails (a session closing,
//! a transport error) is logged at debug level and reported `false`, for
//! the node to count; the node goes on.

use serde::Serialize;
use zenoh::pubsub::Publisher;

/// Encodes `value` and puts it on `publisher`; `false` if either failed.
pub async fn put_counted<T: Serialize>(publisher: &Publisher<'_>, value: &T) -> bool {
    let bytes = match ickon_proto::encode(value) {
        Ok(b) => b,
        Err(e) => {
            tracing::debug!("not sent on {}: {e}", publisher.key_expr());
            return false;
        }
    };
    match publisher.put(bytes).await {
        Ok(()) => true,
        Err(e) => {
            tracing::debug!("put on {} failed: {e}", publisher.key_expr());
            false
        }
    }
}
