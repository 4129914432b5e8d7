//! What every receiver source hands on and shares with the agent's
//! status: the types [`crate::receivers`] and the sources it opens
//! ([`crate::board_receivers`], [`crate::marvelmind_receivers`]) both use.

use ickon_proto::DecodeError;
use ickon_proto::msg::robot::{Imu, Odometry, UltrasoundArrivals};

use crate::hedgehog::HedgehogInput;

/// What a receiver source hands on.
#[derive(Debug)]
pub enum ReceiverInput {
    /// One cycle's arrivals (`Err(..)` for a message that does not decode,
    /// to count and drop).
    Arrivals(Result<UltrasoundArrivals, DecodeError>),
    /// A ranging kit's distances or position.
    Ranging(HedgehogInput),
    /// The robot's wheel ticks, from a receiver board that reports them.
    Odometry(Odometry),
    /// The robot's gyro, from a receiver board that reports it.
    Imu(Imu),
}

/// A source's state in a line, written by its task and read by the
/// agent's status.
#[derive(Debug, Clone, Default)]
pub struct SharedSummary(std::sync::Arc<std::sync::Mutex<String>>);

impl SharedSummary {
    /// The line last written.
    pub fn get(&self) -> String {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// Replaces the line.
    pub fn set(&self, line: String) {
        *self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = line;
    }
}
