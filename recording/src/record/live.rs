//! The Zenoh edge of a recording: one subscriber on the site's keys, the
//! site and the schedule asked of the central unit once (they are
//! queryables: a recorder that joins late would otherwise never see them),
//! every sample handed to the [`Recorder`] with its receive time.

use std::future::Future;
use std::io::{Seek, Write};
use std::time::Duration;

use ickon_proto::keys::Keys;
use ickon_runtime::{NodeError, system_now, zerr};

use ickon_proto::msg::control::SiteInfo;

use super::view::{RecordedView, ViewMessage};
use super::writer::{RecordError, Recorder};

/// How often the open chunk is checked for flushing on a quiet site.
const TICK: Duration = Duration::from_millis(200);
/// Samples the recorder's subscriber queue holds (a few seconds of a
/// 64-robot site, at most a few tens of MB).
const QUEUE_SAMPLES: usize = 1 << 16;
/// How often the central unit is asked for the site and the schedule until it answers.
const FETCH_RETRY: Duration = Duration::from_millis(500);

/// Why a live recording stopped early.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// Zenoh refused a declaration.
    #[error(transparent)]
    Node(#[from] NodeError),
    /// The file could not be written.
    #[error(transparent)]
    Record(#[from] RecordError),
}

/// Records every sample on `pattern` into `recorder` until `stop` completes,
/// with the Foxglove view ([`super::view`]) once the site is known when
/// `with_view`. Returns early only on an error (the recorder then holds
/// what was flushed).
pub async fn record_site<W: Write + Seek>(
    session: &zenoh::Session,
    keys: &Keys,
    pattern: &str,
    recorder: &mut Recorder<W>,
    with_view: bool,
    stop: impl Future<Output = ()>,
) -> Result<(), LiveError> {
    let mut stop = std::pin::pin!(stop);
    // A deep queue: when the recorder falls behind for a moment (a loaded
    // machine, a chunk being compressed), a full queue would push back on
    // the link and the publishers (congestion control `Drop`) would drop
    // samples to the recorder that the nodes still got.
    let samples = session
        .declare_subscriber(pattern)
        .with(zenoh::handlers::FifoChannel::new(QUEUE_SAMPLES))
        .await
        .map_err(zerr)?;
    // The site and the schedule, once, beside the loop.
    let (tx, mut initial) = tokio::sync::mpsc::channel::<(String, Vec<u8>)>(4);
    let asking = {
        let session = session.clone();
        let (site_key, schedule_key) = (keys.central_site(), keys.central_schedule());
        tokio::spawn(async move {
            let mut never = std::pin::pin!(std::future::pending::<()>());
            for key in [site_key, schedule_key] {
                if let Ok(Some(bytes)) = fetch_raw(&session, &key, FETCH_RETRY, &mut never).await {
                    let _ = tx.send((key, bytes)).await;
                }
            }
        })
    };
    let mut tick = tokio::time::interval(TICK);
    let mut view: Option<RecordedView> = None;
    let result = loop {
        tokio::select! {
            _ = &mut stop => break drain(&samples, recorder),
            Ok(s) = samples.recv_async() => {
                let key = s.key_expr().as_str().to_string();
                if let Err(e) = recorder.record(&key, &s.payload().to_bytes(), system_now()) {
                    break Err(e.into());
                }
            }
            Some((key, bytes)) = initial.recv() => {
                if let Err(e) = recorder.record(&key, &bytes, system_now()) {
                    break Err(e.into());
                }
                if with_view && view.is_none() && key == keys.central_site()
                    && let Ok(info) = ickon_proto::decode::<SiteInfo>(&bytes)
                {
                    view = RecordedView::start(session, keys, &info).await;
                }
            }
            Some(m) = next_view(&mut view) => {
                if let Err(e) = recorder.record_view(&m, system_now()) {
                    break Err(e.into());
                }
            }
            _ = tick.tick() => {
                if let Err(e) = recorder.tick(system_now()) {
                    break Err(e.into());
                }
            }
        }
    };
    asking.abort();
    if let Some(v) = &view
        && v.dropped() > 0
    {
        tracing::warn!(
            "{} messages of the Foxglove view were dropped: the recorder fell behind",
            v.dropped()
        );
    }
    result
}

/// The view's next message; never, without a view.
async fn next_view(view: &mut Option<RecordedView>) -> Option<ViewMessage> {
    match view {
        Some(v) => v.messages.recv().await,
        None => std::future::pending().await,
    }
}

/// Records what already arrived when the stop came: a sample the nodes'
/// other subscribers got is in the queue, and the file must hold it too.
fn drain<W: Write + Seek>(
    samples: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    recorder: &mut Recorder<W>,
) -> Result<(), LiveError> {
    while let Ok(Some(s)) = samples.try_recv() {
        recorder.record(s.key_expr().as_str(), &s.payload().to_bytes(), system_now())?;
    }
    Ok(())
}

/// Asks `key` until a reply arrives and returns its raw payload (the
/// recorder checks its type like any other sample).
async fn fetch_raw(
    session: &zenoh::Session,
    key: &str,
    retry: Duration,
    stop: &mut (impl Future<Output = ()> + Unpin),
) -> Result<Option<Vec<u8>>, NodeError> {
    loop {
        let replies = session
            .get(key)
            .timeout(Duration::from_secs(2))
            .await
            .map_err(zerr)?;
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result() {
                return Ok(Some(sample.payload().to_bytes().into_owned()));
            }
        }
        tokio::select! {
            _ = &mut *stop => return Ok(None),
            _ = tokio::time::sleep(retry) => {}
        }
    }
}
