//! Where the MSU's arrivals come from, chosen when the agent starts
//! (`ickon-msu --receivers`): the simulated world's, published on
//! `robot/<id>/ultrasound`, or a receiver board of the device protocol
//! ([`crate::board_receivers`]), both as the same [`UltrasoundArrivals`].

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::robot::UltrasoundArrivals;
use ickon_proto::{DecodeError, decode};
use ickon_runtime::link::LinkAddress;
use ickon_runtime::{NodeError, SimulatedClock, zerr};
use zenoh::Session;
use zenoh::pubsub::Subscriber;

use crate::board_receivers::BoardReceivers;

/// Which receiver source the agent uses.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ReceiverKind {
    /// The simulated world's arrivals on `robot/<id>/ultrasound`.
    #[default]
    Sim,
    /// A receiver board of the device protocol at this address.
    Board(LinkAddress),
}

impl std::str::FromStr for ReceiverKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "sim" {
            return Ok(ReceiverKind::Sim);
        }
        s.parse()
            .map(ReceiverKind::Board)
            .map_err(|e| format!("{e} (or `sim`)"))
    }
}

impl std::fmt::Display for ReceiverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReceiverKind::Sim => f.write_str("sim"),
            ReceiverKind::Board(a) => a.fmt(f),
        }
    }
}

/// An open receiver source; it hands each cycle's arrivals to the sink it
/// was opened with (`Err(..)` for a message that does not decode, to count
/// and drop), in the order they come, until it is dropped.
pub enum ReceiverSource {
    /// Arrivals from the simulated world, over Zenoh.
    Sim(Subscriber<()>),
    /// Arrivals from a receiver board.
    Board(BoardReceivers),
}

impl ReceiverSource {
    /// Opens the source `kind` for `robot` (whose clock is `clock`),
    /// delivering to `sink`.
    pub async fn open(
        kind: ReceiverKind,
        clock: SimulatedClock,
        session: &Session,
        keys: &Keys,
        robot: &str,
        sink: impl Fn(Result<UltrasoundArrivals, DecodeError>) + Send + Sync + 'static,
    ) -> Result<Self, NodeError> {
        match kind {
            ReceiverKind::Sim => Ok(Self::Sim(
                session
                    .declare_subscriber(keys.robot(robot, RobotTopic::Ultrasound)?)
                    .callback(move |sample| {
                        sink(decode::<UltrasoundArrivals>(&sample.payload().to_bytes()))
                    })
                    .await
                    .map_err(zerr)?,
            )),
            ReceiverKind::Board(address) => Ok(Self::Board(BoardReceivers::open(
                robot, address, clock, sink,
            ))),
        }
    }
}
