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
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

/// Which receiver source the agent uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum ReceiverKind {
    /// The simulated world's arrivals on `robot/<id>/ultrasound`.
    #[default]
    Sim,
}

/// An open receiver source.
pub enum ReceiverSource {
    /// Arrivals from the simulated world, over Zenoh.
    Sim(Subscriber<FifoChannelHandler<Sample>>),
}

impl ReceiverSource {
    /// Opens the source `kind` for `robot`.
    pub async fn open(
        kind: ReceiverKind,
        session: &Session,
        keys: &Keys,
        robot: &str,
    ) -> Result<Self, NodeError> {
        match kind {
            ReceiverKind::Sim => Ok(Self::Sim(
                session
                    .declare_subscriber(keys.robot(robot, RobotTopic::Ultrasound)?)
                    .await
                    .map_err(zerr)?,
            )),
        }
    }

    /// The next cycle's arrivals; `Some(Err(..))` for a message that does
    /// not decode (to count and drop), `None` once the source has closed.
    pub async fn recv(&self) -> Option<Result<UltrasoundArrivals, DecodeError>> {
        match self {
            Self::Sim(sub) => {
                let sample = sub.recv_async().await.ok()?;
                Some(decode::<UltrasoundArrivals>(&sample.payload().to_bytes()))
            }
        }
    }
}
