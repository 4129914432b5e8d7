//! Frames of the hedgehog's stream: finding them in a byte stream that may
//! carry garbage, checking their length and CRC, and writing them.
//!
//! A frame is `0xFF` (the stream's destination address), `0x47` (the
//! packet type of streamed data), the packet code (u16, little-endian), the
//! payload length (u8), the payload, and the CRC-16/MODBUS of everything
//! before it (u16, little-endian): a frame whose CRC is computed over all
//! its bytes, CRC included, gives 0 (`marvelmind.c`, `Marvelmind_Thread_`).

use crc::{CRC_16_MODBUS, Crc};

use crate::codes::{self, PacketError};

/// The first byte of every streamed frame (the destination address the
/// hedgehog writes for its host).
pub const STREAM_ADDRESS: u8 = 0xFF;

/// The second byte of every streamed frame (packet type: streamed data).
pub const STREAM_TYPE: u8 = 0x47;

/// Bytes before the payload: address, type, code (2), length.
pub const HEADER_LEN: usize = 5;

/// The CRC after the payload.
const CRC_LEN: usize = 2;

/// The longest frame: a payload length is one byte.
pub const MAX_FRAME_LEN: usize = HEADER_LEN + u8::MAX as usize + CRC_LEN;

const MODBUS: Crc<u16> = Crc::<u16>::new(&CRC_16_MODBUS);

/// CRC-16/MODBUS of `bytes` (polynomial 0x8005 reflected, initial 0xFFFF).
pub fn crc16_modbus(bytes: &[u8]) -> u16 {
    MODBUS.checksum(bytes)
}

/// One frame whose length fits its code and whose CRC holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// The packet code.
    pub code: u16,
    /// The payload (at most 255 bytes).
    pub payload: Vec<u8>,
}

/// Something in the stream that is not a usable frame. The deframer has
/// already resynchronised past it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Bytes that do not start a frame were skipped.
    #[error("{bytes} byte(s) of garbage skipped")]
    Garbage {
        /// How many bytes were skipped.
        bytes: usize,
    },
    /// A frame's payload length does not fit its packet code.
    #[error("packet 0x{code:04x} announces {len} byte(s), which its layout does not allow")]
    BadLength {
        /// The packet code.
        code: u16,
        /// The announced payload length.
        len: u8,
    },
    /// A frame's CRC does not match its bytes.
    #[error("packet 0x{code:04x} fails its CRC")]
    BadCrc {
        /// The packet code the (corrupt) header announced.
        code: u16,
    },
}

/// What the deframer has seen since it was made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeframeStats {
    /// Frames delivered.
    pub frames: u64,
    /// Bytes skipped as garbage.
    pub garbage_bytes: u64,
    /// Frames refused for a length their code does not allow.
    pub bad_length: u64,
    /// Frames refused for their CRC.
    pub bad_crc: u64,
}

/// Finds frames in the bytes of a stream, however they are cut into reads.
///
/// It holds at most one frame's bytes between calls, whatever it is fed:
/// garbage is dropped as soon as it cannot start a frame, and a frame that
/// fails its length or CRC check gives up only its first byte, so a real
/// frame hidden behind a false start is still found.
#[derive(Debug, Default)]
pub struct Deframer {
    pending: Vec<u8>,
    garbage_run: usize,
    stats: DeframeStats,
}

impl Deframer {
    /// A deframer that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// What it has seen so far.
    pub fn stats(&self) -> DeframeStats {
        self.stats
    }

    /// Bytes held while waiting for the rest of a frame (less than
    /// [`MAX_FRAME_LEN`] after every [`Deframer::feed`]).
    pub fn buffered(&self) -> usize {
        self.pending.len()
    }

    /// Feeds `bytes` read from the stream; every frame found and every
    /// refusal goes to `sink`, in stream order.
    pub fn feed(&mut self, bytes: &[u8], mut sink: impl FnMut(Result<Frame, FrameError>)) {
        // Taken a frame's length at a time so that `pending` stays bounded
        // whatever a read returns.
        for chunk in bytes.chunks(MAX_FRAME_LEN) {
            self.pending.extend_from_slice(chunk);
            self.drain(&mut sink);
        }
    }

    fn drain(&mut self, sink: &mut impl FnMut(Result<Frame, FrameError>)) {
        loop {
            let start = sync_position(&self.pending);
            if start > 0 {
                self.skip(start);
            }
            if self.pending.len() < HEADER_LEN {
                return;
            }
            self.flush_garbage(sink);
            let code = u16::from_le_bytes([self.pending[2], self.pending[3]]);
            let len = self.pending[4];
            if !codes::length_fits(code, len) {
                self.stats.bad_length += 1;
                sink(Err(FrameError::BadLength { code, len }));
                self.pending.drain(..1);
                continue;
            }
            let total = HEADER_LEN + usize::from(len) + CRC_LEN;
            if self.pending.len() < total {
                return;
            }
            if crc16_modbus(&self.pending[..total]) != 0 {
                self.stats.bad_crc += 1;
                sink(Err(FrameError::BadCrc { code }));
                self.pending.drain(..1);
                continue;
            }
            let payload = self.pending[HEADER_LEN..HEADER_LEN + usize::from(len)].to_vec();
            self.pending.drain(..total);
            self.stats.frames += 1;
            sink(Ok(Frame { code, payload }));
        }
    }

    /// Drops `n` bytes from the front as garbage.
    fn skip(&mut self, n: usize) {
        self.pending.drain(..n);
        self.garbage_run += n;
        self.stats.garbage_bytes += n as u64;
    }

    /// Reports a run of garbage once a frame header ends it.
    fn flush_garbage(&mut self, sink: &mut impl FnMut(Result<Frame, FrameError>)) {
        if self.garbage_run > 0 {
            sink(Err(FrameError::Garbage {
                bytes: self.garbage_run,
            }));
            self.garbage_run = 0;
        }
    }
}

/// Where the first possible frame starts in `bytes`: the first `0xFF 0x47`,
/// or a trailing `0xFF` that the next read may complete; `bytes.len()` when
/// nothing can start a frame.
fn sync_position(bytes: &[u8]) -> usize {
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == STREAM_ADDRESS {
            match bytes.get(i + 1) {
                None => return i,
                Some(&STREAM_TYPE) => return i,
                Some(_) => {}
            }
        }
        i += 1;
    }
    bytes.len()
}

/// Writes one frame: header, `payload`, CRC.
pub fn encode_frame(code: u16, payload: &[u8]) -> Result<Vec<u8>, PacketError> {
    let len = u8::try_from(payload.len()).map_err(|_| PacketError::TooLong {
        code,
        bytes: payload.len(),
    })?;
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len() + CRC_LEN);
    out.extend_from_slice(&[STREAM_ADDRESS, STREAM_TYPE]);
    out.extend_from_slice(&code.to_le_bytes());
    out.push(len);
    out.extend_from_slice(payload);
    let crc = crc16_modbus(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(deframer: &mut Deframer, bytes: &[u8]) -> Vec<Result<Frame, FrameError>> {
        let mut out = Vec::new();
        deframer.feed(bytes, |f| out.push(f));
        out
    }

    #[test]
    fn crc_is_modbus_as_the_kit_computes_it() {
        // The catalogue's check value for "123456789".
        assert_eq!(crc16_modbus(b"123456789"), 0x4B37);
        let frame = encode_frame(0x0007, &[3, 80, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0])
            .expect("short payload");
        assert_eq!(crc16_modbus(&frame), 0, "a whole frame checks to zero");
    }

    #[test]
    fn a_frame_cut_into_single_bytes_is_found_once() {
        let frame = encode_frame(0x0007, &[3; 16]).expect("short payload");
        let mut d = Deframer::new();
        let mut got = Vec::new();
        for b in &frame {
            got.extend(frames(&mut d, std::slice::from_ref(b)));
        }
        assert_eq!(
            got,
            vec![Ok(Frame {
                code: 0x0007,
                payload: vec![3; 16]
            })]
        );
        assert_eq!(d.stats().frames, 1);
    }

    #[test]
    fn garbage_before_a_frame_is_skipped_and_reported_once() {
        let frame = encode_frame(0x0007, &[1; 16]).expect("short payload");
        let mut bytes = vec![0x00, 0xFF, 0x00, 0x47, 0xFF];
        bytes.extend_from_slice(&frame);
        let got = frames(&mut Deframer::new(), &bytes);
        assert_eq!(got.len(), 2, "{got:?}");
        assert_eq!(got[0], Err(FrameError::Garbage { bytes: 5 }));
        assert!(got[1].is_ok());
    }

    #[test]
    fn a_corrupt_frame_gives_up_one_byte_and_the_next_frame_is_found() {
        let good = encode_frame(0x0007, &[2; 16]).expect("short payload");
        let mut bad = good.clone();
        bad[7] ^= 0x55;
        let mut bytes = bad;
        bytes.extend_from_slice(&good);
        let mut d = Deframer::new();
        let got = frames(&mut d, &bytes);
        assert_eq!(got[0], Err(FrameError::BadCrc { code: 0x0007 }));
        assert_eq!(
            got.last(),
            Some(&Ok(Frame {
                code: 0x0007,
                payload: vec![2; 16]
            }))
        );
        assert_eq!(d.stats().bad_crc, 1);
        assert_eq!(d.stats().frames, 1);
    }

    #[test]
    fn a_length_the_code_does_not_allow_is_refused_before_waiting_for_it() {
        // Quality is 16 bytes; 200 would make the deframer wait for bytes
        // that belong to the next frames.
        let mut bytes = vec![0xFF, 0x47, 0x07, 0x00, 200];
        let good = encode_frame(0x0007, &[4; 16]).expect("short payload");
        bytes.extend_from_slice(&good);
        let got = frames(&mut Deframer::new(), &bytes);
        assert_eq!(
            got[0],
            Err(FrameError::BadLength {
                code: 0x0007,
                len: 200
            })
        );
        assert_eq!(
            got.last(),
            Some(&Ok(Frame {
                code: 0x0007,
                payload: vec![4; 16]
            }))
        );
    }

    #[test]
    fn pending_bytes_stay_bounded_under_a_flood() {
        let mut d = Deframer::new();
        let flood: Vec<u8> = (0..1_000_000u32).map(|i| (i % 251) as u8).collect();
        d.feed(&flood, |_| {});
        assert!(d.pending.len() <= MAX_FRAME_LEN, "{}", d.pending.len());
        let frame = encode_frame(0x0007, &[5; 16]).expect("short payload");
        assert_eq!(
            frames(&mut d, &frame).last(),
            Some(&Ok(Frame {
                code: 0x0007,
                payload: vec![5; 16]
            }))
        );
    }

    #[test]
    fn a_payload_longer_than_a_length_byte_is_not_encoded() {
        assert_eq!(
            encode_frame(0x0012, &[0; 256]),
            Err(PacketError::TooLong {
                code: 0x0012,
                bytes: 256
            })
        );
    }
}
