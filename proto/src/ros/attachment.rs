//! The attachment rmw_zenoh puts on every sample, and drops a sample
//! without ("Unable to obtain attachment"): zenoh-ext's serialisation of
//! `(i64 sequence_number, i64 source_timestamp_ns, [u8; 16] gid)`, which is
//! 8 bytes little-endian, 8 bytes little-endian, the length byte `0x10` and
//! the 16 bytes: 33 bytes. Written by hand: it is three fixed-size fields,
//! and this module must stay free of Zenoh so that pure crates use it.

use thiserror::Error;

/// The length of the attachment in bytes.
pub const ATTACHMENT_LEN: usize = 33;

/// The zenoh-ext length prefix of a 16-byte array (a LEB128 varint).
const GID_LEN_BYTE: u8 = 16;

/// One sample's attachment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// Per publisher, from 1, one more per sample.
    pub sequence_number: i64,
    /// When the sample was published, nanoseconds since the Unix epoch.
    pub source_timestamp_ns: i64,
    /// The publisher's global id (any stable 16 bytes).
    pub gid: [u8; 16],
}

/// Why bytes are not an rmw_zenoh attachment.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum AttachmentError {
    /// Not 33 bytes (rmw_zenoh 0.2.0-0.2.3 used another layout).
    #[error("attachment of {0} bytes, expected {ATTACHMENT_LEN}")]
    Length(usize),
    /// The GID's length byte is not 16.
    #[error("attachment GID length byte {0}, expected 16")]
    GidLength(u8),
}

impl Attachment {
    /// The 33 bytes on the wire.
    pub fn to_bytes(&self) -> [u8; ATTACHMENT_LEN] {
        let mut out = [0u8; ATTACHMENT_LEN];
        out[0..8].copy_from_slice(&self.sequence_number.to_le_bytes());
        out[8..16].copy_from_slice(&self.source_timestamp_ns.to_le_bytes());
        out[16] = GID_LEN_BYTE;
        out[17..33].copy_from_slice(&self.gid);
        out
    }

    /// Reads the 33 bytes of an attachment.
    pub fn parse(bytes: &[u8]) -> Result<Self, AttachmentError> {
        let Ok(b) = <&[u8; ATTACHMENT_LEN]>::try_from(bytes) else {
            return Err(AttachmentError::Length(bytes.len()));
        };
        if b[16] != GID_LEN_BYTE {
            return Err(AttachmentError::GidLength(b[16]));
        }
        let mut seq = [0u8; 8];
        seq.copy_from_slice(&b[0..8]);
        let mut ts = [0u8; 8];
        ts.copy_from_slice(&b[8..16]);
        let mut gid = [0u8; 16];
        gid.copy_from_slice(&b[17..33]);
        Ok(Attachment {
            sequence_number: i64::from_le_bytes(seq),
            source_timestamp_ns: i64::from_le_bytes(ts),
            gid,
        })
    }
}

/// A stable 16-byte GID for a publisher, from a string naming it (its
/// liveliness token or key): two FNV-1a 64-bit hashes, so that a restarted
/// publisher keeps its GID.
pub fn gid_for(name: &str) -> [u8; 16] {
    fn fnv1a(bytes: impl Iterator<Item = u8>) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        h
    }
    let a = fnv1a(name.bytes());
    let b = fnv1a(name.bytes().chain(*b"\0gid"));
    let mut gid = [0u8; 16];
    gid[..8].copy_from_slice(&a.to_le_bytes());
    gid[8..].copy_from_slice(&b.to_le_bytes());
    gid
}

/// The attachments of one publisher: its GID and its sequence numbers.
#[derive(Debug, Clone)]
pub struct SampleStamper {
    gid: [u8; 16],
    next: i64,
}

impl SampleStamper {
    /// A publisher named `name` (see [`gid_for`]); its first sample is number 1.
    pub fn new(name: &str) -> Self {
        Self {
            gid: gid_for(name),
            next: 1,
        }
    }

    /// The attachment of the next sample, published at `now_unix_ns`.
    pub fn next(&mut self, now_unix_ns: i64) -> Attachment {
        let a = Attachment {
            sequence_number: self.next,
            source_timestamp_ns: now_unix_ns,
            gid: self.gid,
        };
        self.next = self.next.saturating_add(1);
        a
    }
}
