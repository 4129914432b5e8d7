//! Robots added to a site: the same for the same seed, spread over the
//! routes, with ids of their own, and a site every node reads the same.

use std::collections::HashSet;

use super::*;

fn warehouse() -> (Site, &'static str) {
    Site::builtin("warehouse").expect("built in")
}

fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[test]
fn the_same_seed_adds_the_same_robots_and_another_seed_moves_them() {
    let (site, text) = warehouse();
    let (a, a_text) = extend(&site, text, 256, 7).expect("extends");
    let (b, b_text) = extend(&site, text, 256, 7).expect("extends");
    assert_eq!(a, b);
    assert_eq!(a_text, b_text);
    let (c, _) = extend(&site, text, 256, 8).expect("extends");
    assert_eq!(a.robots.len(), c.robots.len());
    // Same ids and routes (the stretches are the site's), other places.
    let moved = a.robots[128..]
        .iter()
        .zip(&c.robots[128..])
        .filter(|(x, y)| x.id == y.id && x.route == y.route && distance_m(x.start, y.start) > 1e-3)
        .count();
    assert!(
        moved > 100,
        "only {moved} of 128 robots moved with the seed"
    );
}

#[test]
fn added_robots_start_apart_from_each_other_and_the_sites_own() {
    let (site, text) = warehouse();
    let (extended, _) = extend(&site, text, 1000, 1).expect("extends");
    assert_eq!(extended.robots.len(), 1000);
    assert_eq!(extended.robots[..128], site.robots[..]);
    // Every start on its route, as the world will drive it.
    for robot in &extended.robots[128..] {
        let route = extended.route(&robot.route).expect("route exists");
        let (q, _) = route.nearest_point([robot.start[0], robot.start[1]]);
        assert!((q[0] - robot.start[0]).hypot(q[1] - robot.start[1]) < 1e-3);
    }
    // No two robots of one route closer along it than a third of the
    // route's length shared out evenly among them.
    for route in &extended.routes {
        let mut along: Vec<f64> = extended
            .robots
            .iter()
            .filter(|r| r.route == route.name)
            .map(|r| arc_length_at(route, [r.start[0], r.start[1]]))
            .collect();
        along.sort_by(f64::total_cmp);
        let even_m = route.length_m() / along.len() as f64;
        for w in along.windows(2) {
            assert!(
                w[1] - w[0] > even_m / 3.0,
                "route {}: robots {:.2} m apart where {even_m:.2} m is even",
                route.name,
                w[1] - w[0]
            );
        }
    }
    // And no two starts at one place on the floor, whatever their routes.
    let starts = &extended.robots;
    for (i, a) in starts.iter().enumerate() {
        for b in &starts[i + 1..] {
            assert!(
                distance_m(a.start, b.start) > 0.05,
                "{} and {} start at one place",
                a.id,
                b.id
            );
        }
    }
}

#[test]
fn routes_fill_in_proportion_to_their_length() {
    let (site, text) = warehouse();
    let (extended, _) = extend(&site, text, 1024, 3).expect("extends");
    let total_m: f64 = extended.routes.iter().map(Route::length_m).sum();
    for route in &extended.routes {
        let on = extended
            .robots
            .iter()
            .filter(|r| r.route == route.name)
            .count() as f64;
        let fair = 1024.0 * route.length_m() / total_m;
        assert!(
            (on - fair).abs() <= 0.5 * fair + 2.0,
            "route {}: {on} robots, {fair:.1} in proportion to its length",
            route.name
        );
    }
}

#[test]
fn added_ids_are_unique_and_clear_of_the_sites_own() {
    // A site whose own ids hold the numbers the added robots would take.
    let (lab, text) = Site::builtin("lab").expect("built in");
    let route = &lab.routes[0];
    let p = route.points[0];
    let text = format!(
        "{text}\n[[robots]]\nid = \"r{}\"\nroute = \"{}\"\nstart = [{}, {}, 0.0]\n",
        lab.robots.len() + 2,
        route.name,
        p[0],
        p[1]
    );
    let site = Site::from_toml(&text, "lab with an r7").expect("valid");
    let (extended, _) = extend(&site, &text, 40, 1).expect("extends");
    let ids: HashSet<&str> = extended.robots.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(ids.len(), 40);
    for own in &site.robots {
        assert_eq!(
            extended.robots.iter().filter(|r| r.id == own.id).count(),
            1,
            "{} taken twice",
            own.id
        );
    }
}

#[test]
fn the_extended_text_loads_as_the_same_site_and_passes_the_site_checks() {
    for name in ["lab", "warehouse", "hall"] {
        let (site, text) = Site::builtin(name).expect("built in");
        let (extended, written) = extend(&site, text, 300, 5).expect("extends");
        let written = written.expect("robots were added");
        // What every node reads from the file the launcher writes.
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("site.toml");
        std::fs::write(&path, &written).expect("written");
        let read = Site::from_file(&path).expect("passes the site checks");
        assert_eq!(read, extended, "{name}");
        ickon_operator::check_site(Some(&path)).expect("`ickon site check` takes it");
        // Everything but the robots is the site's own.
        assert_eq!(read.cells, site.cells);
        assert_eq!(read.transmitters, site.transmitters);
        assert_eq!(read.routes, site.routes);
    }
}

#[test]
fn a_fleet_the_site_holds_is_the_site_itself() {
    let (site, text) = warehouse();
    let (same, written) = extend(&site, text, 128, 1).expect("fits");
    assert_eq!(same, site);
    assert!(written.is_none());
}

#[test]
fn too_many_robots_or_no_route_is_refused() {
    let (site, text) = warehouse();
    let e = extend(&site, text, MAX_ROBOTS + 1, 1).expect_err("too many");
    assert!(e.to_string().contains("10000"), "{e}");
    let mut bare = site.clone();
    bare.routes.clear();
    let e = added_robots(&bare, 3, 1).expect_err("nowhere to put them");
    assert!(e.to_string().contains("no route"), "{e}");
}
