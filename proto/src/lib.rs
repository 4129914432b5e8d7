//! # ickon-proto
//!
//! What every ICKON-rs process shares: the wire messages (serde types encoded
//! as CDR little-endian with the 4-byte encapsulation header), the Zenoh key
//! expressions, the integer-nanosecond time types, and the site model.
//!
//! - [`codec`]: the one [`encode`]/[`decode`] pair for every message.
//! - [`keys`]: the only place that spells a key expression.
//! - [`time`]: [`Time`] and [`Duration`], integer nanoseconds.
//! - [`msg`]: the messages, grouped by who sends them.
//! - [`ros`]: ROS 2 over Zenoh (rmw_zenoh and the DDS bridge): keys,
//!   liveliness tokens and the sample attachment.
//! - [`epoch`]: central unit epochs and the rules for taking a schedule.
//! - [`site`]: the site model in TOML, its validation and the built-in default site.
//! - [`text_file`]: reading a configuration-sized text file with a bound.
//!
//! Conventions: SI units inside (metres, seconds, radians); field names carry
//! their unit where it is not SI or not obvious (`drift_ppb`, `offset_ns`).

pub mod codec;
pub mod epoch;
pub mod file_issue;
pub mod keys;
pub mod msg;
pub mod ros;
pub mod site;
pub mod text_file;
pub mod time;
mod wire_string;

pub use codec::{DecodeError, EncodeError, decode, encode};
pub use time::{Duration, Time};
#[cfg(any(test, feature = "fuzz"))]
pub mod fuzz;

#[cfg(test)]
mod msg_files_tests;
