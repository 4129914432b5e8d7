//! The devices the world emulates in `ickon sim --devices emulated` and
//! `ickon sim --receivers marvelmind`: which node's device listens where
//! ([`DeviceEndpoint`], the world's `--device` flag), and how the bursts
//! its transmitter boards really fired are matched with the cells' reports
//! of them ([`EmissionLedger`]).
//!
//! With boards, the sound leaves when the board fires, not when the cell
//! believes it did: the world takes each emission's time from the board
//! and only the cycle it belongs to from the cell's report.

use std::collections::VecDeque;
use std::net::SocketAddr;

/// Whose device it is.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum DeviceOwner {
    /// A cell controller (its transmitter board).
    Cell(String),
    /// A robot's MSU agent (its receiver board or ranging kit).
    Robot(String),
}

/// What the world emulates at an endpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    /// A transmitter board of the ICKON device protocol.
    TransmitterBoard,
    /// A receiver board of the ICKON device protocol, reporting the
    /// robot's wheel ticks and gyro too.
    ReceiverBoard,
    /// A Marvelmind hedgehog's stream.
    Marvelmind,
}

impl DeviceKind {
    fn name(self) -> &'static str {
        match self {
            DeviceKind::TransmitterBoard => "transmitter-board",
            DeviceKind::ReceiverBoard => "receiver-board",
            DeviceKind::Marvelmind => "marvelmind",
        }
    }
}

/// One emulated device and the TCP address it listens on:
/// `cell/ID=transmitter-board@HOST:PORT`, `robot/ID=receiver-board@HOST:PORT`
/// or `robot/ID=marvelmind@HOST:PORT`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceEndpoint {
    /// Whose device.
    pub owner: DeviceOwner,
    /// What it is.
    pub kind: DeviceKind,
    /// Where it listens.
    pub listen: SocketAddr,
}

impl std::str::FromStr for DeviceEndpoint {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let form = "`cell/ID=transmitter-board@HOST:PORT`, `robot/ID=receiver-board@HOST:PORT` \
                    or `robot/ID=marvelmind@HOST:PORT`";
        let (owner, rest) = s
            .split_once('=')
            .ok_or_else(|| format!("`{s}`: expected {form}"))?;
        let (kind, listen) = rest
            .split_once('@')
            .ok_or_else(|| format!("`{s}`: expected {form}"))?;
        let owner = match owner.split_once('/') {
            Some(("cell", id)) if !id.is_empty() => DeviceOwner::Cell(id.to_string()),
            Some(("robot", id)) if !id.is_empty() => DeviceOwner::Robot(id.to_string()),
            _ => return Err(format!("`{owner}`: expected `cell/ID` or `robot/ID`")),
        };
        let kind = match (kind, &owner) {
            ("transmitter-board", DeviceOwner::Cell(_)) => DeviceKind::TransmitterBoard,
            ("receiver-board", DeviceOwner::Robot(_)) => DeviceKind::ReceiverBoard,
            ("marvelmind", DeviceOwner::Robot(_)) => DeviceKind::Marvelmind,
            _ => return Err(format!("`{s}`: expected {form}")),
        };
        let listen = listen
            .parse()
            .map_err(|e| format!("`{listen}`: not HOST:PORT ({e})"))?;
        Ok(Self {
            owner,
            kind,
            listen,
        })
    }
}

impl std::fmt::Display for DeviceEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let owner = match &self.owner {
            DeviceOwner::Cell(id) => format!("cell/{id}"),
            DeviceOwner::Robot(id) => format!("robot/{id}"),
        };
        write!(f, "{owner}={}@{}", self.kind.name(), self.listen)
    }
}

/// Board emissions remembered for matching (a few cycles of every board).
const EMISSIONS_KEPT: usize = 1024;

/// How far a cell's report of a burst may be from when its board really
/// fired it: the cell reports the scheduled time moved by the board's own
/// lateness, so the two differ by the cell's sync error (microseconds) and
/// the clock fit's error; a burst of another slot of the same transmitter
/// is at least a cycle (tens of milliseconds) away.
pub const MATCH_WINDOW_NS: i64 = 5_000_000;

/// The bursts the transmitter boards fired, waiting for the cells' reports.
#[derive(Debug, Default)]
pub struct EmissionLedger {
    fired: VecDeque<(u32, i64)>,
    /// Reports no board emission explained (dropped: no sound left).
    pub unmatched_reports: u64,
}

impl EmissionLedger {
    /// Records that a board fired `tx_id` at true time `t_ns`.
    pub fn record(&mut self, tx_id: u32, t_ns: i64) {
        if self.fired.len() == EMISSIONS_KEPT {
            self.fired.pop_front();
        }
        self.fired.push_back((tx_id, t_ns));
    }

    /// The true time of the emission a cell reported as `tx_id` at
    /// `reported_ns`, taken out of the ledger; `None` (counted) when no
    /// board fired it within [`MATCH_WINDOW_NS`].
    pub fn take(&mut self, tx_id: u32, reported_ns: i64) -> Option<i64> {
        let nearest = self
            .fired
            .iter()
            .enumerate()
            .filter(|(_, (tx, _))| *tx == tx_id)
            .map(|(i, &(_, t))| (i, t, t.saturating_sub(reported_ns).unsigned_abs()))
            .filter(|&(_, _, d)| d <= MATCH_WINDOW_NS.unsigned_abs())
            .min_by_key(|&(_, _, d)| d);
        match nearest {
            Some((i, t, _)) => {
                self.fired.remove(i);
                Some(t)
            }
            None => {
                self.unmatched_reports += 1;
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_read_back_as_written_and_nonsense_is_refused_by_name() {
        for s in [
            "cell/c1=transmitter-board@127.0.0.1:4000",
            "robot/r1=receiver-board@127.0.0.1:4001",
            "robot/r2=marvelmind@[::1]:4002",
        ] {
            let e: DeviceEndpoint = s.parse().unwrap();
            assert_eq!(e.to_string(), s);
        }
        for bad in [
            "",
            "cell/c1",
            "cell/=transmitter-board@127.0.0.1:1",
            "robot/r1=transmitter-board@127.0.0.1:1",
            "cell/c1=marvelmind@127.0.0.1:1",
            "cell/c1=transmitter-board@localhost",
            "dock/d1=receiver-board@127.0.0.1:1",
        ] {
            assert!(bad.parse::<DeviceEndpoint>().is_err(), "{bad}");
        }
    }

    #[test]
    fn a_report_takes_the_nearest_firing_of_its_transmitter_once() {
        let mut l = EmissionLedger::default();
        l.record(11, 1_000_000_000);
        l.record(12, 1_000_300_000);
        l.record(11, 1_100_000_000);
        // The cell's report is 40 us off the board's firing.
        assert_eq!(l.take(11, 1_000_040_000), Some(1_000_000_000));
        // Taken once: a repeated report finds nothing near.
        assert_eq!(l.take(11, 1_000_040_000), None);
        // A report of a burst no board fired makes no sound.
        assert_eq!(l.take(13, 1_000_300_000), None);
        assert_eq!(l.take(12, 1_000_300_000 + MATCH_WINDOW_NS + 1), None);
        assert_eq!(l.unmatched_reports, 3);
        assert_eq!(l.take(11, 1_099_999_000), Some(1_100_000_000));
    }

    #[test]
    fn the_ledger_forgets_the_oldest_firings_first() {
        let mut l = EmissionLedger::default();
        for k in 0..(EMISSIONS_KEPT as i64 + 10) {
            l.record(1, k * 100_000_000);
        }
        assert_eq!(l.take(1, 0), None);
        assert!(
            l.take(1, (EMISSIONS_KEPT as i64 + 9) * 100_000_000)
                .is_some()
        );
    }
}
