//! # ickon-device
//!
//! The ICKON device protocol, version 1 (`docs/device-protocol.md`): how a
//! host (a cell controller, an MSU agent) talks with a transmitter board or
//! a receiver board over a serial line or a TCP connection.
//!
//! - [`frame`]: COBS framing with a CRC-16, so that a reader finds the
//!   frames again after garbage;
//! - [`message`]: the messages of both boards and their bodies;
//! - [`stream`]: a [`Decoder`] from bytes to messages that counts what it
//!   refuses, and an [`Encoder`] that numbers and frames;
//! - [`clock`]: the board's clock against the host's, from clock exchanges;
//! - [`host`]: the host's side of a link as a state machine ([`BoardHost`]):
//!   handshake, clock exchanges, armed bursts, arrival groups, health.
//!
//! Nothing here does I/O or reads a clock: the links and the nodes that use
//! them sit at the edge (`ickon_runtime::link`).

pub mod clock;
pub mod frame;
pub mod host;
pub mod message;
pub mod sequence;
pub mod stream;

pub use clock::{BoardClock, ClockExchange};
pub use frame::{FrameError, FrameReader, encode_frame};
pub use host::{BoardHost, DeviceReport, HostArrival, HostEvent, HostState};
pub use message::{
    BoardArrival, BoardKind, Identify, Message, MessageError, NO_TEMPERATURE, RefusedReason,
    VERSION,
};
pub use sequence::GroupSequence;
pub use stream::{Decoder, DecoderCounters, Encoder, ProtocolError};

#[cfg(test)]
mod fuzz_decoder_tests;
#[cfg(test)]
mod resync_tests;
#[cfg(test)]
mod vectors_tests;
