//! Where the MSU's arrivals come from, chosen when the agent starts
//! (`ickon-msu --receivers`). Today the simulated world publishes them on
//! `robot/<id>/ultrasound`; a hardware receiver ring adds a variant that
//! reads its device and yields the same [`UltrasoundArrivals`].

use clap::ValueEnum;
use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::robot::UltrasoundArrivals;
use ickon_proto::{DecodeError, decode};
use ickon_runtime::{NodeError, zerr};
use zenoh::Session;
use zenoh::pubsub::Subscriber;

/// Which receiver source the agent uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum ReceiverKind {
    /// The simulated world's arrivals on `robot/<id>/ultrasound`.
    #[default]
    Sim,
}

/// An open receiver source; it hands each cycle's arrivals to the sink it
/// was opened with (`Err(..)` for a message that does not decode, to count
/// and drop), in the order they come, until it is dropped.
pub enum ReceiverSource {
    /// Arrivals from the simulated world, over Zenoh.
    Sim(Subscriber<()>),
}

impl ReceiverSource {
    /// Opens the source `kind` for `robot`, delivering to `sink`.
    pub async fn open(
        kind: ReceiverKind,
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
        }
    }
}
