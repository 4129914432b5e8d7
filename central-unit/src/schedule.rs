//! The emission schedule of a site (docs/architecture.md), a pure function of the
//! site model and the cells taking part.
//!
//! [`compute_schedule`], the one the central unit runs, places every
//! transmitter as early as the geometry and the carrier channels let it
//! ([`crate::spacing`]: the largest arrival-time difference where two
//! bursts are both audible, plus burst length, decoder window and the
//! reverberation guard). [`compute_uniform_schedule`] is the schedule from
//! before, kept to measure against:
//!
//! - **Slot**: the longest audible flight in a cell (from the farthest point
//!   of the cell polygon, at MSU height, to its farthest transmitter) divided
//!   by the speed of sound, plus the site's reverberation guard. The longest
//!   slot of all cells is used for every slot, so that slots line up.
//! - **Interference**: two cells interfere when a transmitter of one is
//!   audible at some point of the other: within [`AUDIBLE_RANGE_M`] and in
//!   line of sight (points sampled every [`GRID_M`]).
//! - **Colouring**: greedy, largest degree first, ties by file order, so the
//!   result is the same on every machine. Cells of one colour fire in the same
//!   sub-slots; interfering cells never share a colour.
//! - **Cycle**: colour `c`, transmitter `k` of the cell (file order) fires at
//!   `offset = (c * max_tx + k) * slot`, and
//!   `cycle_period = colours * max_tx * slot`, where `max_tx` is the largest
//!   number of transmitters of an active cell.

use ickon_proto::msg::control::{Emission, Schedule};
use ickon_proto::site::{Cell, Site};
use ickon_proto::time::Duration;

use crate::audibility::sample_points;
pub use crate::audibility::{AUDIBLE_RANGE_M, GRID_M};
use crate::spacing::{Packing, SpacingTable};

/// Why no schedule could be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ScheduleError {
    /// A cell named as active is not in the site.
    #[error("active cell {0:?} is not in the site")]
    UnknownCell(String),
    /// No cell is active: nothing to schedule.
    #[error("no active cell: nothing to schedule")]
    NoActiveCells,
}

fn distance3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Whether a transmitter of cell `a` is audible somewhere in cell `b`, or the reverse.
pub fn cells_interfere(site: &Site, a: &Cell, b: &Cell) -> bool {
    let h = site.msu.height_m;
    let audible = |from: &Cell, to: &Cell| {
        let points = sample_points(to, GRID_M);
        site.transmitters_of(&from.id).any(|tx| {
            points.iter().any(|p| {
                let q = [p[0], p[1], h];
                distance3(tx.position_m, q) <= AUDIBLE_RANGE_M
                    && site.line_of_sight(tx.position_m, q)
            })
        })
    };
    audible(a, b) || audible(b, a)
}

/// Slot length: the longest audible flight in any of `cells`, plus the guard, seconds.
pub fn slot_length_s(site: &Site, cells: &[&Cell]) -> f64 {
    let h = site.msu.height_m;
    let longest_m = cells
        .iter()
        .flat_map(|c| {
            let corners = c.polygon.clone();
            site.transmitters_of(&c.id)
                .flat_map(move |tx| {
                    corners
                        .iter()
                        .map(|p| distance3(tx.position_m, [p[0], p[1], h]))
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        })
        .fold(0.0, f64::max);
    longest_m / site.speed_of_sound_m_s + site.guard_time_s
}

/// Colours of `cells` (index into `cells` -> colour), interfering cells apart.
pub fn colour_cells(site: &Site, cells: &[&Cell]) -> Vec<usize> {
    let n = cells.len();
    let mut adjacent = vec![vec![false; n]; n];
    for i in 0..n {
        for j in (i + 1)..n {
            let hit = cells_interfere(site, cells[i], cells[j]);
            adjacent[i][j] = hit;
            adjacent[j][i] = hit;
        }
    }
    let degree = |i: usize| adjacent[i].iter().filter(|&&x| x).count();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(degree(i)), i));
    let mut colour = vec![usize::MAX; n];
    for &i in &order {
        let mut c = 0;
        while (0..n).any(|j| adjacent[i][j] && colour[j] == c) {
            c += 1;
        }
        colour[i] = c;
    }
    colour
}

/// The schedule of `site` with `active_cells` taking part (site order is
/// kept), with epoch 0 (the central unit stamps its own), each transmitter
/// as early as the geometry lets it fire ([`crate::spacing`]): the
/// tight schedule, the one the central unit runs.
pub fn compute_schedule(
    site: &Site,
    active_cells: &[String],
    version: u32,
    effective_cycle: u64,
) -> Result<Schedule, ScheduleError> {
    let cells = active(site, active_cells)?;
    let table = SpacingTable::new(site, &cells);
    Ok(schedule_from_packing(
        &table,
        &table.pack_all(),
        version,
        effective_cycle,
        cells,
    ))
}

/// The cells of `site` named in `active_cells`, site order, all known.
fn active(site: &Site, active_cells: &[String]) -> Result<Vec<String>, ScheduleError> {
    if let Some(unknown) = active_cells.iter().find(|id| site.cell(id).is_none()) {
        return Err(ScheduleError::UnknownCell(unknown.clone()));
    }
    let cells: Vec<String> = site
        .cells
        .iter()
        .filter(|c| active_cells.contains(&c.id))
        .map(|c| c.id.clone())
        .collect();
    if cells.is_empty() {
        return Err(ScheduleError::NoActiveCells);
    }
    Ok(cells)
}

/// A schedule firing the packed transmitters of `table`: `slot` numbers the
/// distinct offsets in order, `slot_length` is the longest spacing used.
pub fn schedule_from_packing(
    table: &SpacingTable,
    packing: &Packing,
    version: u32,
    effective_cycle: u64,
    active_cells: Vec<String>,
) -> Schedule {
    let mut emissions = Vec::with_capacity(packing.offsets.len());
    let mut slot = 0u32;
    let mut last = None;
    let mut longest = Duration::ZERO;
    for &(i, offset) in &packing.offsets {
        if last.is_some_and(|l| l != offset) {
            slot += 1;
        }
        last = Some(offset);
        if let Some(n) = table.need(i, i) {
            longest = longest.max(n);
        }
        emissions.push(Emission {
            tx_id: table.tx_ids[i],
            cell_id: table.cells[i].clone(),
            offset,
            slot,
        });
    }
    for &(i, _) in &packing.offsets {
        for &(j, _) in &packing.offsets {
            if let Some(n) = table.need(i, j) {
                longest = longest.max(n);
            }
        }
    }
    Schedule {
        version,
        effective_cycle,
        epoch: 0,
        cycle_period: packing.period,
        slot_length: longest,
        emissions,
        active_cells,
    }
}

/// The uniform schedule, kept to measure against: cells
/// coloured apart when one hears the other, one slot of the longest flight
/// of any cell for every emission, every transmitter of a colour in turn.
/// It lets bursts collide at points that hear two cells of one colour
/// (`ickon_sim::schedule_audit` finds them).
pub fn compute_uniform_schedule(
    site: &Site,
    active_cells: &[String],
    version: u32,
    effective_cycle: u64,
) -> Result<Schedule, ScheduleError> {
    if let Some(unknown) = active_cells.iter().find(|id| site.cell(id).is_none()) {
        return Err(ScheduleError::UnknownCell(unknown.clone()));
    }
    let cells: Vec<&Cell> = site
        .cells
        .iter()
        .filter(|c| active_cells.contains(&c.id))
        .collect();
    if cells.is_empty() {
        return Err(ScheduleError::NoActiveCells);
    }
    let colours = colour_cells(site, &cells);
    let n_colours = colours.iter().max().map_or(1, |m| m + 1);
    let max_tx = cells
        .iter()
        .map(|c| site.transmitters_of(&c.id).count())
        .max()
        .unwrap_or(1)
        .max(1);
    let slot = Duration::from_secs_f64(slot_length_s(site, &cells));
    let mut emissions = Vec::new();
    for (cell, &colour) in cells.iter().zip(&colours) {
        for (k, tx) in site.transmitters_of(&cell.id).enumerate() {
            let slot_index = colour * max_tx + k;
            emissions.push(Emission {
                tx_id: tx.id,
                cell_id: cell.id.clone(),
                offset: slot * slot_index as i64,
                slot: u32::try_from(slot_index).unwrap_or(u32::MAX),
            });
        }
    }
    emissions.sort_by_key(|e| (e.offset, e.tx_id));
    Ok(Schedule {
        version,
        effective_cycle,
        cycle_period: slot * (n_colours * max_tx) as i64,
        slot_length: slot,
        emissions,
        active_cells: cells.iter().map(|c| c.id.clone()).collect(),
        // The central unit stamps its own epoch on what it publishes.
        epoch: 0,
    })
}

/// Cycles per second of a schedule.
pub fn update_rate_hz(schedule: &Schedule) -> f64 {
    let period = schedule.cycle_period.as_secs_f64();
    if period > 0.0 { 1.0 / period } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_cells(site: &Site) -> Vec<String> {
        site.cells.iter().map(|c| c.id.clone()).collect()
    }

    #[test]
    fn default_site_reuses_slots_between_distant_cells() {
        let site = Site::default_site();
        let s = compute_uniform_schedule(&site, &all_cells(&site), 1, 0).unwrap();
        assert_eq!(s.emissions.len(), 16);
        let slot = s.slot_length.as_secs_f64();
        // Corridor cell c1 cannot hear the room: c1 and c3/c4 can share a colour.
        let colours = s.cycle_period.as_secs_f64() / slot / 4.0;
        assert!(
            (colours - colours.round()).abs() < 1e-6 && colours < 4.0,
            "{colours} colours"
        );
        assert!(update_rate_hz(&s) > 0.5, "rate {}", update_rate_hz(&s));
    }

    #[test]
    fn interfering_cells_never_overlap() {
        let site = Site::default_site();
        let s = compute_uniform_schedule(&site, &all_cells(&site), 1, 0).unwrap();
        let slot = s.slot_length;
        for a in &s.emissions {
            for b in &s.emissions {
                if a.cell_id == b.cell_id || a.tx_id == b.tx_id {
                    continue;
                }
                let ca = site.cell(&a.cell_id).unwrap();
                let cb = site.cell(&b.cell_id).unwrap();
                if cells_interfere(&site, ca, cb) {
                    let gap = (a.offset.as_nanos() - b.offset.as_nanos()).abs();
                    assert!(
                        gap >= slot.as_nanos(),
                        "{} and {} overlap",
                        a.tx_id,
                        b.tx_id
                    );
                }
            }
        }
        // Neighbouring corridor cells and the two room cells hear each other.
        let c = |id| site.cell(id).unwrap();
        assert!(cells_interfere(&site, c("c1"), c("c2")));
        assert!(cells_interfere(&site, c("c3"), c("c4")));
        assert!(!cells_interfere(&site, c("c1"), c("c4")));
    }

    #[test]
    fn every_transmitter_of_every_active_cell_fires_once_per_cycle() {
        let site = Site::default_site();
        let s = compute_schedule(&site, &["c2".into(), "c4".into()], 3, 10).unwrap();
        let mut ids: Vec<u32> = s.emissions.iter().map(|e| e.tx_id).collect();
        ids.sort();
        assert_eq!(ids, vec![21, 22, 23, 24, 41, 42, 43, 44]);
        assert_eq!(s.version, 3);
        assert_eq!(s.effective_cycle, 10);
        assert_eq!(s.active_cells, vec!["c2".to_string(), "c4".to_string()]);
        for e in &s.emissions {
            assert!(e.offset < s.cycle_period);
        }
    }

    #[test]
    fn slot_covers_the_longest_flight_plus_guard() {
        let site = Site::default_site();
        let s = compute_uniform_schedule(&site, &all_cells(&site), 1, 0).unwrap();
        // Corridor cell 8 x 2.5 m: corner to far transmitter about 7.6 m, 22 ms.
        let slot_s = s.slot_length.as_secs_f64();
        assert!(
            slot_s > site.guard_time_s + 0.015 && slot_s < 0.06,
            "{slot_s}"
        );
    }

    #[test]
    fn bad_cell_lists_are_refused() {
        let site = Site::default_site();
        assert_eq!(
            compute_schedule(&site, &["c9".into()], 1, 0),
            Err(ScheduleError::UnknownCell("c9".into()))
        );
        assert_eq!(
            compute_schedule(&site, &[], 1, 0),
            Err(ScheduleError::NoActiveCells)
        );
    }
}
