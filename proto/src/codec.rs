//! The one encode/decode pair for every ICKON message.
//!
//! Wire format: CDR little-endian (OMG CDR as used by ROS 2/DDS), starting with
//! the 4-byte encapsulation header `00 01 00 00`; alignment is counted from
//! after the header. Decoding accepts either byte order (the header says which),
//! rejects trailing bytes, payloads larger than [`MAX_MESSAGE_BYTES`], and
//! never allocates more than the payload could hold.

use cdr::{Bounded, CdrLe, Infinite};
use serde::Serialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

/// The largest payload any ICKON message may have (the site model with its
/// floor plan is the largest; a few hundred kilobytes at most).
pub const MAX_MESSAGE_BYTES: usize = 4 * 1024 * 1024;

/// Why a value could not be encoded.
#[derive(Debug, Error)]
pub enum EncodeError {
    /// The value has a shape CDR cannot express (an `Option`, a map).
    #[error("cannot encode as CDR: {0}")]
    Unsupported(String),
    /// The encoded value would exceed [`MAX_MESSAGE_BYTES`].
    #[error("encoded message of {size} bytes exceeds the limit of {MAX_MESSAGE_BYTES} bytes")]
    TooLarge {
        /// The size it would have had.
        size: usize,
    },
}

/// Why a payload could not be decoded.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum DecodeError {
    /// Fewer bytes than the encapsulation header.
    #[error("payload of {0} bytes is shorter than the 4-byte CDR header")]
    MissingHeader(usize),
    /// A header other than plain CDR big- or little-endian.
    #[error("unsupported CDR encapsulation header {0:02x?}")]
    BadHeader([u8; 4]),
    /// The payload exceeds [`MAX_MESSAGE_BYTES`].
    #[error("payload of {0} bytes exceeds the limit of {MAX_MESSAGE_BYTES} bytes")]
    TooLarge(usize),
    /// The payload ended before the message did.
    #[error("payload truncated: the message needs more bytes than the {0} received")]
    Truncated(usize),
    /// Bytes left over after a complete message.
    #[error("{0} trailing bytes after the message")]
    TrailingBytes(usize),
    /// The bytes do not form a valid message (bad UTF-8, a bad enum tag, ...).
    #[error("malformed payload: {0}")]
    Malformed(String),
}

/// Encodes a message as CDR little-endian with its encapsulation header.
pub fn encode<T: Serialize + ?Sized>(message: &T) -> Result<Vec<u8>, EncodeError> {
    let bytes = cdr::serialize::<_, _, CdrLe>(message, Infinite)
        .map_err(|e| EncodeError::Unsupported(e.to_string()))?;
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(EncodeError::TooLarge { size: bytes.len() });
    }
    Ok(bytes)
}

/// Decodes one message from a complete payload.
pub fn decode<T: DeserializeOwned>(payload: &[u8]) -> Result<T, DecodeError> {
    if payload.len() > MAX_MESSAGE_BYTES {
        return Err(DecodeError::TooLarge(payload.len()));
    }
    let Some(header) = payload.first_chunk::<4>() else {
        return Err(DecodeError::MissingHeader(payload.len()));
    };
    // Plain CDR only: 00 00 (big-endian) or 00 01 (little-endian), options zero.
    if header[0] != 0 || header[1] > 1 || header[2] != 0 || header[3] != 0 {
        return Err(DecodeError::BadHeader(*header));
    }
    let mut reader = payload;
    let value = cdr::deserialize_from::<_, T, _>(&mut reader, Bounded(payload.len() as u64))
        .map_err(|e| classify(e, payload.len()))?;
    if !reader.is_empty() {
        return Err(DecodeError::TrailingBytes(reader.len()));
    }
    Ok(value)
}

/// A reader of one older layout of the message `T` (see [`decode_layouts`]).
pub type OlderLayout<T> = fn(&[u8]) -> Result<T, DecodeError>;

/// Reads a payload in the older layout `O` as the current message `T`:
/// one of the older layouts [`decode_layouts`] tries.
pub fn decode_older<O: DeserializeOwned + Into<T>, T>(payload: &[u8]) -> Result<T, DecodeError> {
    decode::<O>(payload).map(Into::into)
}

/// Decodes a message whose layout grew over time: the current layout
/// `T`, else each of `older` in turn (newest first, each a
/// [`decode_older`]). A payload of none fails with the current layout's
/// error, the one a sender of today needs to read. Each layout must be
/// one no other can be mistaken for (each longer than the one before).
pub fn decode_layouts<T: DeserializeOwned>(
    payload: &[u8],
    older: &[OlderLayout<T>],
) -> Result<T, DecodeError> {
    decode::<T>(payload).or_else(|current| {
        older
            .iter()
            .find_map(|read| read(payload).ok())
            .ok_or(current)
    })
}

fn classify(error: cdr::Error, len: usize) -> DecodeError {
    match error {
        cdr::Error::Io(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            DecodeError::Truncated(len)
        }
        cdr::Error::SizeLimit => DecodeError::Truncated(len),
        other => DecodeError::Malformed(other.to_string()),
    }
}
