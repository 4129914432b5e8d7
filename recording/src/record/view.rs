//! The Foxglove view in a recording: the channels the central unit's
//! Foxglove server shows live (`ickon_central::foxglove`: the site scene,
//! the cells and robots, `/tf`, the plots and the site's log), built in the
//! recorder from the same subscriptions and the central unit's status, and
//! written beside the site's own streams. A recording opened in Foxglove
//! then looks as the live view does, with the same layout.
//!
//! Its channels carry Foxglove's own schemas (protobuf, or JSON for the
//! plots) and the channel metadata [`VIEW_METADATA`]: `ickon replay mcap`
//! leaves them aside. Asked for (`--foxglove-view`), not by default:
//! rosbag2 refuses a file whose topics do not share one serialization
//! format, and a recording without the view stays a ROS 2 bag.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use foxglove::{FoxgloveError, Metadata, RawChannel, Schema, Sink, SinkId};
use ickon_central::foxglove::FoxgloveLive;
use ickon_proto::keys::Keys;
use ickon_proto::msg::admin::StatusReport;
use ickon_proto::msg::control::SiteInfo;
use ickon_proto::site::Site;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// The channel metadata key and value that mark a view channel.
pub const VIEW_METADATA: (&str, &str) = ("ickon_view", "foxglove");

/// How often the central unit is asked for its status: the cells' and
/// robots' health the view draws. Twice a second keeps the query load on
/// the central unit small; the poses come at their own rate.
const STATUS_EVERY: Duration = Duration::from_millis(500);

/// View messages waiting for the recorder: several seconds of a large
/// site's ticks. A recorder that falls further behind drops view messages
/// (counted), never the site's own streams.
const QUEUE_MESSAGES: usize = 4096;

/// One message of a view channel, as the recorder stores it.
#[derive(Debug, Clone)]
pub struct ViewMessage {
    /// The Foxglove topic (`/site/scene`, `/robot/r1/pose`, ...).
    pub topic: String,
    /// Its schema (Foxglove's protobuf schemas, or a JSON schema).
    pub schema: Option<Schema>,
    /// `protobuf` or `json`.
    pub message_encoding: String,
    /// The encoded message.
    pub data: Vec<u8>,
    /// When the view made it, nanoseconds since the Unix epoch.
    pub made_ns: u64,
}

/// The sink the view's channels log into: each message is queued for the
/// recorder's loop (never waits; a full queue drops and counts).
struct QueueSink {
    id: SinkId,
    queue: mpsc::Sender<ViewMessage>,
    dropped: std::sync::Arc<AtomicU64>,
}

impl Sink for QueueSink {
    fn id(&self) -> SinkId {
        self.id
    }

    fn log(
        &self,
        channel: &RawChannel,
        msg: &[u8],
        metadata: &Metadata,
    ) -> Result<(), FoxgloveError> {
        let message = ViewMessage {
            topic: channel.topic().to_string(),
            schema: channel.schema().cloned(),
            message_encoding: channel.message_encoding().to_string(),
            data: msg.to_vec(),
            made_ns: metadata.log_time,
        };
        if self.queue.try_send(message).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        Ok(())
    }
}

/// The view of a recording while it runs.
pub struct RecordedView {
    /// The view's messages, for the recorder's loop.
    pub messages: mpsc::Receiver<ViewMessage>,
    dropped: std::sync::Arc<AtomicU64>,
    _live: FoxgloveLive,
    status_poll: JoinHandle<()>,
}

impl RecordedView {
    /// Starts the view of `site_info`'s site: the same subscriptions as the
    /// live server, and the central unit's status asked for every
    /// [`STATUS_EVERY`]. `None` (with a warning) when the site file does
    /// not load or Zenoh refuses a subscriber: the recording goes on
    /// without the view.
    pub async fn start(
        session: &zenoh::Session,
        keys: &Keys,
        site_info: &SiteInfo,
    ) -> Option<Self> {
        let site = match Site::from_toml(&site_info.site_toml, "the central unit's site") {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!("recording without the Foxglove view: {e}");
                return None;
            }
        };
        let (queue, messages) = mpsc::channel(QUEUE_MESSAGES);
        let dropped = std::sync::Arc::new(AtomicU64::new(0));
        let sink = std::sync::Arc::new(QueueSink {
            id: SinkId::next(),
            queue,
            dropped: dropped.clone(),
        });
        let live = match FoxgloveLive::into_sink(session, keys, &site, sink).await {
            Ok(l) => l,
            Err(e) => {
                tracing::warn!("recording without the Foxglove view: {e}");
                return None;
            }
        };
        let status_poll = tokio::spawn(poll_status(
            session.clone(),
            keys.clone(),
            live.status_sender(),
        ));
        Some(Self {
            messages,
            dropped,
            _live: live,
            status_poll,
        })
    }

    /// View messages dropped because the recorder fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Drop for RecordedView {
    fn drop(&mut self) {
        self.status_poll.abort();
    }
}

/// Asks the central unit for its status every [`STATUS_EVERY`] and hands
/// each answer to the view. A central unit that does not answer (gone, or
/// an access-controlled site where the recorder lacks the admin identity)
/// leaves the view without messages until it does.
async fn poll_status(
    session: zenoh::Session,
    keys: Keys,
    publish: impl Fn(StatusReport) + Send + 'static,
) {
    // `robots` without a request: the status with every robot (`status`
    // lists only the worst of a large fleet), each drawn in the view.
    let Ok(key) = keys.central_admin("robots") else {
        return;
    };
    let mut every = tokio::time::interval(STATUS_EVERY);
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut unanswered = 0u64;
    loop {
        every.tick().await;
        let answer =
            ickon_runtime::query_once::<StatusReport>(&session, &key, None, Duration::from_secs(2))
                .await
                .ok()
                .flatten();
        match answer {
            Some(report) => publish(report),
            None => {
                unanswered += 1;
                if unanswered.is_power_of_two() {
                    tracing::warn!(
                        "the central unit did not answer the recorder's status query ({unanswered} times): the recording holds no Foxglove view meanwhile"
                    );
                }
            }
        }
    }
}

/// The metadata of a view channel.
pub fn channel_metadata() -> BTreeMap<String, String> {
    BTreeMap::from([(VIEW_METADATA.0.to_string(), VIEW_METADATA.1.to_string())])
}
