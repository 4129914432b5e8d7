//! The zones of `ickon sim --routers N`: the site's cells split into N
//! contiguous groups along the site's longest axis, one router each, as a
//! site with a router per zone (a floor, a hall, a wing) is cabled.
//!
//! The split is by cell count (zones differ by at most one cell), not by
//! area: a router's load is its clients' traffic, and a cell's traffic (its
//! bursts, its status) does not grow with its floor area. It depends only on
//! the site file, so every run of a site has the same zones. A robot belongs
//! to the zone of the cell its start lies in (else of the cell whose centre
//! is nearest to its start): its agent stays a client of that zone's router
//! for the whole run, as a robot's computer keeps one router on a site.

use ickon_proto::site::Site;

/// The zone names and the names of their routers' processes start here
/// (`z1`, `router z1`).
const FIRST_ZONE: usize = 1;

/// Why a site cannot be split into the zones asked for.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ZoneError {
    /// No zone asked for.
    #[error("--routers 0: a run needs at least one router")]
    NoZone,
    /// More zones than cells: a zone would have no cell.
    #[error(
        "--routers {zones} is more than the {cells} cells of the site: each zone's router serves at least one cell (1 to {cells})"
    )]
    MoreZonesThanCells {
        /// Zones asked for.
        zones: usize,
        /// Cells of the site.
        cells: usize,
    },
    /// A robot of the run is not one of the site's.
    #[error("robot {0:?} is not one of the site's robots")]
    UnknownRobot(String),
}

/// One zone: its cells and the robots that start in it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Zone {
    /// `z1`, `z2`, ... in order along the site's longest axis.
    pub name: String,
    /// Ids of its cells, in order along the axis.
    pub cells: Vec<String>,
    /// Ids of the run's robots whose start lies in it, in the run's order.
    pub robots: Vec<String>,
}

/// Splits `site` into `n` zones and places each of `robots` in one.
pub fn split(site: &Site, robots: &[String], n: usize) -> Result<Vec<Zone>, ZoneError> {
    if n == 0 {
        return Err(ZoneError::NoZone);
    }
    if n > site.cells.len() {
        return Err(ZoneError::MoreZonesThanCells {
            zones: n,
            cells: site.cells.len(),
        });
    }
    let (lo, hi) = site.bounds();
    let axis = usize::from(hi[1] - lo[1] > hi[0] - lo[0]);
    let centres: Vec<[f64; 2]> = site.cells.iter().map(|c| centre(&c.polygon)).collect();
    let mut order: Vec<usize> = (0..site.cells.len()).collect();
    // Along the axis, then across it, then by id: a total order, so that
    // cells side by side across the axis always fall the same way.
    order.sort_by(|&a, &b| {
        centres[a][axis]
            .total_cmp(&centres[b][axis])
            .then(centres[a][1 - axis].total_cmp(&centres[b][1 - axis]))
            .then(site.cells[a].id.cmp(&site.cells[b].id))
    });
    let (base, extra) = (order.len() / n, order.len() % n);
    let mut zone_of_cell = vec![0; site.cells.len()];
    let mut zones = Vec::with_capacity(n);
    let mut next = 0;
    for z in 0..n {
        let size = base + usize::from(z < extra);
        let members = &order[next..next + size];
        next += size;
        for &c in members {
            zone_of_cell[c] = z;
        }
        zones.push(Zone {
            name: format!("z{}", z + FIRST_ZONE),
            cells: members.iter().map(|&c| site.cells[c].id.clone()).collect(),
            robots: Vec::new(),
        });
    }
    for robot in robots {
        let spec = site
            .robots
            .iter()
            .find(|r| &r.id == robot)
            .ok_or_else(|| ZoneError::UnknownRobot(robot.clone()))?;
        let start = [spec.start[0], spec.start[1]];
        let cell = site
            .cells
            .iter()
            .position(|c| c.contains(start))
            .unwrap_or_else(|| nearest(&centres, start));
        zones[zone_of_cell[cell]].robots.push(robot.clone());
    }
    Ok(zones)
}

/// The name of the router process of zone `zone` of `count`: `router` when
/// there is one (the layout of a run without zones), else `router <zone>`.
pub fn router_name(zone: &Zone, count: usize) -> String {
    if count == 1 {
        "router".to_string()
    } else {
        format!("router {}", zone.name)
    }
}

/// The zones of a run and where each zone's router listens: the first
/// router is the hub the others link to (a star: no loop for a message to
/// go round, and any two zones two router hops apart at most).
#[derive(Debug, Clone)]
pub struct ZonedMesh {
    zones: Vec<Zone>,
    /// `(endpoint, port)` of each zone's router, in zone order.
    listeners: Vec<(String, u16)>,
}

impl ZonedMesh {
    /// The zones with their routers' listeners, one per zone; `None`
    /// unless there is at least one zone and as many listeners as zones.
    pub fn new(zones: Vec<Zone>, listeners: Vec<(String, u16)>) -> Option<Self> {
        (!zones.is_empty() && zones.len() == listeners.len())
            .then_some(ZonedMesh { zones, listeners })
    }

    /// The zones, in order along the site's axis.
    pub fn zones(&self) -> &[Zone] {
        &self.zones
    }

    /// The hub's endpoint: the first router's, where the central unit, the
    /// world and the launcher connect, and the other routers link.
    pub fn hub(&self) -> &str {
        &self.listeners[0].0
    }

    /// Every router's `(endpoint, port)`, in zone order.
    pub fn listeners(&self) -> &[(String, u16)] {
        &self.listeners
    }

    /// The process name of zone `k`'s router (from 0).
    pub fn router_name(&self, k: usize) -> String {
        router_name(&self.zones[k], self.zones.len())
    }

    /// The endpoint of the router of cell `id`'s zone (the hub for a cell of none).
    pub fn endpoint_of_cell(&self, id: &str) -> &str {
        self.endpoint_where(|z| z.cells.iter().any(|c| c == id))
    }

    /// The endpoint of the router of robot `id`'s zone (the hub for a robot of none).
    pub fn endpoint_of_robot(&self, id: &str) -> &str {
        self.endpoint_where(|z| z.robots.iter().any(|r| r == id))
    }

    fn endpoint_where(&self, member: impl Fn(&Zone) -> bool) -> &str {
        let k = self.zones.iter().position(member).unwrap_or(0);
        &self.listeners[k].0
    }
}

/// The centroid of a polygon (its area's centre of mass, so that an extra
/// vertex along a side does not move it); the mean of its vertices when it
/// has no area.
fn centre(polygon: &[[f64; 2]]) -> [f64; 2] {
    let n = polygon.len();
    let (mut twice_area, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (p, q) = (polygon[i], polygon[(i + 1) % n]);
        let cross = p[0] * q[1] - q[0] * p[1];
        twice_area += cross;
        cx += (p[0] + q[0]) * cross;
        cy += (p[1] + q[1]) * cross;
    }
    if twice_area.abs() > 1e-12 {
        return [cx / (3.0 * twice_area), cy / (3.0 * twice_area)];
    }
    let count = n.max(1) as f64;
    let sum = polygon
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
    [sum[0] / count, sum[1] / count]
}

/// The index of the centre nearest to `p` (the first of equals).
fn nearest(centres: &[[f64; 2]], p: [f64; 2]) -> usize {
    let d = |c: &[f64; 2]| (c[0] - p[0]).hypot(c[1] - p[1]);
    (0..centres.len())
        .min_by(|&a, &b| d(&centres[a]).total_cmp(&d(&centres[b])))
        .unwrap_or(0)
}

/// The robots of each agent process that hosts several: `k` at most
/// each, in the site's order, never two zones in one (a process has one
/// session, to its zone's router); none when each robot has its own (`k`
/// 1).
pub(crate) fn fleets(site: &Site, robots: &[String], k: usize, routers: usize) -> Vec<Vec<String>> {
    if k <= 1 {
        return Vec::new();
    }
    match split(site, robots, routers.max(1)) {
        Ok(zones) if !zones.is_empty() => zones
            .iter()
            .flat_map(|z| z.robots.chunks(k).map(<[String]>::to_vec))
            .collect(),
        _ => robots.chunks(k).map(<[String]>::to_vec).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn site(name: &str) -> Site {
        Site::load_or_default(Some(std::path::Path::new(name)))
            .unwrap()
            .0
    }

    fn all_robots(site: &Site) -> Vec<String> {
        site.robots.iter().map(|r| r.id.clone()).collect()
    }

    /// Every cell and robot in exactly one zone, zones balanced to one
    /// cell, and each zone a contiguous slab along the site's longest axis.
    fn check_partition(site: &Site, robots: &[String], zones: &[Zone]) {
        let mut cells: Vec<&String> = zones.iter().flat_map(|z| &z.cells).collect();
        cells.sort();
        let mut expected: Vec<&String> = site.cells.iter().map(|c| &c.id).collect();
        expected.sort();
        assert_eq!(cells, expected, "every cell once");
        let mut placed: Vec<&String> = zones.iter().flat_map(|z| &z.robots).collect();
        placed.sort();
        let mut wanted: Vec<&String> = robots.iter().collect();
        wanted.sort();
        assert_eq!(placed, wanted, "every robot once");
        let sizes: Vec<usize> = zones.iter().map(|z| z.cells.len()).collect();
        let (min, max) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
        assert!(max - min <= 1, "balanced: {sizes:?}");
        let (lo, hi) = site.bounds();
        let axis = usize::from(hi[1] - lo[1] > hi[0] - lo[0]);
        let along = |id: &String| centre(&site.cell(id).unwrap().polygon)[axis];
        for pair in zones.windows(2) {
            let last = pair[0].cells.iter().map(along).fold(f64::MIN, f64::max);
            let first = pair[1].cells.iter().map(along).fold(f64::MAX, f64::min);
            assert!(
                last <= first,
                "{} ends at {last} m, after {} begins at {first} m",
                pair[0].name,
                pair[1].name
            );
        }
        for zone in zones {
            for robot in &zone.robots {
                let start = site.robots.iter().find(|r| &r.id == robot).unwrap().start;
                if let Some(cell) = site.cell_at([start[0], start[1]]) {
                    assert!(
                        zone.cells.contains(&cell.id),
                        "{robot} starts in {}",
                        cell.id
                    );
                }
            }
        }
    }

    #[test]
    fn every_site_splits_into_balanced_contiguous_zones() {
        for name in ["lab", "warehouse", "hall"] {
            let site = site(name);
            let robots = all_robots(&site);
            for n in 1..=site.cells.len() {
                let zones = split(&site, &robots, n).unwrap();
                assert_eq!(zones.len(), n);
                check_partition(&site, &robots, &zones);
                assert_eq!(split(&site, &robots, n).unwrap(), zones, "deterministic");
            }
        }
    }

    #[test]
    fn the_lab_splits_between_corridor_and_room() {
        let site = site("lab");
        let robots = all_robots(&site);
        let zones = split(&site, &robots, 2).unwrap();
        assert_eq!(zones[0].name, "z1");
        assert_eq!(zones[0].cells, ["c1", "c2"]);
        assert_eq!(zones[1].cells, ["c3", "c4"]);
        assert_eq!(router_name(&zones[1], 2), "router z2");
        assert_eq!(router_name(&zones[0], 1), "router");
    }

    #[test]
    fn the_warehouse_zones_hold_its_robots_by_where_they_start() {
        let site = site("warehouse");
        let robots: Vec<String> = all_robots(&site).into_iter().take(16).collect();
        let zones = split(&site, &robots, 4).unwrap();
        assert!(zones.iter().all(|z| z.cells.len() == 4));
        check_partition(&site, &robots, &zones);
        // Robots keep the run's order inside a zone.
        for z in &zones {
            let pos: Vec<usize> = z
                .robots
                .iter()
                .map(|r| robots.iter().position(|x| x == r).unwrap())
                .collect();
            assert!(pos.windows(2).all(|w| w[0] < w[1]), "{pos:?}");
        }
    }

    #[test]
    fn a_cell_centre_is_its_area_centroid() {
        let square = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        assert_eq!(centre(&square), [1.0, 1.0]);
        // An extra vertex along a side moves the vertex mean, not the centroid.
        let with_extra = [
            [0.0, 0.0],
            [1.0, 0.0],
            [1.5, 0.0],
            [2.0, 0.0],
            [2.0, 2.0],
            [0.0, 2.0],
        ];
        let c = centre(&with_extra);
        assert!(
            (c[0] - 1.0).abs() < 1e-12 && (c[1] - 1.0).abs() < 1e-12,
            "{c:?}"
        );
        // Clockwise the same; no area: the vertices' mean.
        let clockwise = [[0.0, 0.0], [0.0, 2.0], [2.0, 2.0], [2.0, 0.0]];
        assert_eq!(centre(&clockwise), [1.0, 1.0]);
        assert_eq!(centre(&[[0.0, 0.0], [4.0, 0.0]]), [2.0, 0.0]);
        assert_eq!(centre(&[]), [0.0, 0.0]);
    }

    #[test]
    fn impossible_splits_are_refused_with_the_reason() {
        let site = site("lab");
        let robots = all_robots(&site);
        assert_eq!(split(&site, &robots, 0), Err(ZoneError::NoZone));
        let err = split(&site, &robots, 5).unwrap_err();
        assert_eq!(err, ZoneError::MoreZonesThanCells { zones: 5, cells: 4 });
        assert!(err.to_string().contains("1 to 4"), "{err}");
        assert!(split(&site, &robots, usize::MAX).is_err());
        let err = split(&site, &["nobody".to_string()], 1).unwrap_err();
        assert_eq!(err, ZoneError::UnknownRobot("nobody".into()));
    }

    #[test]
    fn a_robot_starting_outside_every_cell_joins_the_nearest() {
        let mut site = site("lab");
        site.robots[0].start = [100.0, 1.0, 0.0];
        site.robots[1].start = [-50.0, 1.0, 0.0];
        let robots = vec![site.robots[0].id.clone(), site.robots[1].id.clone()];
        let zones = split(&site, &robots, 2).unwrap();
        assert_eq!(zones[1].robots, [robots[0].clone()]);
        assert_eq!(zones[0].robots, [robots[1].clone()]);
    }
}
