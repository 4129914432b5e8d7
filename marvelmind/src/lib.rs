//! The stream a Marvelmind mobile beacon ("hedgehog") writes on its USB or
//! UART port, decoded and encoded without I/O.
//!
//! A Marvelmind kit is laid out as ICKON is: stationary beacons emit
//! ultrasound and the hedgehog on the robot listens. The hedgehog streams
//! what it measures as frames `0xFF 0x47`, a 16-bit little-endian packet
//! code, a payload length, the payload and a CRC-16/MODBUS. The layouts
//! follow Marvelmind's published interface description ("Marvelmind Indoor
//! Navigation System: Interfaces", marvelmind.com) as read by Marvelmind's
//! own open-source parsers (`MarvelmindRobotics/marvelmind.c`,
//! `src/marvelmind.c` and `marvelmind.h`; `MarvelmindRobotics/marvelmind.py`);
//! each packet's layout cites its source in [`packet`].
//!
//! [`Deframer`] takes bytes as they come from the port, resynchronises
//! after garbage and yields [`Frame`]s whose CRC holds; [`Packet::decode`]
//! turns a frame into what it says; [`Packet::encode`] writes a frame (the
//! emulated hedgehog and the tests).

mod codes;
mod frame;
pub mod packet;

pub use frame::{
    DeframeStats, Deframer, Frame, FrameError, HEADER_LEN, MAX_FRAME_LEN, STREAM_ADDRESS,
    STREAM_TYPE, crc16_modbus, encode_frame,
};
pub use packet::{
    BeaconDistance, BeaconPosition, FusedImu, HedgeTime, Packet, PacketError, Position, Quality,
    RawDistances, RawImu, Telemetry,
};

#[cfg(test)]
mod fuzz_frames_tests;
#[cfg(test)]
mod vectors_tests;
