//! Both ends of a device link above the bytes: [`Decoder`] turns a byte
//! stream into messages and counts what it refused, [`Encoder`] numbers and
//! frames outgoing messages.

use crate::frame::{FrameError, FrameReader, encode_frame};
use crate::message::{Message, MessageError};

/// Why a stretch of the stream did not yield a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ProtocolError {
    /// Not a frame.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// A frame, but not a message.
    #[error(transparent)]
    Message(#[from] MessageError),
}

impl ProtocolError {
    /// A short fixed name of the kind of error (a key for rate-limited logs
    /// and counters).
    pub fn kind(&self) -> &'static str {
        match self {
            ProtocolError::Frame(FrameError::Oversized) => "oversized frame",
            ProtocolError::Frame(FrameError::BadEncoding) => "broken encoding",
            ProtocolError::Frame(FrameError::Truncated(_)) => "truncated frame",
            ProtocolError::Frame(FrameError::BadCrc { .. }) => "CRC mismatch",
            ProtocolError::Message(MessageError::Truncated(_)) => "truncated body",
            ProtocolError::Message(MessageError::UnsupportedVersion(_)) => "unsupported version",
            ProtocolError::Message(MessageError::UnknownType(_)) => "unknown type",
            ProtocolError::Message(MessageError::BadLength { .. }) => "bad length",
            ProtocolError::Message(MessageError::BadField { .. }) => "bad field",
        }
    }
}

/// What a [`Decoder`] has seen.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct DecoderCounters {
    /// Bytes taken.
    pub bytes: u64,
    /// Messages decoded.
    pub messages: u64,
    /// Frames or bodies refused (any [`ProtocolError`]).
    pub refused: u64,
    /// Frames the sender numbered but that never arrived (gaps in `seq`).
    pub lost: u64,
}

/// Turns a byte stream from one device into messages.
#[derive(Debug, Default)]
pub struct Decoder {
    frames: FrameReader,
    last_seq: Option<u8>,
    counters: DecoderCounters,
}

impl Decoder {
    /// A decoder at the start of a stream (or after a reconnection).
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes a chunk of the stream: each message it completes, with its
    /// sequence number, or why a frame was refused, in order.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<Result<(u8, Message), ProtocolError>> {
        self.counters.bytes += bytes.len() as u64;
        let mut out = Vec::new();
        for body in self.frames.feed(bytes) {
            let decoded = body
                .map_err(ProtocolError::from)
                .and_then(|b| Message::decode(&b).map_err(ProtocolError::from));
            match &decoded {
                Ok((seq, _)) => {
                    self.counters.messages += 1;
                    if let Some(last) = self.last_seq {
                        self.counters.lost += u64::from(seq.wrapping_sub(last).wrapping_sub(1));
                    }
                    self.last_seq = Some(*seq);
                }
                Err(_) => self.counters.refused += 1,
            }
            out.push(decoded);
        }
        out
    }

    /// What it has seen so far.
    pub fn counters(&self) -> DecoderCounters {
        self.counters
    }
}

/// Numbers and frames outgoing messages.
#[derive(Debug, Default)]
pub struct Encoder {
    seq: u8,
}

impl Encoder {
    /// An encoder whose first frame is number 0.
    pub fn new() -> Self {
        Self::default()
    }

    /// The sequence number the next frame will carry.
    pub fn next_seq(&self) -> u8 {
        self.seq
    }

    /// The wire bytes of `message`, numbered with the next sequence number.
    pub fn frame(&mut self, message: &Message) -> Vec<u8> {
        let bytes = encode_frame(&message.encode(self.seq));
        self.seq = self.seq.wrapping_add(1);
        bytes
    }
}
