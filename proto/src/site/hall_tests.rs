//! The built-in `hall` site: an open floor as large as promised, nothing
//! inside blocking sound, routes covering the floor, robots spread over it.

use super::geometry::{self, Point2};
use super::*;

fn hall() -> Site {
    Site::builtin("hall").expect("built-in hall").0
}

#[test]
fn hall_is_an_open_floor_of_sixteen_cells_and_sixty_four_transmitters() {
    let site = hall();
    assert_eq!(site.name, "hall");
    assert_eq!(site.cells.len(), 16);
    assert_eq!(site.transmitters.len(), 64);
    assert!(
        (site.area_m2() - 400.0).abs() < 1e-9,
        "{} m2",
        site.area_m2()
    );
    assert!(site.columns.is_empty());
    assert_eq!(site.walls.len(), 4, "only the outer walls");
    for cell in &site.cells {
        assert_eq!(site.transmitters_of(&cell.id).count(), 4, "{}", cell.id);
    }
    for t in &site.transmitters {
        assert!((3.8..=4.0).contains(&t.position_m[2]), "{}", t.id);
    }
    // Every transmitter is in line of sight of every point of the floor.
    for t in &site.transmitters {
        for p in [
            [0.1, 0.1],
            [19.9, 0.1],
            [10.0, 10.0],
            [0.1, 19.9],
            [19.9, 19.9],
        ] {
            assert!(site.line_of_sight(t.position_m, [p[0], p[1], site.msu.height_m]));
        }
    }
}

#[test]
fn hall_routes_pass_near_every_point_of_the_floor() {
    let site = hall();
    let on_routes: Vec<Point2> = site
        .routes
        .iter()
        .flat_map(|r| {
            let n = (r.length_m() / 0.25).ceil() as usize;
            (0..n).map(|k| geometry::point_at_arc_length(&r.points, r.closed, k as f64 * 0.25))
        })
        .collect();
    for i in 0..=40 {
        for j in 0..=40 {
            let p = [f64::from(i) * 0.5, f64::from(j) * 0.5];
            let nearest = on_routes
                .iter()
                .map(|q| (q[0] - p[0]).hypot(q[1] - p[1]))
                .fold(f64::INFINITY, f64::min);
            // As `make_hall.py` says: within 1.25 m of every point but
            // the corners, which are 1.6 m from the nearest loop.
            assert!(
                nearest <= 1.61,
                "({:.1}, {:.1}) is {nearest:.2} m from a route",
                p[0],
                p[1]
            );
        }
    }
}

#[test]
fn the_first_sixteen_hall_robots_spread_over_every_row_and_half_of_the_floor() {
    let site = hall();
    assert!(site.robots.len() >= 64);
    let first = &site.robots[..16];
    for row in 0..4 {
        let y0 = 5.0 * f64::from(row);
        let in_row: Vec<_> = first
            .iter()
            .filter(|r| (y0..y0 + 5.0).contains(&r.start[1]))
            .collect();
        assert_eq!(in_row.len(), 4, "row {row}");
        assert!(in_row.iter().any(|r| r.start[0] < 10.0), "row {row}");
        assert!(in_row.iter().any(|r| r.start[0] >= 10.0), "row {row}");
    }
    for (i, a) in site.robots.iter().enumerate() {
        for b in &site.robots[i + 1..] {
            let d = (a.start[0] - b.start[0]).hypot(a.start[1] - b.start[1]);
            assert!(d > 0.35, "{} and {} start {d:.2} m apart", a.id, b.id);
        }
    }
}
