//! The validated site model.

use super::geometry::{self, Point2};

/// Speed of sound in dry air at `temperature_c`, m/s (331.3 sqrt(1 + T/273.15)).
pub fn speed_of_sound_at(temperature_c: f64) -> f64 {
    331.3 * (1.0 + temperature_c / 273.15).sqrt()
}

/// The mobile sensory unit's receiver arrangement.
#[derive(Debug, Clone, PartialEq)]
pub struct MsuGeometry {
    /// Pointing angle of each receiver relative to the robot's heading,
    /// counter-clockwise, radians; receiver `i` is `receiver_angles_rad[i]`.
    pub receiver_angles_rad: Vec<f64>,
    /// Height of the receivers above the floor, metres.
    pub height_m: f64,
    /// Number of carrier channels the receivers can tell apart (channels
    /// `0..channels`); every transmitter's channel must be one of them.
    pub channels: u8,
}

/// One cell: a floor polygon served by one cell controller.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Cell id (a key chunk).
    pub id: String,
    /// Floor polygon, metres, counter-clockwise.
    pub polygon: Vec<Point2>,
}

impl Cell {
    /// Floor area, m^2.
    pub fn area_m2(&self) -> f64 {
        geometry::signed_area(&self.polygon).abs()
    }

    /// Whether a floor point lies in the cell (boundary included).
    pub fn contains(&self, p: Point2) -> bool {
        geometry::contains(&self.polygon, p, 1e-9)
    }
}

/// One ceiling transmitter.
#[derive(Debug, Clone, PartialEq)]
pub struct Transmitter {
    /// Id the transmitter sends in its burst.
    pub id: u32,
    /// Cell that fires it.
    pub cell: String,
    /// Position, metres (x, y on the floor, z height).
    pub position_m: [f64; 3],
    /// Carrier channel (0 unless the file says otherwise): bursts on
    /// different channels do not collide at a receiver.
    pub channel: u8,
}

/// A wall segment that blocks sound up to its height.
#[derive(Debug, Clone, PartialEq)]
pub struct Wall {
    /// One end, metres.
    pub from: Point2,
    /// Other end, metres.
    pub to: Point2,
    /// Height, metres (the ceiling when not given).
    pub height_m: f64,
}

/// A column: a polygon that blocks sound and robots up to its height.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// Outline, metres.
    pub polygon: Vec<Point2>,
    /// Height, metres (the ceiling when not given).
    pub height_m: f64,
}

/// A named route the robots follow, with its evaluation reference points.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// Route name.
    pub name: String,
    /// Polyline vertices, metres.
    pub points: Vec<Point2>,
    /// Whether a tour returns to the first point.
    pub closed: bool,
    /// Reference points where the error is measured (the ICKON paper: 60 per route),
    /// evenly spaced along the route starting at its first point.
    pub reference_points: Vec<Point2>,
    /// Cruise speed, m/s.
    pub speed_m_s: f64,
}

impl Route {
    /// Length of one tour, metres.
    pub fn length_m(&self) -> f64 {
        geometry::polyline_length(&self.points, self.closed)
    }

    /// The point of the route nearest to `p`, and the index of the segment it lies on.
    pub fn nearest_point(&self, p: Point2) -> (Point2, usize) {
        let mut best = (f64::INFINITY, self.points.first().copied().unwrap_or(p), 0);
        for (i, (a, b)) in geometry::polyline_segments(&self.points, self.closed).enumerate() {
            let q = geometry::closest_on_segment(p, a, b);
            let d = (q[0] - p[0]).hypot(q[1] - p[1]);
            if d < best.0 {
                best = (d, q, i);
            }
        }
        (best.1, best.2)
    }

    /// The route as a robot starting at `p` drives it: it begins at the
    /// route's point nearest to `p` and then follows the same vertices (a
    /// closed route comes round to where it began; an open one drops what lies
    /// before). Robots sharing a route start spread along it this way, each
    /// on its own copy. Reference points are kept as they are.
    pub fn starting_near(&self, p: Point2) -> Route {
        let (q, seg) = self.nearest_point(p);
        let n = self.points.len();
        let tail: Vec<Point2> = if self.closed {
            (1..=n).map(|k| self.points[(seg + k) % n]).collect()
        } else {
            self.points[(seg + 1).min(n)..].to_vec()
        };
        let mut points = vec![q];
        for v in tail {
            let last = points[points.len() - 1];
            if (v[0] - last[0]).hypot(v[1] - last[1]) > 1e-9 {
                points.push(v);
            }
        }
        // The closing vertex may coincide with the new start.
        if self.closed && points.len() > 1 {
            let last = points[points.len() - 1];
            if (q[0] - last[0]).hypot(q[1] - last[1]) <= 1e-9 {
                points.pop();
            }
        }
        if points.len() < 2 {
            return self.clone();
        }
        Route {
            points,
            ..self.clone()
        }
    }
}

/// A robot and the route it drives.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotSpec {
    /// Robot id (a key chunk).
    pub id: String,
    /// Name of its route.
    pub route: String,
    /// Start pose: x, y in metres and heading in radians.
    pub start: [f64; 3],
}

/// A validated site.
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// Site name, the `<site>` of every key.
    pub name: String,
    /// Speed of sound, m/s.
    pub speed_of_sound_m_s: f64,
    /// Temperature it was derived from, if the file gave one.
    pub temperature_c: Option<f64>,
    /// Reverberation guard added to every slot, seconds.
    pub guard_time_s: f64,
    /// Length of one coded burst, seconds: two bursts on one channel must
    /// reach a receiver at least this plus [`Site::decoder_window_s`] apart.
    pub burst_length_s: f64,
    /// How long after a burst's onset the MSU's decoder still takes in
    /// sound as part of it, seconds (beyond the burst itself).
    pub decoder_window_s: f64,
    /// Ceiling height, metres (walls and columns without a height reach it).
    pub ceiling_height_m: f64,
    /// MSU geometry, the same on every robot.
    pub msu: MsuGeometry,
    /// Cells, in file order.
    pub cells: Vec<Cell>,
    /// Transmitters, in file order.
    pub transmitters: Vec<Transmitter>,
    /// Wall segments.
    pub walls: Vec<Wall>,
    /// Columns.
    pub columns: Vec<Column>,
    /// Routes.
    pub routes: Vec<Route>,
    /// Robots.
    pub robots: Vec<RobotSpec>,
}

impl Site {
    /// The cell with this id.
    pub fn cell(&self, id: &str) -> Option<&Cell> {
        self.cells.iter().find(|c| c.id == id)
    }

    /// The transmitter with this id.
    pub fn transmitter(&self, id: u32) -> Option<&Transmitter> {
        self.transmitters.iter().find(|t| t.id == id)
    }

    /// The transmitters of one cell, in file order.
    pub fn transmitters_of<'a>(&'a self, cell: &'a str) -> impl Iterator<Item = &'a Transmitter> {
        self.transmitters.iter().filter(move |t| t.cell == cell)
    }

    /// The route with this name.
    pub fn route(&self, name: &str) -> Option<&Route> {
        self.routes.iter().find(|r| r.name == name)
    }

    /// The cell containing a floor point, if any.
    pub fn cell_at(&self, p: Point2) -> Option<&Cell> {
        self.cells.iter().find(|c| c.contains(p))
    }

    /// Total floor area of the cells, m^2.
    pub fn area_m2(&self) -> f64 {
        self.cells.iter().map(Cell::area_m2).sum()
    }

    /// Bounding box of the cells: `([min_x, min_y], [max_x, max_y])`.
    pub fn bounds(&self) -> (Point2, Point2) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in self.cells.iter().flat_map(|c| c.polygon.iter()) {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Whether the straight line from `a` to `b` (3D, metres) clears every wall
    /// and column: an obstacle blocks it where the line passes over its footprint
    /// lower than its height.
    pub fn line_of_sight(&self, a: [f64; 3], b: [f64; 3]) -> bool {
        line_of_sight(&self.walls, &self.columns, a, b)
    }

    /// Whether a robot can drive straight from `a` to `b` (no wall or column in between).
    pub fn drivable(&self, a: Point2, b: Point2) -> bool {
        let hits_wall = self
            .walls
            .iter()
            .any(|w| geometry::segment_crossing(a, b, w.from, w.to).is_some());
        let hits_column = self.columns.iter().any(|c| {
            geometry::contains(&c.polygon, a, 0.0)
                || geometry::contains(&c.polygon, b, 0.0)
                || geometry::polyline_segments(&c.polygon, true)
                    .any(|(p, q)| geometry::segment_crossing(a, b, p, q).is_some())
        });
        !hits_wall && !hits_column
    }
}

/// Whether the straight line from `a` to `b` (3D, metres) clears every one
/// of `walls` and `columns`: an obstacle blocks it where the line passes
/// over its footprint lower than its height.
pub fn line_of_sight(walls: &[Wall], columns: &[Column], a: [f64; 3], b: [f64; 3]) -> bool {
    let (pa, pb) = ([a[0], a[1]], [b[0], b[1]]);
    let height_at = |t: f64| a[2] + t * (b[2] - a[2]);
    for w in walls {
        if let Some(t) = geometry::segment_crossing(pa, pb, w.from, w.to)
            && height_at(t) < w.height_m
        {
            return false;
        }
    }
    for c in columns {
        let n = c.polygon.len();
        for i in 0..n {
            if let Some(t) =
                geometry::segment_crossing(pa, pb, c.polygon[i], c.polygon[(i + 1) % n])
                && height_at(t) < c.height_m
            {
                return false;
            }
        }
    }
    true
}
