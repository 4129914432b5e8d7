//! The hedgehog's packet codes, the payload length each allows, and why a
//! packet could not be read or written: what the framing and the packets
//! both need (re-exported by [`crate::packet`]).

/// Position of the hedgehog, centimetres, 32-bit time (16 bytes).
pub const POSITION_CM: u16 = 0x0001;
/// Stationary beacons' positions, centimetres (1 + 8 per beacon).
pub const BEACON_POSITIONS_CM: u16 = 0x0002;
/// Raw IMU: accelerometer, gyroscope, compass (32 bytes).
pub const RAW_IMU: u16 = 0x0003;
/// Raw distances to up to four beacons (32 bytes).
pub const RAW_DISTANCES: u16 = 0x0004;
/// The kit's IMU fusion: position, attitude, velocity, acceleration (42).
pub const FUSED_IMU: u16 = 0x0005;
/// Battery voltage and radio strength (16 bytes).
pub const TELEMETRY: u16 = 0x0006;
/// Positioning quality (16 bytes).
pub const QUALITY: u16 = 0x0007;
/// Position of the hedgehog, millimetres, 32-bit time (22 bytes).
pub const POSITION_MM: u16 = 0x0011;
/// Stationary beacons' positions, millimetres (1 + 14 per beacon).
pub const BEACON_POSITIONS_MM: u16 = 0x0012;
/// [`POSITION_MM`] with a 64-bit real-time stamp.
pub const POSITION_MM_REAL_TIME: u16 = 0x0081;
/// [`RAW_IMU`] with a 64-bit real-time stamp.
pub const RAW_IMU_REAL_TIME: u16 = 0x0083;
/// [`RAW_DISTANCES`] with a 64-bit real-time stamp.
pub const RAW_DISTANCES_REAL_TIME: u16 = 0x0084;
/// [`FUSED_IMU`] with a 64-bit real-time stamp.
pub const FUSED_IMU_REAL_TIME: u16 = 0x0085;

/// Whether a payload of `len` bytes fits packet `code`'s layout. Unknown
/// codes fit any length: they are skipped by it.
pub fn length_fits(code: u16, len: u8) -> bool {
    let len = usize::from(len);
    match code {
        POSITION_CM | TELEMETRY | QUALITY => len == 16,
        POSITION_MM => len == 22,
        RAW_IMU | RAW_DISTANCES => len == 32,
        FUSED_IMU => len == 42,
        POSITION_MM_REAL_TIME => len >= 24,
        RAW_IMU_REAL_TIME => len >= 32,
        RAW_DISTANCES_REAL_TIME => len >= 35,
        FUSED_IMU_REAL_TIME => len >= 42,
        BEACON_POSITIONS_CM => len >= 1 && (len - 1) % 8 == 0,
        BEACON_POSITIONS_MM => len >= 1 && (len - 1) % 14 == 0,
        _ => true,
    }
}

/// Why a packet could not be read or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// The payload's length does not fit the code's layout.
    #[error("packet 0x{code:04x} has {len} byte(s), which its layout does not allow")]
    Length {
        /// The packet code.
        code: u16,
        /// The payload length.
        len: usize,
    },
    /// A beacon-positions packet announces another number of beacons than
    /// its length holds.
    #[error("packet 0x{code:04x} announces {announced} beacon(s) but holds {held}")]
    BeaconCount {
        /// The packet code.
        code: u16,
        /// The count in its first byte.
        announced: usize,
        /// The count its length holds.
        held: usize,
    },
    /// A payload to write is longer than a frame's length byte allows.
    #[error("packet 0x{code:04x} would need {bytes} bytes of payload; a frame holds 255")]
    TooLong {
        /// The packet code.
        code: u16,
        /// The payload's length.
        bytes: usize,
    },
}
