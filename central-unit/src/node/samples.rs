//! What a received sample means to the core: each decoded into its
//! [`Event`], one that does not decode counted.

use ickon_proto::decode;
use ickon_proto::keys::{Key, Keys};
use ickon_proto::msg::control::{AirTemperature, Burst, CellStatus, RouterLink};
use ickon_proto::msg::robot::{MsuStatus, RobotSummary, Truth};
use ickon_runtime::SimulatedClock;
use zenoh::sample::{Sample, SampleKind};

use crate::core::Event;

/// A liveliness change as an event for the core (`None`: nothing it
/// follows). The active central unit's token going matters only to a
/// standby.
pub(super) fn alive_event(keys: &Keys, s: &Sample, active: bool) -> Option<Event> {
    let up = s.kind() == SampleKind::Put;
    match keys.parse(s.key_expr().as_str()) {
        Ok(Key::AliveCell(id)) => Some(Event::CellAlive { id, up }),
        Ok(Key::AliveRobot(id)) => Some(Event::RobotAlive { id, up }),
        Ok(Key::AliveCentral) if !up && !active => Some(Event::ActiveGone),
        _ => None,
    }
}

/// A cell's status report, counting one that does not decode.
pub(super) fn status_event(s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match decode::<CellStatus>(&s.payload().to_bytes()) {
        Ok(st) => Some(Event::CellStatus(st)),
        Err(e) => {
            *undecodable += 1;
            tracing::debug!("undecodable status on {}: {e}", s.key_expr());
            None
        }
    }
}

/// A cell board's air temperature reading, counting one that does not
/// decode. The cell is the key's: a payload naming another is not taken
/// for it.
pub(super) fn air_event(keys: &Keys, s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<AirTemperature>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::CellAir(cell_id)), Ok(reading)) => {
            Some(Event::AirTemperature(AirTemperature { cell_id, ..reading }))
        }
        (_, Err(e)) => {
            *undecodable += 1;
            tracing::debug!("undecodable air temperature on {}: {e}", s.key_expr());
            None
        }
        _ => None,
    }
}

/// A node's report of its router link, under the key's id, counting one
/// that does not decode.
pub(super) fn link_report(
    keys: &Keys,
    s: &Sample,
    undecodable: &mut u64,
) -> Option<(crate::router_links::NodeKind, String, RouterLink)> {
    use crate::router_links::NodeKind;
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<RouterLink>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::CellLink(id)), Ok(link)) => Some((NodeKind::Cell, id, link)),
        (Ok(Key::RobotLink(id)), Ok(link)) => Some((NodeKind::Robot, id, link)),
        (_, Err(e)) => {
            *undecodable += 1;
            tracing::debug!("undecodable router link on {}: {e}", s.key_expr());
            None
        }
        _ => None,
    }
}

/// A cell's burst report, counting one that does not decode.
pub(super) fn burst_event(
    s: &Sample,
    clock: &SimulatedClock,
    undecodable: &mut u64,
) -> Option<Event> {
    match decode::<Burst>(&s.payload().to_bytes()) {
        // A simulated driver reports the true emission time: on
        // the master time base it is what this clock read then.
        Ok(b) => Some(Event::Burst(Burst {
            actual: clock.local(b.actual),
            ..b
        })),
        Err(e) => {
            *undecodable += 1;
            tracing::debug!("undecodable burst on {}: {e}", s.key_expr());
            None
        }
    }
}

/// A robot's summary, counting one whose payload does not decode.
pub(super) fn summary_event(keys: &Keys, s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match (
        keys.parse(s.key_expr().as_str()),
        RobotSummary::decode(&s.payload().to_bytes()),
    ) {
        (Ok(Key::RobotSummary(robot)), Ok(summary)) => Some(Event::Summary {
            robot,
            summary: Box::new(summary),
        }),
        (_, Err(_)) => {
            *undecodable += 1;
            None
        }
        _ => None,
    }
}

/// A robot's truth (`None` when its key or payload does not parse).
pub(super) fn truth_of(keys: &Keys, s: &Sample) -> Option<(String, Truth)> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<Truth>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::SimTruth(robot)), Ok(truth)) => Some((robot, truth)),
        _ => None,
    }
}

/// A robot's agent's status, counting one whose payload does not decode.
pub(super) fn robot_status_event(keys: &Keys, s: &Sample, undecodable: &mut u64) -> Option<Event> {
    match (
        keys.parse(s.key_expr().as_str()),
        decode::<MsuStatus>(&s.payload().to_bytes()),
    ) {
        (Ok(Key::RobotStatus(robot)), Ok(status)) => Some(Event::RobotStatus { robot, status }),
        (_, Err(_)) => {
            *undecodable += 1;
            None
        }
        _ => None,
    }
}

/// A sample's payload decoded, counting one that does not decode.
pub(super) fn decode_counted<T: serde::de::DeserializeOwned>(
    s: &Sample,
    undecodable: &mut u64,
) -> Option<T> {
    match decode::<T>(&s.payload().to_bytes()) {
        Ok(t) => Some(t),
        Err(_) => {
            *undecodable += 1;
            None
        }
    }
}
