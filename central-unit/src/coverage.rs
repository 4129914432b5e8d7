//! Coverage of the floor from the transmitter placement (docs/architecture.md):
//! over a grid at the MSU height, how many transmitters a robot hears in line
//! of sight, and the horizontal dilution of precision of its 2D TDOA fix.
//!
//! A transmitter counts at a point when it is within [`AUDIBLE_RANGE_M`] and
//! [`Site::line_of_sight`] clears every wall and column between them; only
//! the transmitters of the cells in the schedule count, so the figures say
//! what the robots get now. The HDOP is [`ickon_fusion::tdoa::dop`] of those
//! transmitters in 2D mode (position error per metre of range noise, the
//! correlated range differences of TDOA included); 0 where fewer than three
//! are heard or their geometry determines no position.

use ickon_fusion::tdoa::{Mode, dop};
use ickon_proto::msg::admin::CoverageReport;
use ickon_proto::site::{Site, Transmitter};
use nalgebra::Vector3;

use crate::audibility::AUDIBLE_RANGE_M;

/// Grid spacing when the admin does not ask for one, metres.
pub const DEFAULT_RESOLUTION_M: f64 = 0.25;
/// Finest grid spacing served, metres.
pub const MIN_RESOLUTION_M: f64 = 0.05;
/// Most grid points of one report: the spacing is enlarged beyond this, so
/// that a query never holds up the cycle triggers for long.
pub const MAX_GRID_POINTS: usize = 40_000;

/// The spacing actually used for a wanted one over a floor of `width_m` x
/// `depth_m`: the default for a non-finite or non-positive wish, at least
/// [`MIN_RESOLUTION_M`], and coarse enough for [`MAX_GRID_POINTS`].
pub fn effective_resolution_m(wanted_m: f64, width_m: f64, depth_m: f64) -> f64 {
    let mut r = if wanted_m.is_finite() && wanted_m > 0.0 {
        wanted_m.max(MIN_RESOLUTION_M)
    } else {
        DEFAULT_RESOLUTION_M
    };
    let area_m2 = width_m.max(0.0) * depth_m.max(0.0);
    let floor_for_cap = (area_m2 / MAX_GRID_POINTS as f64).sqrt();
    if floor_for_cap > r {
        r = floor_for_cap;
    }
    // Rounding up to whole grid cells adds at most a row and a column.
    while grid_size(width_m, r) * grid_size(depth_m, r) > MAX_GRID_POINTS {
        r *= 1.05;
    }
    r
}

fn grid_size(extent_m: f64, resolution_m: f64) -> usize {
    ((extent_m / resolution_m).ceil() as usize).max(1)
}

/// Coverage of `site` by the transmitters of `active_cells`, on a grid of
/// (about) `resolution_m` over the bounding box of the cells. Grid points sit
/// at the centres of the grid squares.
pub fn coverage(
    site: &Site,
    active_cells: &[String],
    resolution_m: f64,
    schedule_version: u32,
) -> CoverageReport {
    let (lo, hi) = site.bounds();
    let (width_m, depth_m) = (hi[0] - lo[0], hi[1] - lo[1]);
    let res = effective_resolution_m(resolution_m, width_m, depth_m);
    let (columns, rows) = (grid_size(width_m, res), grid_size(depth_m, res));
    let height_m = site.msu.height_m;
    let transmitters: Vec<&Transmitter> = site
        .transmitters
        .iter()
        .filter(|t| active_cells.contains(&t.cell))
        .collect();
    let n = columns * rows;
    let mut report = CoverageReport {
        schedule_version,
        origin_x_m: lo[0] + res / 2.0,
        origin_y_m: lo[1] + res / 2.0,
        resolution_m: res,
        height_m,
        columns: u32::try_from(columns).unwrap_or(u32::MAX),
        rows: u32::try_from(rows).unwrap_or(u32::MAX),
        on_floor: Vec::with_capacity(n),
        visible: Vec::with_capacity(n),
        hdop: Vec::with_capacity(n),
    };
    for row in 0..rows {
        for col in 0..columns {
            let p = [
                report.origin_x_m + col as f64 * res,
                report.origin_y_m + row as f64 * res,
            ];
            let on_floor = site.cell_at(p).is_some();
            let heard: Vec<Vector3<f64>> = if on_floor {
                audible(site, &transmitters, [p[0], p[1], height_m])
            } else {
                Vec::new()
            };
            let hdop = dop(
                &heard,
                Vector3::new(p[0], p[1], height_m),
                Mode::TwoD { height_m },
            )
            .map_or(0.0, |d| d.hdop);
            report.on_floor.push(on_floor);
            report.visible.push(heard.len() as u32);
            report.hdop.push(if hdop.is_finite() { hdop } else { 0.0 });
        }
    }
    report
}

/// Positions of the transmitters audible in line of sight from `at`.
fn audible(site: &Site, transmitters: &[&Transmitter], at: [f64; 3]) -> Vec<Vector3<f64>> {
    transmitters
        .iter()
        .filter(|t| {
            let d = Vector3::from(t.position_m) - Vector3::from(at);
            d.norm() <= AUDIBLE_RANGE_M && site.line_of_sight(t.position_m, at)
        })
        .map(|t| Vector3::from(t.position_m))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_cells(site: &Site) -> Vec<String> {
        site.cells.iter().map(|c| c.id.clone()).collect()
    }

    /// Index of the grid point nearest to `(x, y)`.
    fn at(r: &CoverageReport, x: f64, y: f64) -> usize {
        let col = ((x - r.origin_x_m) / r.resolution_m).round() as usize;
        let row = ((y - r.origin_y_m) / r.resolution_m).round() as usize;
        row * r.columns as usize + col
    }

    #[test]
    fn the_grid_spans_the_floor_at_the_asked_spacing() {
        let site = Site::default_site();
        let r = coverage(&site, &all_cells(&site), 0.5, 3);
        // The lab is 21 m x 8 m: 42 x 16 points at 0.5 m, centred in their squares.
        assert_eq!((r.columns, r.rows), (42, 16));
        assert_eq!((r.origin_x_m, r.origin_y_m), (0.25, 0.25));
        assert_eq!(r.visible.len(), 42 * 16);
        assert_eq!(r.hdop.len(), r.on_floor.len());
        assert_eq!(r.schedule_version, 3);
        assert_eq!(r.height_m, site.msu.height_m);
    }

    #[test]
    fn walls_block_what_would_be_in_range() {
        let site = Site::default_site();
        let r = coverage(&site, &all_cells(&site), 0.5, 1);
        // In the room (c4): its own four transmitters and c3's, but not c2's
        // at x = 14.8, only 6 m away behind the corridor wall.
        let i = at(&r, 18.25, 6.25);
        assert!(r.on_floor[i]);
        assert_eq!(r.visible[i], 8);
        assert!(r.hdop[i] > 0.9 && r.hdop[i] < 2.0, "hdop {}", r.hdop[i]);
    }

    #[test]
    fn points_off_the_floor_have_no_figures() {
        let site = Site::default_site();
        let r = coverage(&site, &all_cells(&site), 0.5, 1);
        // North of the corridor, west of the room: inside the bounding box only.
        let i = at(&r, 8.25, 6.25);
        assert!(!r.on_floor[i]);
        assert_eq!((r.visible[i], r.hdop[i]), (0, 0.0));
    }

    #[test]
    fn geometry_is_worse_at_the_end_of_the_corridor_than_in_its_middle() {
        let site = Site::default_site();
        let r = coverage(&site, &all_cells(&site), 0.25, 1);
        let end = at(&r, 0.125, 1.125);
        let middle = at(&r, 4.125, 1.125);
        assert!(r.visible[end] >= 3 && r.visible[middle] >= 3);
        assert!(
            r.hdop[end] > r.hdop[middle],
            "end {} middle {}",
            r.hdop[end],
            r.hdop[middle]
        );
    }

    #[test]
    fn cells_out_of_the_schedule_add_nothing() {
        let site = Site::default_site();
        let r = coverage(&site, &["c1".to_string()], 0.5, 2);
        let room = at(&r, 18.25, 6.25);
        assert_eq!((r.visible[room], r.hdop[room]), (0, 0.0));
        assert!(r.visible[at(&r, 4.25, 1.25)] == 4);
    }

    #[test]
    fn spacing_is_kept_within_bounds() {
        assert_eq!(effective_resolution_m(f64::NAN, 21.0, 8.0), 0.25);
        assert_eq!(effective_resolution_m(-1.0, 21.0, 8.0), 0.25);
        assert_eq!(effective_resolution_m(0.001, 5.0, 4.0), MIN_RESOLUTION_M);
        // The lab at 5 cm would be 67 200 points: coarser, under the cap.
        let lab = effective_resolution_m(0.05, 21.0, 8.0);
        assert!(lab > 0.05 && grid_size(21.0, lab) * grid_size(8.0, lab) <= MAX_GRID_POINTS);
        let r = effective_resolution_m(0.05, 400.0, 300.0);
        assert!(grid_size(400.0, r) * grid_size(300.0, r) <= MAX_GRID_POINTS);
        assert!(r < 2.0, "{r}");
    }
}
