//! The wire messages, grouped by who sends them.
//!
//! Every type here is encoded with [`crate::encode`] and decoded with
//! [`crate::decode`]. CDR has no optional fields: where a value may be absent
//! the message carries an explicit `*_valid` flag, never a NaN.

pub mod admin;
pub mod control;
pub mod robot;
pub mod ros;
pub mod ros_msgs;

#[cfg(test)]
mod tests;
