//! Where a burst is heard: the audible range of a transmitter and the
//! points a cell is sampled at, shared by the schedule's interference test
//! and the spacing of its emissions.

use ickon_proto::site::Cell;

/// Range beyond which a 40 kHz burst is taken as inaudible, metres.
pub const AUDIBLE_RANGE_M: f64 = 12.0;
/// Spacing of the points a cell is sampled at for the interference test, metres.
pub const GRID_M: f64 = 0.25;

/// Sample points of a cell polygon at MSU height: its vertices and a grid inside.
pub(crate) fn sample_points(cell: &Cell, grid_m: f64) -> Vec<[f64; 2]> {
    let mut pts: Vec<[f64; 2]> = cell.polygon.clone();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &cell.polygon {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let nx = ((hi[0] - lo[0]) / grid_m).ceil() as usize;
    let ny = ((hi[1] - lo[1]) / grid_m).ceil() as usize;
    for i in 0..=nx {
        for j in 0..=ny {
            let p = [lo[0] + i as f64 * grid_m, lo[1] + j as f64 * grid_m];
            if cell.contains(p) {
                pts.push(p);
            }
        }
    }
    pts
}
