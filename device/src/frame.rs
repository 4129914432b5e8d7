//! Framing: how a frame's body travels over a byte stream and how a reader
//! finds the frames again after garbage.
//!
//! On the wire a frame is `COBS(body ++ crc16_le(body)) ++ 0x00`. Consistent
//! Overhead Byte Stuffing removes every zero byte from the encoded bytes, so
//! `0x00` only ever ends a frame: a reader that starts in the middle of a
//! frame, or after line noise, loses at most the frame it is in and is in
//! step again at the next `0x00`. The CRC (CRC-16/IBM-3740: polynomial
//! 0x1021, initial value 0xFFFF, no reflection, no final XOR; "123456789"
//! gives 0x29B1) catches what noise leaves of a frame.
//!
//! COBS is written out here rather than taken from a crate: it is the
//! algorithm the specification (`docs/device-protocol.md`) gives to board
//! makers, in its dozen lines, and the reader must refuse every malformed
//! encoding with a reason rather than a bare failure.

use crc::{CRC_16_IBM_3740, Crc};

/// The frame check of protocol version 1.
pub const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// The byte that ends every frame (and appears nowhere else).
pub const DELIMITER: u8 = 0x00;

/// The largest body (header and payload, without the CRC), bytes. With its
/// CRC it is 254 bytes, which COBS encodes in 255 bytes with one overhead
/// byte: a board needs one 256-byte buffer per direction.
pub const MAX_BODY: usize = 252;

/// The largest encoded frame without its delimiter, bytes.
pub const MAX_ENCODED: usize = MAX_BODY + 2 + 1;

/// Why the bytes between two delimiters are not a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// More than [`MAX_ENCODED`] bytes without a delimiter: dropped up to the next one.
    #[error("frame longer than {MAX_ENCODED} bytes (dropped up to the next delimiter)")]
    Oversized,
    /// The COBS encoding is broken (a code byte points past the frame's end).
    #[error("broken COBS encoding")]
    BadEncoding,
    /// Fewer bytes than a header and a CRC.
    #[error("frame of {0} bytes is shorter than a header and a CRC")]
    Truncated(usize),
    /// The CRC does not match the body.
    #[error("CRC mismatch: frame says {got:#06x}, body gives {want:#06x}")]
    BadCrc {
        /// The CRC in the frame.
        got: u16,
        /// The CRC of the body received.
        want: u16,
    },
}

/// Encodes `body` as one frame: COBS of the body and its CRC, then the
/// delimiter. Bodies longer than [`MAX_BODY`] are the caller's error
/// (message encoders never make them); they are still encoded correctly.
pub fn encode_frame(body: &[u8]) -> Vec<u8> {
    let mut raw = Vec::with_capacity(body.len() + 2);
    raw.extend_from_slice(body);
    raw.extend_from_slice(&CRC16.checksum(body).to_le_bytes());
    let mut out = cobs_encode(&raw);
    out.push(DELIMITER);
    out
}

/// COBS encoding of `raw` (no delimiter): each run of up to 254 non-zero
/// bytes is preceded by a code byte, one more than the run's length; a code
/// under 0xFF stands for the run followed by a zero, and the final zero
/// that every encoding implies is dropped.
pub fn cobs_encode(raw: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(raw.len() + raw.len() / 254 + 2);
    let mut code_at = 0;
    out.push(0);
    let mut code: u8 = 1;
    for &b in raw {
        if b == 0 {
            out[code_at] = code;
            code_at = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_at] = code;
    out
}

/// Decodes one COBS-encoded frame (without its delimiter).
pub fn cobs_decode(encoded: &[u8]) -> Result<Vec<u8>, FrameError> {
    if encoded.is_empty() {
        // Even an empty input encodes to one code byte.
        return Err(FrameError::BadEncoding);
    }
    let mut out = Vec::with_capacity(encoded.len());
    let mut i = 0;
    while i < encoded.len() {
        let code = encoded[i];
        if code == 0 {
            return Err(FrameError::BadEncoding);
        }
        let run = usize::from(code) - 1;
        let end = i + 1 + run;
        let bytes = encoded.get(i + 1..end).ok_or(FrameError::BadEncoding)?;
        if bytes.contains(&0) {
            return Err(FrameError::BadEncoding);
        }
        out.extend_from_slice(bytes);
        i = end;
        if code < 0xFF && i < encoded.len() {
            out.push(0);
        }
    }
    Ok(out)
}

/// Checks and strips the CRC of a decoded frame: its body.
pub fn check_crc(raw: &[u8]) -> Result<&[u8], FrameError> {
    if raw.len() < 2 + crate::message::HEADER_LEN {
        return Err(FrameError::Truncated(raw.len()));
    }
    let (body, crc) = raw.split_at(raw.len() - 2);
    let got = u16::from_le_bytes([crc[0], crc[1]]);
    let want = CRC16.checksum(body);
    if got == want {
        Ok(body)
    } else {
        Err(FrameError::BadCrc { got, want })
    }
}

/// Finds frames in a byte stream, whatever it is cut into and whatever
/// garbage it carries. Its memory is bounded by [`MAX_ENCODED`].
#[derive(Debug, Default)]
pub struct FrameReader {
    buf: Vec<u8>,
    /// Dropping bytes up to the next delimiter (after an oversized frame).
    skipping: bool,
}

impl FrameReader {
    /// A reader at the start of a stream.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one byte; at a delimiter, what was between it and the last one:
    /// a frame's body, or why it is not one. Empty frames (two delimiters
    /// in a row, as a sender may send to flush a line) yield nothing.
    pub fn push(&mut self, byte: u8) -> Option<Result<Vec<u8>, FrameError>> {
        if byte != DELIMITER {
            if self.skipping {
                return None;
            }
            if self.buf.len() == MAX_ENCODED {
                self.buf.clear();
                self.skipping = true;
                return Some(Err(FrameError::Oversized));
            }
            self.buf.push(byte);
            return None;
        }
        if std::mem::take(&mut self.skipping) || self.buf.is_empty() {
            self.buf.clear();
            return None;
        }
        let encoded = std::mem::take(&mut self.buf);
        Some(cobs_decode(&encoded).and_then(|raw| check_crc(&raw).map(<[u8]>::to_vec)))
    }

    /// Takes a chunk of the stream: every frame (or refusal) it completes, in order.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
        bytes.iter().filter_map(|&b| self.push(b)).collect()
    }

    /// Bytes held of the frame being read.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_is_the_catalogued_ibm_3740() {
        assert_eq!(CRC16.checksum(b"123456789"), 0x29B1);
    }

    #[test]
    fn cobs_matches_the_published_examples() {
        // The examples of Cheshire and Baker's paper (and Wikipedia's table).
        let cases: [(&[u8], &[u8]); 5] = [
            (&[0x00], &[0x01, 0x01]),
            (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
            (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
            (&[0x11, 0x22, 0x33, 0x44], &[0x05, 0x11, 0x22, 0x33, 0x44]),
            (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
        ];
        for (raw, encoded) in cases {
            assert_eq!(cobs_encode(raw), encoded, "{raw:02x?}");
            assert_eq!(cobs_decode(encoded).unwrap(), raw, "{encoded:02x?}");
        }
    }

    #[test]
    fn cobs_round_trips_long_runs_without_zeros() {
        for len in [0, 1, 253, 254, 255, 256, 600] {
            let raw: Vec<u8> = (0..len).map(|i| (i % 255 + 1) as u8).collect();
            let encoded = cobs_encode(&raw);
            assert!(!encoded.contains(&0));
            assert_eq!(cobs_decode(&encoded).unwrap(), raw, "len {len}");
        }
    }

    #[test]
    fn refuses_a_code_that_points_past_the_end() {
        assert_eq!(cobs_decode(&[0x05, 1, 2]), Err(FrameError::BadEncoding));
    }

    #[test]
    fn oversized_garbage_is_dropped_up_to_the_next_delimiter() {
        let mut r = FrameReader::new();
        let garbage = vec![0x55; 1000];
        let out = r.feed(&garbage);
        assert_eq!(out, vec![Err(FrameError::Oversized)]);
        assert_eq!(r.pending(), 0);
        let body = [1u8, 0x81, 7, 0, 0, 9];
        let mut stream = vec![DELIMITER];
        stream.extend(encode_frame(&body));
        assert_eq!(r.feed(&stream), vec![Ok(body.to_vec())]);
    }

    #[test]
    fn a_flipped_bit_is_a_crc_mismatch() {
        let mut frame = encode_frame(&[1, 0x84, 3, 10, 20, 30, 40]);
        frame[3] ^= 0x04;
        let out = FrameReader::new().feed(&frame);
        assert!(
            matches!(out[..], [Err(FrameError::BadCrc { .. })]),
            "{out:?}"
        );
    }
}
