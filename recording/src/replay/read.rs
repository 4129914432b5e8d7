//! Reading an ICKON recording back, keeping everything readable: a file cut
//! short (a killed recorder), a damaged chunk, channels of another tool and
//! messages that do not decode are each reported as a [`Problem`] while
//! every message that can be read is kept, in file order (receive order).

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use ickon_proto::keys::{Key, Keys};
use ickon_proto::msg::ros_msgs::recorded_as;
use mcap::read::{ChunkReader, LinearReader, Options};
use mcap::records::Record;

/// Why a file cannot be replayed at all.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file cannot be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not an MCAP file.
    #[error("{0} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap(String),
}

/// Something wrong with a readable file; what could be read is still used.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Problem(pub String);

/// One recorded message of an ICKON stream.
#[derive(Debug, Clone)]
pub struct RecordedMessage {
    /// The Zenoh key it was recorded from.
    pub key: Key,
    /// Receive time (MCAP log time), ns.
    pub log_time_ns: u64,
    /// The stored CDR bytes.
    pub data: Vec<u8>,
}

/// What a recording holds.
#[derive(Debug, Default)]
pub struct Recording {
    /// The site the keys belong to.
    pub site: String,
    /// Metadata records, by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Every readable message of an ICKON stream, in file order.
    pub messages: Vec<RecordedMessage>,
    /// Whether the file ended with its summary and footer (a finished recording).
    pub complete: bool,
    /// What is wrong with it.
    pub problems: Vec<Problem>,
}

#[derive(Debug)]
struct ChannelInfo {
    topic: String,
    schema: Option<String>,
    key: Option<Key>,
    /// A channel of the Foxglove view (`crate::record::view`): for the
    /// eye, not an input of the MSU cores.
    view: bool,
}

/// Reads `path`. A file that is not MCAP at all is an error; anything else
/// gives a [`Recording`] with its problems listed.
pub fn read(path: &Path) -> Result<Recording, ReadError> {
    let bytes = std::fs::read(path).map_err(|source| ReadError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse(&bytes).ok_or_else(|| ReadError::NotMcap(path.display().to_string()))
}

/// Parses a recording; `None` when the bytes are not MCAP.
pub fn parse(bytes: &[u8]) -> Option<Recording> {
    if !bytes.starts_with(mcap::MAGIC) {
        return None;
    }
    let mut reader = LinearReader::new_with_options(bytes, Options::IgnoreEndMagic.into()).ok()?;
    let mut rec = Recording::default();
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: HashMap<u16, ChannelInfo> = HashMap::new();
    let mut state = State::default();
    let mut ended = false;
    for record in reader.by_ref() {
        match record {
            Ok(Record::Chunk { header, data }) => {
                let Ok(inner) = ChunkReader::new(header, &data) else {
                    state.damaged_chunks += 1;
                    continue;
                };
                for r in inner {
                    match r {
                        Ok(r) => handle(r, &mut schemas, &mut channels, &mut rec, &mut state),
                        Err(_) => {
                            state.damaged_chunks += 1;
                            break;
                        }
                    }
                }
            }
            Ok(Record::DataEnd(_)) | Ok(Record::Footer(_)) => {
                ended = true;
                break;
            }
            Ok(r) => handle(r, &mut schemas, &mut channels, &mut rec, &mut state),
            Err(e) => {
                rec.problems.push(Problem(format!(
                    "the file ends early or is damaged after {} messages ({e}): a recorder killed before it finished, or a copy cut short; the messages before are used",
                    rec.messages.len()
                )));
                break;
            }
        }
    }
    rec.complete = ended;
    if !ended && rec.problems.is_empty() {
        rec.problems.push(Problem(format!(
            "the file has no summary (a recorder killed before it finished); all {} messages in it are used",
            rec.messages.len()
        )));
    }
    if state.damaged_chunks > 0 {
        rec.problems.push(Problem(format!(
            "{} damaged chunk(s) could not be read (their messages are lost; the others are used)",
            state.damaged_chunks
        )));
    }
    let mut foreign: Vec<String> = channels
        .values()
        .filter(|c| c.key.is_none() && !c.view)
        .map(|c| {
            format!(
                "{} ({}, {} messages)",
                c.topic,
                c.schema.as_deref().unwrap_or("no schema"),
                state.foreign_messages.get(&c.topic).copied().unwrap_or(0)
            )
        })
        .collect();
    foreign.sort();
    if !foreign.is_empty() {
        rec.problems.push(Problem(format!(
            "{} channel(s) are not ICKON streams and were ignored: {}",
            foreign.len(),
            foreign.join(", ")
        )));
    }
    if state.undecodable > 0 {
        rec.problems.push(Problem(format!(
            "{} message(s) on unknown channels or of the wrong size were skipped",
            state.undecodable
        )));
    }
    rec.site = state.site.unwrap_or_default();
    Some(rec)
}

#[derive(Debug, Default)]
struct State {
    site: Option<String>,
    damaged_chunks: u64,
    undecodable: u64,
    foreign_messages: HashMap<String, u64>,
}

/// The site of a topic `/ickon/<site>/...`.
fn site_of(topic: &str) -> Option<&str> {
    topic.strip_prefix("/ickon/")?.split('/').next()
}

fn handle(
    record: Record<'_>,
    schemas: &mut HashMap<u16, String>,
    channels: &mut HashMap<u16, ChannelInfo>,
    rec: &mut Recording,
    state: &mut State,
) {
    match record {
        Record::Schema { header, .. } => {
            schemas.insert(header.id, header.name);
        }
        Record::Channel(c) => {
            if channels.contains_key(&c.id) {
                return;
            }
            let schema = schemas.get(&c.schema_id).cloned();
            let key = site_of(&c.topic).and_then(|site| {
                let site = state.site.get_or_insert_with(|| site.to_string()).clone();
                let keys = Keys::new(&site).ok()?;
                let key = keys.parse(crate::record::channels::key_of(&c.topic)).ok()?;
                // The schema must be the one ICKON writes for this key.
                let expected = recorded_as(&key)?.schema().name;
                (schema.as_deref() == Some(expected.as_str()) && c.message_encoding == "cdr")
                    .then_some(key)
            });
            let (name, value) = crate::record::view::VIEW_METADATA;
            let view = c.metadata.get(name).is_some_and(|v| v == value);
            channels.insert(
                c.id,
                ChannelInfo {
                    topic: c.topic,
                    schema,
                    key,
                    view,
                },
            );
        }
        Record::Message { header, data } => match channels.get(&header.channel_id) {
            Some(ChannelInfo { key: Some(key), .. }) => rec.messages.push(RecordedMessage {
                key: key.clone(),
                log_time_ns: header.log_time,
                data: match data {
                    Cow::Borrowed(b) => b.to_vec(),
                    Cow::Owned(v) => v,
                },
            }),
            Some(ChannelInfo { view: true, .. }) => {}
            Some(c) => *state.foreign_messages.entry(c.topic.clone()).or_default() += 1,
            None => state.undecodable += 1,
        },
        Record::Metadata(m) => {
            rec.metadata.insert(m.name, m.metadata);
        }
        _ => {}
    }
}
