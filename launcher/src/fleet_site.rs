//! A site with more robots than its file defines: the robots it lacks are
//! added on its own routes, each where the routes are emptiest, so that a
//! fleet of any size up to [`MAX_ROBOTS`] can run on a built-in site. The
//! site's text gains one `[[robots]]` table per added robot and is read back
//! through the same checks as any site file, so every node given the
//! written file sees the same site.

use std::collections::HashSet;
use std::fmt::Write;
use std::path::Path;

use ickon_proto::site::geometry::{self, Point2};
use ickon_proto::site::{Route, Site};
use ickon_runtime::CommandError;
use rand::{Rng, SeedableRng};

/// The largest fleet a site is extended to. 10,000 robots add about
/// 700 kB to the site's text, well inside the 4 MiB every node reads
/// ([`ickon_proto::site::MAX_SITE_FILE_BYTES`]) and the central unit
/// serves in one message; that is the largest fleet `ickon bench central`
/// is sized for. Beyond it the number is a typing error more likely than
/// a fleet.
pub const MAX_ROBOTS: usize = 10_000;

/// The random stream the added robots' places are drawn from (mixed with
/// the run's seed, apart from the other draws of a run).
const FLEET_STREAM: u64 = 0x666c_6565_745f_7369;

/// How far an added robot may sit from the middle of the stretch of route
/// it is put in, as a share of that stretch's half-length: the seed moves
/// the robots, the stretch keeps them apart.
const JITTER_SHARE: f64 = 0.5;

/// Why a site cannot be extended.
#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    /// More robots than [`MAX_ROBOTS`].
    #[error("{asked} robots is more than the {MAX_ROBOTS} a run takes")]
    TooMany {
        /// The robots asked for.
        asked: usize,
    },
    /// Robots are to be added but the site has no route to put them on.
    #[error("site {site:?} has {has} robots and no route to add more on")]
    NoRoute {
        /// The site.
        site: String,
        /// Its robots.
        has: usize,
    },
    /// The extended text did not pass the site checks.
    #[error("the site with robots added is not valid: {0}")]
    Invalid(String),
}

/// The site with `robots` robots: `site` itself (and `None`) when it has
/// that many already, else the site with robots added and its TOML text
/// (`text`, the site's own, followed by the added robots), for the nodes.
pub fn extend(
    site: &Site,
    text: &str,
    robots: usize,
    seed: u64,
) -> Result<(Site, Option<String>), FleetError> {
    if robots > MAX_ROBOTS {
        return Err(FleetError::TooMany { asked: robots });
    }
    if robots <= site.robots.len() {
        return Ok((site.clone(), None));
    }
    let added = added_robots(site, robots - site.robots.len(), seed)?;
    let mut extended = text.trim_end().to_string();
    extended.push_str("\n\n# Robots added to run a larger fleet on this site.\n");
    for robot in &added {
        let _ = write!(
            extended,
            "\n[[robots]]\nid = \"{}\"\nroute = \"{}\"\nstart = [{:.4}, {:.4}, {:.3}]\n",
            robot.id,
            robot.route,
            robot.start[0],
            robot.start[1],
            robot.start[2].to_degrees()
        );
    }
    let site = Site::from_toml(&extended, &format!("{} with {robots} robots", site.name))
        .map_err(|e| FleetError::Invalid(e.to_string()))?;
    Ok((site, Some(extended)))
}

/// The site of a run of `robots` robots on `site` (a built-in name or a
/// file; `lab` when `None`), checked, with the text to write for its nodes
/// when robots were added.
pub fn load(
    site: Option<&Path>,
    robots: usize,
    seed: u64,
) -> Result<(Site, Option<String>), CommandError> {
    let (own, text, _name) =
        Site::load_or_default(site).map_err(|e| CommandError::bad_input(e.to_string()))?;
    extend(&own, &text, robots, seed)
        .map_err(|e| CommandError::bad_input(format!("--robots {robots}: {e}")))
}

/// Writes the extended site of a run into a temporary file that every
/// node is given as `--site` (removed when dropped); `None` when the
/// site's own robots make the fleet.
pub fn write_for_run(
    site: Option<&Path>,
    robots: usize,
    seed: u64,
) -> Result<Option<tempfile::NamedTempFile>, CommandError> {
    let (_, text) = load(site, robots, seed)?;
    let Some(text) = text else {
        return Ok(None);
    };
    let write = || -> std::io::Result<tempfile::NamedTempFile> {
        let mut file = tempfile::Builder::new()
            .prefix("ickon-site-")
            .suffix(".toml")
            .tempfile()?;
        std::io::Write::write_all(&mut file, text.as_bytes())?;
        std::io::Write::flush(&mut file)?;
        Ok(file)
    };
    write()
        .map(Some)
        .map_err(|e| CommandError::failure(format!("cannot write the extended site: {e}")))
}

/// A robot to add: its id, route and start pose (metres, radians).
#[derive(Debug, Clone, PartialEq)]
struct Added {
    id: String,
    route: String,
    start: [f64; 3],
}

/// A stretch of a route between two robots (or a route's end), metres of
/// arc length from the route's first point.
#[derive(Debug, Clone, Copy)]
struct Gap {
    route: usize,
    from_m: f64,
    to_m: f64,
}

impl Gap {
    fn length_m(&self) -> f64 {
        self.to_m - self.from_m
    }
}

/// `count` robots, each put in the longest free stretch of any route at
/// the time (so routes fill in proportion to their length and no two
/// robots share a place), near its middle by the seed's draw.
fn added_robots(site: &Site, count: usize, seed: u64) -> Result<Vec<Added>, FleetError> {
    let routes: Vec<&Route> = site
        .routes
        .iter()
        .filter(|r| r.points.len() >= 2 && r.length_m() > 0.0)
        .collect();
    if routes.is_empty() {
        return Err(FleetError::NoRoute {
            site: site.name.clone(),
            has: site.robots.len(),
        });
    }
    let mut gaps = Vec::new();
    for (i, route) in routes.iter().enumerate() {
        let mut taken: Vec<f64> = site
            .robots
            .iter()
            .filter(|r| r.route == route.name)
            .map(|r| arc_length_at(route, [r.start[0], r.start[1]]))
            .collect();
        gaps.extend(free_stretches(i, route, &mut taken));
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ FLEET_STREAM);
    let mut ids = site
        .robots
        .iter()
        .map(|r| r.id.clone())
        .collect::<HashSet<_>>();
    let mut next_number = site.robots.len() + 1;
    let mut added = Vec::with_capacity(count);
    for _ in 0..count {
        // The longest stretch; the first of equals, so that the choice
        // depends on the site and the seed only.
        let longest = gaps.iter().enumerate().fold(0, |best, (i, g)| {
            if g.length_m() > gaps[best].length_m() {
                i
            } else {
                best
            }
        });
        let gap = gaps.swap_remove(longest);
        let jitter = rng.random_range(-JITTER_SHARE..=JITTER_SHARE);
        let at_m = gap.from_m + gap.length_m() * (0.5 + 0.5 * jitter);
        gaps.push(Gap { to_m: at_m, ..gap });
        gaps.push(Gap {
            from_m: at_m,
            ..gap
        });
        let route = routes[gap.route];
        let id = loop {
            let id = format!("r{next_number}");
            next_number += 1;
            if ids.insert(id.clone()) {
                break id;
            }
        };
        added.push(Added {
            id,
            route: route.name.clone(),
            start: pose_at(route, at_m),
        });
    }
    Ok(added)
}

/// The free stretches of route `index` between the arc lengths in `taken`
/// (sorted here): a closed route's last one comes round to its first.
fn free_stretches(index: usize, route: &Route, taken: &mut [f64]) -> Vec<Gap> {
    let length_m = route.length_m();
    taken.sort_by(f64::total_cmp);
    let gap = |from_m, to_m| Gap {
        route: index,
        from_m,
        to_m,
    };
    let (Some(&first), Some(&last)) = (taken.first(), taken.last()) else {
        // An empty closed route: a robot anywhere on it is as good; one
        // whole stretch from its first point round to it again.
        return vec![gap(0.0, length_m)];
    };
    let mut gaps: Vec<Gap> = taken.windows(2).map(|w| gap(w[0], w[1])).collect();
    if route.closed {
        // Past the route's end, arc lengths go on round the loop.
        gaps.push(gap(last, first + length_m));
    } else {
        gaps.push(gap(0.0, first));
        gaps.push(gap(last, length_m));
    }
    gaps
}

/// The arc length along `route` of its point nearest `p`, metres.
fn arc_length_at(route: &Route, p: Point2) -> f64 {
    let (q, segment) = route.nearest_point(p);
    let before: f64 = geometry::polyline_segments(&route.points, route.closed)
        .take(segment)
        .map(|(a, b)| (b[0] - a[0]).hypot(b[1] - a[1]))
        .sum();
    let a = route.points[segment];
    before + (q[0] - a[0]).hypot(q[1] - a[1])
}

/// The pose on `route` at arc length `s_m` (taken round a closed route),
/// heading along it.
fn pose_at(route: &Route, s_m: f64) -> [f64; 3] {
    let length_m = route.length_m();
    let s_m = if route.closed {
        s_m.rem_euclid(length_m)
    } else {
        s_m.clamp(0.0, length_m)
    };
    let p = geometry::point_at_arc_length(&route.points, route.closed, s_m);
    // The heading of the stretch the point lies on: towards a point a
    // little further (round a closed route; at an open route's end, from
    // one a little before).
    const STEP_M: f64 = 0.01;
    let at = |s_m: f64| geometry::point_at_arc_length(&route.points, route.closed, s_m);
    let (from, to) = if route.closed {
        (p, at((s_m + STEP_M).rem_euclid(length_m)))
    } else if s_m + STEP_M <= length_m {
        (p, at(s_m + STEP_M))
    } else {
        (at(s_m - STEP_M), p)
    };
    [p[0], p[1], (to[1] - from[1]).atan2(to[0] - from[0])]
}

#[cfg(test)]
#[path = "fleet_site_tests.rs"]
mod tests;
