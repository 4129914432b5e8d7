//! Test fixtures shared by the cell controller's unit tests.

use ickon_proto::msg::control::{Emission, Schedule};
use ickon_proto::time::Duration;

/// The epoch of the fixtures' central unit.
pub(crate) const EPOCH: u64 = 1_000;

/// A 200 ms schedule: c1 fires tx 11 at 0 ms and tx 12 at 25 ms, c2 tx 21 at 0 ms.
pub(crate) fn schedule(version: u32) -> Schedule {
    let e = |tx_id, cell: &str, ms| Emission {
        tx_id,
        cell_id: cell.into(),
        offset: Duration::from_millis(ms),
        slot: 0,
    };
    Schedule {
        version,
        effective_cycle: 0,
        cycle_period: Duration::from_millis(200),
        slot_length: Duration::from_millis(25),
        emissions: vec![e(11, "c1", 0), e(12, "c1", 25), e(21, "c2", 0)],
        active_cells: vec!["c1".into(), "c2".into()],
        epoch: EPOCH,
    }
}
