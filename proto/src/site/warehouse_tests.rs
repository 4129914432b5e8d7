//! The built-in `warehouse` site: valid, as large as promised, covered
//! everywhere a robot drives, its racks blocking sound and robots.

use super::geometry::{self, Point2};
use super::*;

/// The audible range of a burst in the `harsh` profile (`paper`: 12 m); the
/// coverage test takes the shorter one.
const AUDIBLE_M: f64 = 10.0;
/// Half a robot's width: routes keep at least this far from racks and pillars.
const ROBOT_HALF_WIDTH_M: f64 = 0.3;

fn warehouse() -> Site {
    Site::builtin("warehouse").expect("built-in warehouse").0
}

/// Points every `step_m` along a route.
fn along(route: &Route, step_m: f64) -> Vec<Point2> {
    let n = (route.length_m() / step_m).ceil() as usize;
    (0..n)
        .map(|k| geometry::point_at_arc_length(&route.points, route.closed, k as f64 * step_m))
        .collect()
}

fn audible(site: &Site, p: Point2) -> Vec<u32> {
    let q = [p[0], p[1], site.msu.height_m];
    site.transmitters
        .iter()
        .filter(|t| {
            let d = t.position_m;
            let dist =
                ((d[0] - q[0]).powi(2) + (d[1] - q[1]).powi(2) + (d[2] - q[2]).powi(2)).sqrt();
            dist <= AUDIBLE_M && site.line_of_sight(d, q)
        })
        .map(|t| t.id)
        .collect()
}

#[test]
fn warehouse_is_valid_and_as_large_as_promised() {
    let site = warehouse();
    assert_eq!(site.name, "warehouse");
    assert!(site.cells.len() >= 16, "{} cells", site.cells.len());
    assert!(site.area_m2() >= 400.0, "{} m2", site.area_m2());
    assert!(site.robots.len() >= 64, "{} robots", site.robots.len());
    assert!(!site.columns.is_empty());
    for cell in &site.cells {
        assert!(site.transmitters_of(&cell.id).count() >= 4, "{}", cell.id);
    }
    // Every built-in site loads by name, and a name that is not built in is a file.
    for (name, _) in BUILTIN_SITES {
        let (s, text, file) = Site::load_or_default(Some(Path::new(name))).unwrap();
        assert_eq!(s.name, name);
        assert_eq!(Site::from_toml(&text, &file).unwrap(), s);
    }
    let err = Site::load_or_default(Some(Path::new("no-such-site"))).unwrap_err();
    assert!(matches!(err, SiteError::Io { .. }), "{err}");
}

#[test]
fn every_point_of_every_warehouse_route_hears_enough_transmitters() {
    let site = warehouse();
    for route in &site.routes {
        for p in along(route, 0.25) {
            let heard = audible(&site, p);
            // Four for a 3D fix with one to spare against a dropped burst.
            assert!(
                heard.len() >= 5,
                "{} at ({:.2}, {:.2}) hears {:?}",
                route.name,
                p[0],
                p[1],
                heard
            );
        }
    }
}

#[test]
fn racks_block_the_sound_between_aisles() {
    let site = warehouse();
    // A transmitter over the middle of aisle 1 cannot be heard in aisle 2
    // beside it: the rack row between them is higher than the transmitter.
    let tx = site.transmitter(121).unwrap().position_m;
    let aisle_2_centre = [tx[0], 5.7, site.msu.height_m];
    assert!(site.cell_at([tx[0], 5.7]).is_some_and(|c| c.id == "c22"));
    assert!(!site.line_of_sight(tx, aisle_2_centre));
    assert!(site.line_of_sight(tx, [tx[0] + 2.0, tx[1] + 1.0, site.msu.height_m]));
}

#[test]
fn warehouse_routes_stay_off_racks_and_pillars() {
    let site = warehouse();
    for route in &site.routes {
        for p in along(route, 0.1) {
            assert!(
                site.cell_at(p).is_some(),
                "{} leaves the cells at {p:?}",
                route.name
            );
            for (k, c) in site.columns.iter().enumerate() {
                assert!(
                    !geometry::contains(&c.polygon, p, ROBOT_HALF_WIDTH_M),
                    "{} at {p:?} is within {ROBOT_HALF_WIDTH_M} m of columns[{k}]",
                    route.name
                );
            }
        }
    }
}

#[test]
fn warehouse_robots_start_apart_on_their_routes() {
    let site = warehouse();
    for (i, a) in site.robots.iter().enumerate() {
        let route = site.route(&a.route).unwrap();
        let (q, _) = route.nearest_point([a.start[0], a.start[1]]);
        assert!(
            (q[0] - a.start[0]).hypot(q[1] - a.start[1]) < 1e-6,
            "{}",
            a.id
        );
        for b in &site.robots[i + 1..] {
            let d = (a.start[0] - b.start[0]).hypot(a.start[1] - b.start[1]);
            assert!(d > 0.35, "{} and {} start {d:.2} m apart", a.id, b.id);
        }
    }
    // The first 16 robots (`ickon sim --robots 16`) drive every route.
    let routes: std::collections::BTreeSet<&str> =
        site.robots[..16].iter().map(|r| r.route.as_str()).collect();
    assert_eq!(routes.len(), site.routes.len());
}

#[test]
fn a_route_started_near_a_point_begins_there_and_keeps_its_loop() {
    let site = warehouse();
    let route = site.route("aisle-1").unwrap();
    let moved = route.starting_near([20.0, 0.7]);
    assert_eq!(moved.points[0], [20.0, 1.0]);
    assert!((moved.length_m() - route.length_m()).abs() < 1e-9);
    assert_eq!(moved.points.len(), route.points.len() + 1);
    // Starting on a vertex adds none.
    let same = route.starting_near(route.points[2]);
    assert_eq!(same.points.len(), route.points.len());
    assert_eq!(same.points[0], route.points[2]);
    // An open route drops what lies before the start.
    let open = Route {
        closed: false,
        ..route.clone()
    };
    let cut = open.starting_near([20.0, 1.0]);
    assert_eq!(
        cut.points,
        vec![
            [20.0, 1.0],
            route.points[1],
            route.points[2],
            route.points[3]
        ]
    );
}

#[test]
fn a_robot_start_off_its_route_is_refused() {
    // The first robot's start line (not the comment that shows the format).
    let first = WAREHOUSE_SITE_TOML.find("\nstart = [").unwrap() + 1;
    let end = first + WAREHOUSE_SITE_TOML[first..].find('\n').unwrap();
    let text = format!(
        "{}start = [20.0, 2.7, 0.0]{}",
        &WAREHOUSE_SITE_TOML[..first],
        &WAREHOUSE_SITE_TOML[end..]
    );
    let err = Site::from_toml(&text, "w.toml").unwrap_err().to_string();
    assert!(
        err.contains("robots[0].start") && err.contains("from route"),
        "{err}"
    );
}
