//! Where the MSU's arrivals come from, chosen when the agent starts
//! (`ickon-msu --receivers`): the simulated world's, published on
//! `robot/<id>/ultrasound`, or a receiver board of the device protocol
//! ([`crate::board_receivers`]), both as the same [`UltrasoundArrivals`];
//! or a Marvelmind hedgehog ([`crate::marvelmind_receivers`]), whose
//! distances to beacons are ranges instead of arrivals.

use ickon_fusion::estimator::WheelGeometry;
use ickon_proto::decode;
use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::robot::UltrasoundArrivals;
use ickon_runtime::link::LinkAddress;
use ickon_runtime::{NodeError, SimulatedClock, zerr};
use zenoh::Session;
use zenoh::pubsub::Subscriber;

use crate::board_receivers::BoardReceivers;
use crate::hedgehog::MarvelmindSettings;
use crate::marvelmind_receivers::{MarvelmindReceivers, RangingSite};
// Shared with the sources below, which must not import this module.
pub use crate::receiver_input::{ReceiverInput, SharedSummary};

/// Which receiver source the agent uses.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ReceiverKind {
    /// The simulated world's arrivals on `robot/<id>/ultrasound`.
    #[default]
    Sim,
    /// A receiver board of the device protocol at this address.
    Board(LinkAddress),
    /// A Marvelmind hedgehog at this address.
    Marvelmind(LinkAddress),
}

/// The prefix of a Marvelmind hedgehog's address.
const MARVELMIND: &str = "marvelmind:";

impl std::str::FromStr for ReceiverKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "sim" {
            return Ok(ReceiverKind::Sim);
        }
        if let Some(address) = s.strip_prefix(MARVELMIND) {
            return address
                .parse()
                .map(ReceiverKind::Marvelmind)
                .map_err(|e| format!("{e} (after `{MARVELMIND}`)"));
        }
        s.parse()
            .map(ReceiverKind::Board)
            .map_err(|e| format!("{e} (or `sim`, or `{MARVELMIND}` and an address)"))
    }
}

impl std::fmt::Display for ReceiverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReceiverKind::Sim => f.write_str("sim"),
            ReceiverKind::Board(a) => a.fmt(f),
            ReceiverKind::Marvelmind(a) => write!(f, "{MARVELMIND}{a}"),
        }
    }
}

/// An open receiver source; it hands what it receives to the sink it was
/// opened with, in the order it comes, until it is dropped.
pub enum ReceiverSource {
    /// Arrivals from the simulated world, over Zenoh.
    Sim(Subscriber<()>),
    /// Arrivals from a receiver board.
    Board(BoardReceivers),
    /// Distances from a Marvelmind hedgehog.
    Marvelmind(MarvelmindReceivers),
}

impl ReceiverSource {
    /// Where the source writes its state in a line for an operator (it
    /// stays empty for the simulated world's arrivals).
    pub fn summary(&self) -> SharedSummary {
        match self {
            Self::Sim(_) => SharedSummary::default(),
            Self::Board(b) => b.summary(),
            Self::Marvelmind(m) => m.summary(),
        }
    }
}

/// What a source needs besides its address: the robot, its clock, and for
/// a ranging kit the site's beacons and the kit's settings.
pub struct SourceContext<'a> {
    /// The robot's id.
    pub robot: &'a str,
    /// The agent's clock.
    pub clock: SimulatedClock,
    /// The site's speed of sound and beacons.
    pub site: RangingSite,
    /// The `[marvelmind]` block of the configuration.
    pub marvelmind: MarvelmindSettings,
    /// The robot's wheels (a receiver board's ticks become odometry).
    pub wheels: WheelGeometry,
}

impl ReceiverSource {
    /// Opens the source `kind` for the robot of `cx`, delivering to `sink`.
    pub async fn open(
        kind: ReceiverKind,
        cx: SourceContext<'_>,
        session: &Session,
        keys: &Keys,
        sink: impl Fn(ReceiverInput) + Send + Sync + 'static,
    ) -> Result<Self, NodeError> {
        let robot = cx.robot;
        match kind {
            ReceiverKind::Sim => Ok(Self::Sim(
                session
                    .declare_subscriber(keys.robot(robot, RobotTopic::Ultrasound)?)
                    .callback(move |sample| {
                        sink(ReceiverInput::Arrivals(decode::<UltrasoundArrivals>(
                            &sample.payload().to_bytes(),
                        )))
                    })
                    .await
                    .map_err(zerr)?,
            )),
            ReceiverKind::Board(address) => Ok(Self::Board(BoardReceivers::open(
                robot, address, cx.clock, cx.wheels, sink,
            ))),
            ReceiverKind::Marvelmind(address) => Ok(Self::Marvelmind(MarvelmindReceivers::open(
                robot,
                address,
                cx.clock,
                (cx.site, cx.marvelmind),
                move |r| sink(ReceiverInput::Ranging(r)),
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_marvelmind_address_is_a_link_address_after_its_prefix() {
        let kind: ReceiverKind = "marvelmind:serial:/dev/ttyACM0@9600".parse().unwrap();
        assert_eq!(
            kind,
            ReceiverKind::Marvelmind(LinkAddress::Serial {
                path: "/dev/ttyACM0".into(),
                baud: 9600
            })
        );
        assert_eq!(kind.to_string(), "marvelmind:serial:/dev/ttyACM0@9600");
        let tcp: ReceiverKind = "marvelmind:tcp:10.0.0.5:4000".parse().unwrap();
        assert_eq!(tcp.to_string(), "marvelmind:tcp:10.0.0.5:4000");
        assert!(matches!(
            "serial:/dev/ttyUSB0".parse(),
            Ok(ReceiverKind::Board(_))
        ));
        for bad in [
            "marvelmind:",
            "marvelmind:/dev/ttyACM0",
            "marvelmind:tcp:host",
        ] {
            let e = bad.parse::<ReceiverKind>().unwrap_err();
            assert!(e.contains("after `marvelmind:`"), "{bad}: {e}");
        }
    }
}
