//! [`Recorder`]: the MCAP writer of a recording, fed one sample at a time
//! with its key, payload and receive time (it never reads a clock: the
//! Zenoh loop and the throughput bench drive it alike).
//!
//! The file is the ROS 2 profile of MCAP: zstd-compressed chunks, message
//! indexes, chunk indexes and statistics in the summary. **Crash safety**:
//! a chunk is closed and written out (to the operating system, which keeps
//! it when the process is killed) at least every [`FLUSH_EVERY`] of
//! receive time; a recorder killed with SIGKILL leaves every chunk before
//! the last flush readable by any linear MCAP reader (the file then has no
//! summary and ends mid-record; `ickon replay mcap` says so and uses what is
//! there). A write error (a full disk) stops the recording with
//! [`RecordError::Write`]; what was flushed before it stays readable.

use std::collections::{BTreeMap, HashMap};
use std::io::{Seek, Write};

use ickon_proto::Time;
use ickon_proto::keys::Keys;
use mcap::records::{MessageHeader, Metadata};
use mcap::{Compression, McapError, WriteOptions};

use super::channels;

/// Longest time, in receive time, between two chunks written out.
pub const FLUSH_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// Chunks larger than this (uncompressed) are closed early: bounded memory
/// and seek granularity on a busy site.
const CHUNK_BYTES: u64 = 4 * 1024 * 1024;

/// Channels of the Foxglove view at most (a few per robot and cell; the
/// view makes one per robot it hears, and the site's robots are bounded).
const MAX_VIEW_CHANNELS: usize = 4096;

/// Why a recording stopped.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// Writing the file failed (disk full, file system gone).
    #[error("cannot write the recording: {0}")]
    Write(#[source] std::io::Error),
    /// The MCAP writer refused (too many channels or schemas).
    #[error("MCAP writer: {0}")]
    Mcap(#[source] McapError),
}

impl RecordError {
    /// Whether the disk (or the quota) is full.
    pub fn disk_full(&self) -> bool {
        matches!(self, RecordError::Write(e) if e.kind() == std::io::ErrorKind::StorageFull
            || e.raw_os_error() == Some(nix::errno::Errno::ENOSPC as i32)
            || e.raw_os_error() == Some(nix::errno::Errno::EDQUOT as i32))
    }
}

impl From<McapError> for RecordError {
    fn from(e: McapError) -> Self {
        match e {
            McapError::Io(io) => RecordError::Write(io),
            other => RecordError::Mcap(other),
        }
    }
}

/// What happened to one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Stored.
    Recorded,
    /// A key of no stream (a probe, a foreign site): not stored.
    NotAStream,
    /// The payload is not a message of its key's type: not stored.
    Undecodable,
}

/// Counters of a recording.
#[derive(Debug, Default, Clone, serde::Serialize)]
pub struct RecordStats {
    /// Messages stored, per ROS topic.
    pub per_topic: BTreeMap<String, u64>,
    /// Messages stored.
    pub messages: u64,
    /// Payload bytes stored (before compression).
    pub payload_bytes: u64,
    /// Samples on keys of no stream (not stored).
    pub not_a_stream: u64,
    /// Samples whose payload did not decode as their key's type (not stored).
    pub undecodable: u64,
    /// Messages of the Foxglove view stored (counted in `messages` too).
    pub view_messages: u64,
    /// First and last receive time, ns.
    pub first_ns: Option<i64>,
    /// Last receive time, ns.
    pub last_ns: Option<i64>,
}

/// The MCAP writer of one recording.
pub struct Recorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    keys: Keys,
    /// Channel id per key (`None`: a key not recorded).
    channels: HashMap<String, Option<u16>>,
    /// Channel id per topic of the Foxglove view.
    view_channels: HashMap<String, u16>,
    sequences: HashMap<u16, u32>,
    last_flush: Option<Time>,
    stats: RecordStats,
    undecodable_logged: u64,
}

impl<W: Write + Seek> Recorder<W> {
    /// Starts a recording of the site of `keys` on `out`; `metadata` is
    /// written as MCAP metadata records (name -> key/value pairs).
    pub fn new(
        out: W,
        keys: Keys,
        metadata: &BTreeMap<String, BTreeMap<String, String>>,
    ) -> Result<Self, RecordError> {
        let mut writer = WriteOptions::new()
            .profile("ros2")
            .library(concat!("ickon-", env!("CARGO_PKG_VERSION")))
            .compression(Some(Compression::Zstd))
            .chunk_size(Some(CHUNK_BYTES))
            .create(out)?;
        for (name, entries) in metadata {
            writer.write_metadata(&Metadata {
                name: name.clone(),
                metadata: entries.clone(),
            })?;
        }
        Ok(Self {
            writer,
            keys,
            channels: HashMap::new(),
            view_channels: HashMap::new(),
            sequences: HashMap::new(),
            last_flush: None,
            stats: RecordStats::default(),
            undecodable_logged: 0,
        })
    }

    fn channel(&mut self, key: &str) -> Result<Option<(u16, channels::Plan)>, RecordError> {
        let plan = channels::plan(&self.keys, key);
        if let Some(&id) = self.channels.get(key) {
            return Ok(id.zip(plan));
        }
        let Some(plan) = plan else {
            // Bounded: a flood of foreign keys is not remembered one by one.
            if self.channels.len() < 100_000 {
                self.channels.insert(key.to_string(), None);
            }
            return Ok(None);
        };
        let schema = plan.recorded.schema();
        let schema_id = self
            .writer
            .add_schema(&schema.name, "ros2msg", schema.text.as_bytes())?;
        let id = self.writer.add_channel(
            schema_id,
            &channels::topic_of(key),
            "cdr",
            &channels::channel_metadata(key, &plan),
        )?;
        self.channels.insert(key.to_string(), Some(id));
        Ok(Some((id, plan)))
    }

    /// Records one message of the Foxglove view ([`super::view`]) received
    /// at `received` (the MCAP log time); the time the view made it becomes
    /// the publish time.
    pub fn record_view(
        &mut self,
        message: &super::view::ViewMessage,
        received: Time,
    ) -> Result<(), RecordError> {
        let channel_id = match self.view_channels.get(&message.topic) {
            Some(&id) => id,
            None => {
                if self.view_channels.len() >= MAX_VIEW_CHANNELS {
                    self.stats.not_a_stream += 1;
                    return Ok(());
                }
                let schema_id = match &message.schema {
                    Some(schema) => {
                        self.writer
                            .add_schema(&schema.name, &schema.encoding, &schema.data)?
                    }
                    None => 0,
                };
                let id = self.writer.add_channel(
                    schema_id,
                    &message.topic,
                    &message.message_encoding,
                    &super::view::channel_metadata(),
                )?;
                self.view_channels.insert(message.topic.clone(), id);
                id
            }
        };
        let sequence = self.sequences.entry(channel_id).or_insert(0);
        *sequence = sequence.wrapping_add(1);
        let log_time = received.as_nanos().max(0) as u64;
        self.writer.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence: *sequence,
                log_time,
                publish_time: message.made_ns,
            },
            &message.data,
        )?;
        let s = &mut self.stats;
        s.messages += 1;
        s.view_messages += 1;
        s.payload_bytes += message.data.len() as u64;
        *s.per_topic.entry(message.topic.clone()).or_default() += 1;
        s.first_ns.get_or_insert(received.as_nanos());
        s.last_ns = Some(received.as_nanos());
        self.tick(received)
    }

    /// Records one sample received at `received` (the MCAP log time); its
    /// own event time becomes the publish time.
    pub fn record(
        &mut self,
        key: &str,
        payload: &[u8],
        received: Time,
    ) -> Result<Outcome, RecordError> {
        let Some((channel_id, plan)) = self.channel(key)? else {
            self.stats.not_a_stream += 1;
            return Ok(Outcome::NotAStream);
        };
        let stored = match channels::prepare(&plan, payload) {
            Ok(s) => s,
            Err(e) => {
                self.stats.undecodable += 1;
                // Rate-limited: the first ten, then every thousandth.
                if self.undecodable_logged < 10 || self.stats.undecodable.is_multiple_of(1000) {
                    self.undecodable_logged += 1;
                    tracing::warn!(
                        "not recorded: {key}: {e} ({} so far)",
                        self.stats.undecodable
                    );
                }
                return Ok(Outcome::Undecodable);
            }
        };
        let sequence = self.sequences.entry(channel_id).or_insert(0);
        *sequence = sequence.wrapping_add(1);
        let log_time = received.as_nanos().max(0) as u64;
        let publish_time = stored
            .event_time
            .map_or(log_time, |t| t.as_nanos().max(0) as u64);
        self.writer.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence: *sequence,
                log_time,
                publish_time,
            },
            &stored.data,
        )?;
        let s = &mut self.stats;
        s.messages += 1;
        s.payload_bytes += stored.data.len() as u64;
        *s.per_topic.entry(channels::topic_of(key)).or_default() += 1;
        s.first_ns.get_or_insert(received.as_nanos());
        s.last_ns = Some(received.as_nanos());
        self.tick(received)?;
        Ok(Outcome::Recorded)
    }

    /// Writes the open chunk out when [`FLUSH_EVERY`] has passed since the
    /// last time (call it on a timer too, so a quiet site is flushed).
    pub fn tick(&mut self, now: Time) -> Result<(), RecordError> {
        let last = *self.last_flush.get_or_insert(now);
        if now.since(last).as_nanos() >= FLUSH_EVERY.as_nanos() as i64 {
            self.writer.flush()?;
            self.last_flush = Some(now);
        }
        Ok(())
    }

    /// Writes the summary (indexes, statistics) and the footer.
    pub fn finish(mut self) -> Result<(RecordStats, W), RecordError> {
        self.writer.finish()?;
        Ok((self.stats, self.writer.into_inner()))
    }
}
