//! What the hedgehog's packets say, and their layouts.
//!
//! Every layout below is the one Marvelmind's own parser reads
//! (`MarvelmindRobotics/marvelmind.c`, `src/marvelmind.c`: the
//! `process_*_datagram` functions, with the expected lengths of
//! `Marvelmind_Thread_`) and Marvelmind's interface document describes.
//! Offsets are into the payload; integers are little-endian. Packets whose
//! code ends in `0x8_` carry a 64-bit real-time stamp where the older ones
//! carry a 32-bit counter, 4 bytes more; their parser accepts any length,
//! so here they need only the bytes the layout reads.

use crate::frame::{Frame, encode_frame};
// The codes, their lengths and the error live apart so that the framing
// can check a length without depending on the packets.
pub use crate::codes::{
    BEACON_POSITIONS_CM, BEACON_POSITIONS_MM, FUSED_IMU, FUSED_IMU_REAL_TIME, POSITION_CM,
    POSITION_MM, POSITION_MM_REAL_TIME, PacketError, QUALITY, RAW_DISTANCES,
    RAW_DISTANCES_REAL_TIME, RAW_IMU, RAW_IMU_REAL_TIME, TELEMETRY, length_fits,
};

/// The hedgehog's time of a measurement, as it writes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HedgeTime {
    /// The 32-bit counter of the older packets (milliseconds on current
    /// firmware; the position packets say so in their flags).
    Counter(u32),
    /// The 64-bit real time of the `0x8_` packets, milliseconds.
    RealTime(i64),
}

/// Where the hedgehog says it is (codes `0x0001`, `0x0011`, `0x0081`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Position {
    /// When.
    pub time: HedgeTime,
    /// Coordinates in the kit's frame, millimetres (`0x0001` has
    /// centimetres on the wire).
    pub x_mm: i32,
    /// See `x_mm`.
    pub y_mm: i32,
    /// See `x_mm`.
    pub z_mm: i32,
    /// Bit 0: the position is not available; bit 1: the 32-bit time is in
    /// milliseconds.
    pub flags: u8,
    /// The hedgehog's address.
    pub address: u8,
    /// The paired heading as written: bits 0-11 in tenths of a degree.
    pub heading_raw: u16,
}

impl Position {
    /// Whether the kit had a position (flag bit 0 clear).
    pub fn available(&self) -> bool {
        self.flags & 1 == 0
    }

    /// The paired heading, degrees.
    pub fn heading_deg(&self) -> f64 {
        f64::from(self.heading_raw & 0x0fff) / 10.0
    }
}

/// One stationary beacon's position (codes `0x0002`, `0x0012`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BeaconPosition {
    /// The beacon's address.
    pub address: u8,
    /// Coordinates in the kit's frame, millimetres.
    pub x_mm: i32,
    /// See `x_mm`.
    pub y_mm: i32,
    /// See `x_mm`.
    pub z_mm: i32,
}

/// One raw distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BeaconDistance {
    /// The beacon's address (0 when the slot is unused).
    pub beacon: u8,
    /// Distance from the beacon to the hedgehog, millimetres (0 when not
    /// measured).
    pub distance_mm: u32,
}

/// Distances the hedgehog measured to up to four beacons in one
/// ultrasound cycle (codes `0x0004`, `0x0084`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawDistances {
    /// The hedgehog's address.
    pub hedge: u8,
    /// The four slots, in the order written.
    pub distances: [BeaconDistance; 4],
    /// When the packet was written.
    pub time: HedgeTime,
    /// How long before `time` the distances were measured, milliseconds.
    pub time_shift_ms: u16,
}

/// The hedgehog's raw inertial sensors (codes `0x0003`, `0x0083`), in the
/// sensors' own units (see the MSU's Marvelmind settings for the scales).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawImu {
    /// Accelerometer x, y, z.
    pub accel: [i16; 3],
    /// Gyroscope x, y, z.
    pub gyro: [i16; 3],
    /// Compass x, y, z.
    pub compass: [i16; 3],
    /// When.
    pub time: HedgeTime,
}

/// The kit's own fusion of ultrasound and IMU (codes `0x0005`, `0x0085`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FusedImu {
    /// Position, millimetres.
    pub position_mm: [i32; 3],
    /// Attitude quaternion w, x, y, z, scaled to 10000.
    pub quaternion: [i16; 4],
    /// Velocity, millimetres per second.
    pub velocity_mm_s: [i16; 3],
    /// Acceleration, millimetres per second squared.
    pub accel_mm_s2: [i16; 3],
    /// When.
    pub time: HedgeTime,
}

/// Positioning quality (code `0x0007`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Quality {
    /// The hedgehog's address.
    pub address: u8,
    /// Quality, percent.
    pub percent: u8,
}

/// Battery and radio (code `0x0006`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Telemetry {
    /// Battery voltage, millivolts.
    pub battery_mv: u16,
    /// Radio signal strength, dBm.
    pub rssi_dbm: i8,
}

/// One decoded packet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Packet {
    /// Where the hedgehog says it is.
    Position(Position),
    /// Where the stationary beacons are.
    BeaconPositions(Vec<BeaconPosition>),
    /// Raw distances to beacons.
    RawDistances(RawDistances),
    /// Raw inertial sensors.
    RawImu(RawImu),
    /// The kit's IMU fusion.
    FusedImu(FusedImu),
    /// Positioning quality.
    Quality(Quality),
    /// Battery and radio.
    Telemetry(Telemetry),
}

/// Little-endian reads from a payload whose length was checked first.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn u8(&self, at: usize) -> u8 {
        self.0[at]
    }
    fn u16(&self, at: usize) -> u16 {
        u16::from_le_bytes([self.0[at], self.0[at + 1]])
    }
    fn i16(&self, at: usize) -> i16 {
        i16::from_le_bytes([self.0[at], self.0[at + 1]])
    }
    fn u32(&self, at: usize) -> u32 {
        u32::from_le_bytes(std::array::from_fn(|k| self.0[at + k]))
    }
    fn i32(&self, at: usize) -> i32 {
        i32::from_le_bytes(std::array::from_fn(|k| self.0[at + k]))
    }
    fn i64(&self, at: usize) -> i64 {
        i64::from_le_bytes(std::array::from_fn(|k| self.0[at + k]))
    }
    fn i16x3(&self, at: usize) -> [i16; 3] {
        std::array::from_fn(|k| self.i16(at + 2 * k))
    }
}

impl Packet {
    /// What `frame` says; `Ok(None)` for a code this crate does not read
    /// (skipped by its length).
    pub fn decode(frame: &Frame) -> Result<Option<Packet>, PacketError> {
        let code = frame.code;
        let len = frame.payload.len();
        if u8::try_from(len).map_or(true, |l| !length_fits(code, l)) {
            return Err(PacketError::Length { code, len });
        }
        let r = Reader(&frame.payload);
        let packet = match code {
            POSITION_CM => Packet::Position(Position {
                time: HedgeTime::Counter(r.u32(0)),
                x_mm: i32::from(r.i16(4)) * 10,
                y_mm: i32::from(r.i16(6)) * 10,
                z_mm: i32::from(r.i16(8)) * 10,
                flags: r.u8(10),
                address: r.u8(11),
                heading_raw: r.u16(12),
            }),
            POSITION_MM => Packet::Position(position_mm(&r, 4, HedgeTime::Counter(r.u32(0)))),
            POSITION_MM_REAL_TIME => {
                Packet::Position(position_mm(&r, 8, HedgeTime::RealTime(r.i64(0))))
            }
            BEACON_POSITIONS_CM | BEACON_POSITIONS_MM => {
                Packet::BeaconPositions(beacon_positions(code, &frame.payload)?)
            }
            RAW_DISTANCES => raw_distances(&r, HedgeTime::Counter(r.u32(25)), 29),
            RAW_DISTANCES_REAL_TIME => raw_distances(&r, HedgeTime::RealTime(r.i64(25)), 33),
            RAW_IMU => raw_imu(&r, HedgeTime::Counter(r.u32(24))),
            RAW_IMU_REAL_TIME => raw_imu(&r, HedgeTime::RealTime(r.i64(24))),
            FUSED_IMU => fused_imu(&r, HedgeTime::Counter(r.u32(34))),
            FUSED_IMU_REAL_TIME => fused_imu(&r, HedgeTime::RealTime(r.i64(34))),
            QUALITY => Packet::Quality(Quality {
                address: r.u8(0),
                percent: r.u8(1),
            }),
            TELEMETRY => Packet::Telemetry(Telemetry {
                battery_mv: r.u16(0),
                rssi_dbm: i8::from_le_bytes([r.u8(2)]),
            }),
            _ => return Ok(None),
        };
        Ok(Some(packet))
    }

    /// Writes this packet as one frame, in the millimetre layouts; a
    /// [`HedgeTime::RealTime`] time selects the `0x8_` code.
    pub fn encode(&self) -> Result<Vec<u8>, PacketError> {
        let (code, payload) = match self {
            Packet::Position(p) => encode_position(p),
            Packet::BeaconPositions(beacons) => {
                let count = u8::try_from(beacons.len()).map_err(|_| PacketError::TooLong {
                    code: BEACON_POSITIONS_MM,
                    bytes: 1 + 14 * beacons.len(),
                })?;
                let mut w = vec![count];
                for b in beacons {
                    w.push(b.address);
                    for v in [b.x_mm, b.y_mm, b.z_mm] {
                        w.extend_from_slice(&v.to_le_bytes());
                    }
                    w.push(0);
                }
                (BEACON_POSITIONS_MM, w)
            }
            Packet::RawDistances(d) => encode_raw_distances(d),
            Packet::RawImu(imu) => encode_raw_imu(imu),
            Packet::FusedImu(f) => encode_fused_imu(f),
            Packet::Quality(q) => {
                let mut w = vec![0; 16];
                w[0] = q.address;
                w[1] = q.percent;
                (QUALITY, w)
            }
            Packet::Telemetry(t) => {
                let mut w = vec![0; 16];
                w[..2].copy_from_slice(&t.battery_mv.to_le_bytes());
                w[2] = t.rssi_dbm.to_le_bytes()[0];
                (TELEMETRY, w)
            }
        };
        encode_frame(code, &payload)
    }
}

fn position_mm(r: &Reader, at: usize, time: HedgeTime) -> Position {
    Position {
        time,
        x_mm: r.i32(at),
        y_mm: r.i32(at + 4),
        z_mm: r.i32(at + 8),
        flags: r.u8(at + 12),
        address: r.u8(at + 13),
        heading_raw: r.u16(at + 14),
    }
}

fn beacon_positions(code: u16, payload: &[u8]) -> Result<Vec<BeaconPosition>, PacketError> {
    let stride = if code == BEACON_POSITIONS_CM { 8 } else { 14 };
    let announced = usize::from(payload[0]);
    let held = (payload.len() - 1) / stride;
    if announced != held {
        return Err(PacketError::BeaconCount {
            code,
            announced,
            held,
        });
    }
    let r = Reader(payload);
    Ok((0..held)
        .map(|i| {
            let at = 1 + i * stride;
            if code == BEACON_POSITIONS_CM {
                BeaconPosition {
                    address: r.u8(at),
                    x_mm: i32::from(r.i16(at + 1)) * 10,
                    y_mm: i32::from(r.i16(at + 3)) * 10,
                    z_mm: i32::from(r.i16(at + 5)) * 10,
                }
            } else {
                BeaconPosition {
                    address: r.u8(at),
                    x_mm: r.i32(at + 1),
                    y_mm: r.i32(at + 5),
                    z_mm: r.i32(at + 9),
                }
            }
        })
        .collect())
}

fn raw_distances(r: &Reader, time: HedgeTime, shift_at: usize) -> Packet {
    Packet::RawDistances(RawDistances {
        hedge: r.u8(0),
        distances: std::array::from_fn(|i| BeaconDistance {
            beacon: r.u8(1 + 6 * i),
            distance_mm: r.u32(2 + 6 * i),
        }),
        time,
        time_shift_ms: r.u16(shift_at),
    })
}

fn raw_imu(r: &Reader, time: HedgeTime) -> Packet {
    Packet::RawImu(RawImu {
        accel: r.i16x3(0),
        gyro: r.i16x3(6),
        compass: r.i16x3(12),
        time,
    })
}

fn fused_imu(r: &Reader, time: HedgeTime) -> Packet {
    Packet::FusedImu(FusedImu {
        position_mm: std::array::from_fn(|k| r.i32(4 * k)),
        quaternion: std::array::from_fn(|k| r.i16(12 + 2 * k)),
        velocity_mm_s: r.i16x3(20),
        accel_mm_s2: r.i16x3(26),
        time,
    })
}

/// Writes `time` at `at` (4 or 8 bytes) and says which code it selects.
fn put_time(w: &mut [u8], at: usize, time: HedgeTime, counter: u16, real: u16) -> u16 {
    match time {
        HedgeTime::Counter(t) => {
            w[at..at + 4].copy_from_slice(&t.to_le_bytes());
            counter
        }
        HedgeTime::RealTime(t) => {
            w[at..at + 8].copy_from_slice(&t.to_le_bytes());
            real
        }
    }
}

fn encode_position(p: &Position) -> (u16, Vec<u8>) {
    let (at, len) = match p.time {
        HedgeTime::Counter(_) => (4, 22),
        HedgeTime::RealTime(_) => (8, 26),
    };
    let mut w = vec![0; len];
    let code = put_time(&mut w, 0, p.time, POSITION_MM, POSITION_MM_REAL_TIME);
    for (k, v) in [p.x_mm, p.y_mm, p.z_mm].into_iter().enumerate() {
        w[at + 4 * k..at + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
    w[at + 12] = p.flags;
    w[at + 13] = p.address;
    w[at + 14..at + 16].copy_from_slice(&p.heading_raw.to_le_bytes());
    (code, w)
}

fn encode_raw_distances(d: &RawDistances) -> (u16, Vec<u8>) {
    let (len, shift_at) = match d.time {
        HedgeTime::Counter(_) => (32, 29),
        HedgeTime::RealTime(_) => (36, 33),
    };
    let mut w = vec![0; len];
    w[0] = d.hedge;
    for (i, item) in d.distances.iter().enumerate() {
        w[1 + 6 * i] = item.beacon;
        w[2 + 6 * i..6 + 6 * i].copy_from_slice(&item.distance_mm.to_le_bytes());
    }
    let code = put_time(&mut w, 25, d.time, RAW_DISTANCES, RAW_DISTANCES_REAL_TIME);
    w[shift_at..shift_at + 2].copy_from_slice(&d.time_shift_ms.to_le_bytes());
    (code, w)
}

fn put_i16s(w: &mut [u8], at: usize, values: &[i16]) {
    for (k, v) in values.iter().enumerate() {
        w[at + 2 * k..at + 2 * k + 2].copy_from_slice(&v.to_le_bytes());
    }
}

fn encode_raw_imu(imu: &RawImu) -> (u16, Vec<u8>) {
    let mut w = vec![0; 32];
    put_i16s(&mut w, 0, &imu.accel);
    put_i16s(&mut w, 6, &imu.gyro);
    put_i16s(&mut w, 12, &imu.compass);
    let code = put_time(&mut w, 24, imu.time, RAW_IMU, RAW_IMU_REAL_TIME);
    (code, w)
}

fn encode_fused_imu(f: &FusedImu) -> (u16, Vec<u8>) {
    let mut w = vec![0; 42];
    for (k, v) in f.position_mm.iter().enumerate() {
        w[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
    put_i16s(&mut w, 12, &f.quaternion);
    put_i16s(&mut w, 20, &f.velocity_mm_s);
    put_i16s(&mut w, 26, &f.accel_mm_s2);
    let code = put_time(&mut w, 34, f.time, FUSED_IMU, FUSED_IMU_REAL_TIME);
    (code, w)
}
