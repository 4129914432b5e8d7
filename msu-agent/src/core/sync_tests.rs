//! Each cell's reported sync sigma reaches the filters with its arrivals,
//! and a status that cannot be right is refused.

use super::tests::core_with;
use super::*;
use crate::events::{Event, InputKind, Output};
use ickon_proto::msg::robot::Arrival;

fn status(cell: &str, sigma_ns: i64) -> CellStatus {
    CellStatus {
        cell_id: cell.into(),
        stamp: Time::from_secs_f64(1.0),
        offset_ns: 0,
        drift_ppb: 0,
        offset_sigma_ns: sigma_ns,
        sync_samples: 10,
        last_cycle_fired: 0,
        cycles_fired: 0,
        slots_skipped: 0,
        faults: Vec::new(),
        inputs_refused: 0,
        device: String::new(),
    }
}

/// The arrivals of transmitters 1-3, 40 ms apart as the schedule has them.
fn cycle() -> UltrasoundArrivals {
    UltrasoundArrivals {
        seq: 1,
        arrivals: (1..=3)
            .map(|id| Arrival {
                tx_id: id,
                receiver_id: 0,
                t_arrival: Time::from_secs_f64(10.0 + 0.04 * f64::from(id - 1) + 0.01),
            })
            .collect(),
    }
}

#[test]
fn the_sync_sigma_a_cell_reports_goes_with_each_of_its_arrivals() {
    let mut core = core_with("tdoa-ekf");
    let sigmas = |core: &mut MsuCore| {
        let solved = core.solver.solve(&cycle(), None, &mut core.clock).unwrap();
        solved
            .range_differences
            .iter()
            .flat_map(|m| m.clocks.unwrap())
            .map(|c| (c.id, c.sync_sigma_m))
            .collect::<Vec<_>>()
    };
    // A report before the robot's first input is not taken (a replay could
    // not tell whether the agent had heard it).
    assert!(
        core.handle(Event::CellStatus(status("a", 100_000)))
            .is_empty()
    );
    core.handle(Event::Arrivals(cycle()));
    // Before any report taken: the clock is named, its sigma unknown.
    assert!(sigmas(&mut core).iter().all(|&(id, s)| id == 0 && s == 0.0));
    assert!(
        core.handle(Event::CellStatus(status("a", 100_000)))
            .is_empty()
    );
    let metres = 100e-6 * super::tests::C;
    assert!(
        sigmas(&mut core)
            .iter()
            .all(|&(_, s)| (s - metres).abs() < 1e-12),
        "{:?}",
        sigmas(&mut core)
    );
}

#[test]
fn a_status_of_no_cell_of_the_site_or_an_impossible_sigma_is_refused() {
    let mut core = core_with("tdoa-ekf");
    for bad in [
        status("zz", 1_000),
        status("a", -1),
        status("a", 20_000_000),
    ] {
        let out = core.handle(Event::CellStatus(bad.clone()));
        assert!(
            matches!(
                out.as_slice(),
                [Output::Refused {
                    input: InputKind::CellStatus,
                    error: MsuError::CellStatus { .. }
                }]
            ),
            "{bad:?}: {out:?}"
        );
    }
    // The message names the cell and the reason.
    let err = core.on_cell_status(&status("zz", 1_000)).unwrap_err();
    assert_eq!(
        err.to_string(),
        "status of cell \"zz\": not a cell of this site"
    );
}

/// The live agent and the replay take a status only under its own cell's
/// key: another cell's name under a key (forged, or a misconfigured cell)
/// and a key that is no cell's are refused, naming the cell.
#[test]
fn a_status_under_another_cells_key_is_refused() {
    let own = MsuCore::status_under_key(Some("a"), status("a", 1_000)).unwrap();
    assert_eq!(own.cell_id, "a");
    for key in [Some("b"), Some(""), None] {
        let err = MsuCore::status_under_key(key, status("a", 1_000)).unwrap_err();
        assert_eq!(
            err.to_string(),
            "status of cell \"a\": heard under another cell's key",
            "{key:?}"
        );
    }
}
