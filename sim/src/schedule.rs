//! The emission schedule the engine runs: the central unit's scheduler when
//! available; this file holds the conservative fallback used until then
//! (every transmitter of the site in its own slot, cells in file order).

use ickon_proto::msg::control::{Emission, Schedule};
use ickon_proto::site::Site;
use ickon_proto::time::Duration;

/// One slot per transmitter: slot length = longest flight from any point of
/// a cell to one of its transmitters, plus the site's guard time.
pub fn sequential_schedule(site: &Site) -> Schedule {
    let h = site.msu.height_m;
    let mut longest_m: f64 = 0.0;
    for cell in &site.cells {
        for tx in site.transmitters_of(&cell.id) {
            for p in &cell.polygon {
                let d = ((p[0] - tx.position_m[0]).powi(2)
                    + (p[1] - tx.position_m[1]).powi(2)
                    + (h - tx.position_m[2]).powi(2))
                .sqrt();
                longest_m = longest_m.max(d);
            }
        }
    }
    let slot_s = longest_m / site.speed_of_sound_m_s + site.guard_time_s;
    let slot_length = Duration::from_secs_f64(slot_s);
    let mut emissions = Vec::new();
    for cell in &site.cells {
        for tx in site.transmitters_of(&cell.id) {
            let slot = u32::try_from(emissions.len()).unwrap_or(u32::MAX);
            emissions.push(Emission {
                tx_id: tx.id,
                cell_id: cell.id.clone(),
                offset: Duration::from_nanos(slot_length.as_nanos() * i64::from(slot)),
                slot,
            });
        }
    }
    let slots = i64::try_from(emissions.len()).unwrap_or(1).max(1);
    Schedule {
        version: 1,
        effective_cycle: 0,
        cycle_period: Duration::from_nanos(slot_length.as_nanos() * slots),
        slot_length,
        emissions,
        active_cells: site.cells.iter().map(|c| c.id.clone()).collect(),
    }
}
