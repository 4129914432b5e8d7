//! From TOML text to a validated [`Site`], collecting every problem with its line.

use std::collections::{HashMap, HashSet};
use std::ops::Range;

use toml::Spanned;

use super::geometry::{self, Point2};
use super::model::*;
use super::raw::*;
use super::{SiteError, SiteIssue};
use crate::keys::validate_id;

/// How close (metres) a transmitter may come to a wall before it counts as inside it.
const WALL_CLEARANCE_M: f64 = 0.05;
/// Temperature used when the file gives neither a temperature nor a speed of sound.
const DEFAULT_TEMPERATURE_C: f64 = 20.0;
/// Reverberation guard when the file gives none, seconds.
const DEFAULT_GUARD_TIME_MS: f64 = 10.0;
/// Burst length when the file gives none, milliseconds.
const DEFAULT_BURST_LENGTH_MS: f64 = 2.0;
/// Decoder window when the file gives none, milliseconds.
const DEFAULT_DECODER_WINDOW_MS: f64 = 0.5;
/// Most carrier channels an MSU can declare.
pub(super) const MAX_CHANNELS: i64 = 16;
/// Ceiling when the file gives none, metres.
const DEFAULT_CEILING_M: f64 = 3.0;
/// Reference points per route when the file gives no count (the ICKON paper uses 60).
const DEFAULT_REFERENCE_POINTS: i64 = 60;
/// Route speed when the file gives none, m/s (a cautious Pioneer 3-DX pace).
const DEFAULT_ROUTE_SPEED_M_S: f64 = 0.3;
/// Cells need at least this many transmitters for a 2D fix with known height.
const MIN_TRANSMITTERS_PER_CELL: usize = 3;
/// How far a robot's `start` may lie from its route: the world starts it on the
/// route, so its filter's start pose must be there too.
const MAX_START_OFF_ROUTE_M: f64 = 0.5;

struct Ctx<'a> {
    text: &'a str,
    issues: Vec<SiteIssue>,
}

impl Ctx<'_> {
    fn issue(&mut self, span: Range<usize>, field: impl Into<String>, message: impl Into<String>) {
        self.issues
            .push(SiteIssue::at(self.text, span, field, message));
    }

    fn finite_all(&mut self, span: Range<usize>, field: &str, values: &[f64]) -> bool {
        if values.iter().all(|v| v.is_finite()) {
            true
        } else {
            self.issue(span, field, "must be a finite number (not nan or inf)");
            false
        }
    }

    /// A finite number in `[lo, hi]`; `unit` is named in the message.
    fn in_range(&mut self, v: &Spanned<f64>, field: &str, lo: f64, hi: f64, unit: &str) -> bool {
        let x = *v.get_ref();
        if !self.finite_all(v.span(), field, &[x]) {
            return false;
        }
        if x < lo || x > hi {
            self.issue(
                v.span(),
                field,
                format!("{x} {unit} is out of range: expected {lo} to {hi} {unit}"),
            );
            return false;
        }
        true
    }

    fn id(&mut self, v: &Spanned<String>, field: &str) -> bool {
        match validate_id(v.get_ref()) {
            Ok(()) => true,
            Err(e) => {
                self.issue(v.span(), field, e.to_string());
                false
            }
        }
    }

    fn polygon(&mut self, v: &Spanned<Vec<Point2>>, field: &str) -> bool {
        let pts = v.get_ref();
        let flat: Vec<f64> = pts.iter().flatten().copied().collect();
        if !self.finite_all(v.span(), field, &flat) {
            return false;
        }
        if flat.iter().any(|x| x.abs() > MAX_EXTENT_M) {
            // Finite but absurd (1e308): areas and distances would overflow to inf.
            self.issue(
                v.span(),
                field,
                format!("coordinates must lie within +-{MAX_EXTENT_M} m"),
            );
            return false;
        }
        if pts.len() < 3 {
            self.issue(
                v.span(),
                field,
                format!("a polygon needs at least 3 vertices, got {}", pts.len()),
            );
            return false;
        }
        if geometry::signed_area(pts).abs() < 1e-6 {
            self.issue(v.span(), field, "polygon has no area");
            return false;
        }
        if geometry::self_intersects(pts) {
            self.issue(v.span(), field, "polygon edges cross each other");
            return false;
        }
        true
    }
}

/// The largest polygon coordinate a site may have, metres (1000 km: no
/// building is larger, and squares of it stay far from overflow).
const MAX_EXTENT_M: f64 = 1e6;

fn counter_clockwise(mut polygon: Vec<Point2>) -> Vec<Point2> {
    if geometry::signed_area(&polygon) < 0.0 {
        polygon.reverse();
    }
    polygon
}

pub(super) fn parse_and_validate(text: &str, file: &str) -> Result<Site, SiteError> {
    let mut ctx = Ctx {
        text,
        issues: Vec::new(),
    };
    let raw: RawSite = match toml::from_str(text) {
        Ok(raw) => raw,
        Err(e) => {
            let span = e.span().unwrap_or(0..0);
            ctx.issue(span, "(syntax)", e.message().trim().to_string());
            return Err(SiteError::Invalid {
                file: file.to_string(),
                issues: ctx.issues,
            });
        }
    };
    let site = validate(&mut ctx, raw);
    if ctx.issues.is_empty() {
        Ok(site)
    } else {
        ctx.issues.sort_by_key(|i| (i.line, i.column));
        Err(SiteError::Invalid {
            file: file.to_string(),
            issues: ctx.issues,
        })
    }
}

fn validate(ctx: &mut Ctx, raw: RawSite) -> Site {
    ctx.id(&raw.name, "name");

    let (speed, temperature) = match (&raw.speed_of_sound_m_s, &raw.temperature_c) {
        (Some(s), Some(_)) => {
            ctx.issue(
                s.span(),
                "speed_of_sound_m_s",
                "give either speed_of_sound_m_s or temperature_c, not both",
            );
            (*s.get_ref(), None)
        }
        (Some(s), None) => {
            ctx.in_range(s, "speed_of_sound_m_s", 300.0, 400.0, "m/s");
            (*s.get_ref(), None)
        }
        (None, Some(t)) => {
            ctx.in_range(t, "temperature_c", -40.0, 60.0, "degC");
            (speed_of_sound_at(*t.get_ref()), Some(*t.get_ref()))
        }
        (None, None) => (
            speed_of_sound_at(DEFAULT_TEMPERATURE_C),
            Some(DEFAULT_TEMPERATURE_C),
        ),
    };
    let guard_ms = match &raw.guard_time_ms {
        Some(g) => {
            ctx.in_range(g, "guard_time_ms", 0.0, 1000.0, "ms");
            *g.get_ref()
        }
        None => DEFAULT_GUARD_TIME_MS,
    };
    let mut optional_ms = |v: &Option<Spanned<f64>>, field: &str, default: f64| match v {
        Some(g) => {
            ctx.in_range(g, field, 0.0, 100.0, "ms");
            *g.get_ref()
        }
        None => default,
    };
    let burst_ms = optional_ms(
        &raw.burst_length_ms,
        "burst_length_ms",
        DEFAULT_BURST_LENGTH_MS,
    );
    let window_ms = optional_ms(
        &raw.decoder_window_ms,
        "decoder_window_ms",
        DEFAULT_DECODER_WINDOW_MS,
    );
    let ceiling = match &raw.ceiling_height_m {
        Some(c) => {
            ctx.in_range(c, "ceiling_height_m", 1.0, 50.0, "m");
            *c.get_ref()
        }
        None => DEFAULT_CEILING_M,
    };

    let msu = validate_msu(ctx, &raw.msu);
    let cells = validate_cells(ctx, &raw.cells);
    let transmitters = validate_transmitters(ctx, &raw.transmitters, &cells, msu.channels);
    let walls = validate_walls(ctx, &raw.walls, ceiling);
    let columns = validate_columns(ctx, &raw.columns, ceiling);

    let mut site = Site {
        name: raw.name.into_inner(),
        speed_of_sound_m_s: speed,
        temperature_c: temperature,
        guard_time_s: guard_ms / 1000.0,
        burst_length_s: burst_ms / 1000.0,
        decoder_window_s: window_ms / 1000.0,
        ceiling_height_m: ceiling,
        msu,
        cells,
        transmitters,
        walls,
        columns,
        routes: Vec::new(),
        robots: Vec::new(),
    };
    check_transmitters_clear_of_obstacles(ctx, &raw.transmitters, &site);
    check_cells_have_transmitters(ctx, &raw.cells, &site);
    site.routes = validate_routes(ctx, &raw.routes, &site);
    site.robots = validate_robots(ctx, &raw.robots, &site);
    site
}

fn validate_msu(ctx: &mut Ctx, msu: &Spanned<RawMsu>) -> MsuGeometry {
    let m = msu.get_ref();
    let count = *m.receivers.get_ref();
    let count_ok = (1..=32).contains(&count);
    if !count_ok {
        ctx.issue(
            m.receivers.span(),
            "msu.receivers",
            format!("{count} receivers: expected 1 to 32"),
        );
    }
    let count = count.clamp(1, 32) as usize;
    let angles_rad = match &m.receiver_angles_deg {
        Some(a) => {
            ctx.finite_all(a.span(), "msu.receiver_angles_deg", a.get_ref());
            if count_ok && a.get_ref().len() != count {
                ctx.issue(
                    a.span(),
                    "msu.receiver_angles_deg",
                    format!(
                        "{} angles for {count} receivers: give one angle per receiver",
                        a.get_ref().len()
                    ),
                );
            }
            a.get_ref().iter().map(|d| d.to_radians()).collect()
        }
        None => (0..count)
            .map(|i| i as f64 * std::f64::consts::TAU / count as f64)
            .collect(),
    };
    ctx.in_range(&m.height_m, "msu.height_m", 0.0, 5.0, "m");
    let channels = match &m.channels {
        Some(c) => {
            let n = *c.get_ref();
            if !(1..=MAX_CHANNELS).contains(&n) {
                ctx.issue(
                    c.span(),
                    "msu.channels",
                    format!("{n} channels: expected 1 to {MAX_CHANNELS}"),
                );
            }
            n.clamp(1, MAX_CHANNELS) as u8
        }
        None => 1,
    };
    MsuGeometry {
        receiver_angles_rad: angles_rad,
        height_m: *m.height_m.get_ref(),
        channels,
    }
}

fn validate_cells(ctx: &mut Ctx, raw: &[RawCell]) -> Vec<Cell> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut cells = Vec::new();
    for (i, c) in raw.iter().enumerate() {
        let field = format!("cells[{i}]");
        ctx.id(&c.id, &format!("{field}.id"));
        if let Some(first) = seen.insert(c.id.get_ref().clone(), i) {
            ctx.issue(
                c.id.span(),
                format!("{field}.id"),
                format!(
                    "duplicate cell id {:?} (also cells[{first}])",
                    c.id.get_ref()
                ),
            );
        }
        let ok = ctx.polygon(&c.polygon, &format!("{field}.polygon"));
        cells.push(Cell {
            id: c.id.get_ref().clone(),
            polygon: if ok {
                counter_clockwise(c.polygon.get_ref().clone())
            } else {
                Vec::new()
            },
        });
    }
    if raw.is_empty() {
        ctx.issue(
            0..0,
            "cells",
            "the site has no cells: add at least one [[cells]]",
        );
    }
    cells
}

fn validate_transmitters(
    ctx: &mut Ctx,
    raw: &[RawTransmitter],
    cells: &[Cell],
    msu_channels: u8,
) -> Vec<Transmitter> {
    let mut seen: HashMap<i64, usize> = HashMap::new();
    let mut out = Vec::new();
    for (i, t) in raw.iter().enumerate() {
        let field = format!("transmitters[{i}]");
        let id = *t.id.get_ref();
        if !(0..=i64::from(u32::MAX)).contains(&id) {
            ctx.issue(
                t.id.span(),
                format!("{field}.id"),
                format!("transmitter id {id} must be between 0 and {}", u32::MAX),
            );
        }
        if let Some(first) = seen.insert(id, i) {
            ctx.issue(
                t.id.span(),
                format!("{field}.id"),
                format!("duplicate transmitter id {id} (also transmitters[{first}])"),
            );
        }
        let pos = *t.position.get_ref();
        let finite = ctx.finite_all(t.position.span(), &format!("{field}.position"), &pos);
        match cells.iter().find(|c| &c.id == t.cell.get_ref()) {
            None => ctx.issue(
                t.cell.span(),
                format!("{field}.cell"),
                format!("no cell with id {:?}", t.cell.get_ref()),
            ),
            Some(cell)
                if finite && !cell.polygon.is_empty() && !cell.contains([pos[0], pos[1]]) =>
            {
                ctx.issue(
                    t.position.span(),
                    format!("{field}.position"),
                    format!(
                        "transmitter {id} at ({}, {}) is outside its cell {:?}",
                        pos[0], pos[1], cell.id
                    ),
                )
            }
            Some(_) => {}
        }
        if finite && pos[2] <= 0.0 {
            ctx.issue(
                t.position.span(),
                format!("{field}.position"),
                format!(
                    "transmitter {id} height {} m must be above the floor",
                    pos[2]
                ),
            );
        }
        let channel = match &t.channel {
            Some(c) => {
                let ch = *c.get_ref();
                if !(0..i64::from(msu_channels)).contains(&ch) {
                    ctx.issue(
                        c.span(),
                        format!("{field}.channel"),
                        format!(
                            "channel {ch}: the MSU declares {msu_channels} channel(s) it can hear \
                             (msu.channels), so expected 0 to {}",
                            msu_channels - 1
                        ),
                    );
                }
                ch.clamp(0, MAX_CHANNELS - 1) as u8
            }
            None => 0,
        };
        out.push(Transmitter {
            id: id.clamp(0, i64::from(u32::MAX)) as u32,
            cell: t.cell.get_ref().clone(),
            position_m: pos,
            channel,
        });
    }
    out
}

fn validate_walls(ctx: &mut Ctx, raw: &[RawWall], ceiling: f64) -> Vec<Wall> {
    raw.iter()
        .enumerate()
        .map(|(i, w)| {
            let field = format!("walls[{i}]");
            let (a, b) = (*w.from.get_ref(), *w.to.get_ref());
            let finite = ctx.finite_all(w.from.span(), &format!("{field}.from"), &a)
                & ctx.finite_all(w.to.span(), &format!("{field}.to"), &b);
            if finite && a == b {
                ctx.issue(w.to.span(), format!("{field}.to"), "wall has zero length");
            }
            let height = match &w.height_m {
                Some(h) => {
                    ctx.in_range(h, &format!("{field}.height_m"), 0.01, 50.0, "m");
                    *h.get_ref()
                }
                None => ceiling,
            };
            Wall {
                from: a,
                to: b,
                height_m: height,
            }
        })
        .collect()
}

fn validate_columns(ctx: &mut Ctx, raw: &[RawColumn], ceiling: f64) -> Vec<Column> {
    raw.iter()
        .enumerate()
        .map(|(i, c)| {
            let field = format!("columns[{i}]");
            let ok = ctx.polygon(&c.polygon, &format!("{field}.polygon"));
            let height = match &c.height_m {
                Some(h) => {
                    ctx.in_range(h, &format!("{field}.height_m"), 0.01, 50.0, "m");
                    *h.get_ref()
                }
                None => ceiling,
            };
            Column {
                polygon: if ok {
                    counter_clockwise(c.polygon.get_ref().clone())
                } else {
                    Vec::new()
                },
                height_m: height,
            }
        })
        .collect()
}

fn check_transmitters_clear_of_obstacles(ctx: &mut Ctx, raw: &[RawTransmitter], site: &Site) {
    for (i, (t, r)) in site.transmitters.iter().zip(raw).enumerate() {
        let p = t.position_m;
        if !p.iter().all(|v| v.is_finite()) {
            continue;
        }
        let xy = [p[0], p[1]];
        let in_wall = site.walls.iter().position(|w| {
            p[2] <= w.height_m && geometry::distance_to_segment(xy, w.from, w.to) < WALL_CLEARANCE_M
        });
        if let Some(w) = in_wall {
            ctx.issue(
                r.position.span(),
                format!("transmitters[{i}].position"),
                format!(
                    "transmitter {} is inside walls[{w}] (closer than {WALL_CLEARANCE_M} m)",
                    t.id
                ),
            );
        }
        let in_column = site.columns.iter().position(|c| {
            p[2] <= c.height_m && geometry::contains(&c.polygon, xy, WALL_CLEARANCE_M)
        });
        if let Some(c) = in_column {
            ctx.issue(
                r.position.span(),
                format!("transmitters[{i}].position"),
                format!("transmitter {} is inside columns[{c}]", t.id),
            );
        }
    }
}

fn check_cells_have_transmitters(ctx: &mut Ctx, raw: &[RawCell], site: &Site) {
    for (cell, r) in site.cells.iter().zip(raw) {
        let n = site.transmitters_of(&cell.id).count();
        if n < MIN_TRANSMITTERS_PER_CELL {
            ctx.issue(
                r.id.span(),
                format!("cells[{}]", site.cells.iter().position(|c| c.id == cell.id).unwrap_or(0)),
                format!(
                    "cell {:?} has {n} transmitter{}: at least {MIN_TRANSMITTERS_PER_CELL} are needed for a fix",
                    cell.id,
                    if n == 1 { "" } else { "s" }
                ),
            );
        }
    }
}

fn validate_routes(ctx: &mut Ctx, raw: &[RawRoute], site: &Site) -> Vec<Route> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut routes = Vec::new();
    for (i, r) in raw.iter().enumerate() {
        let field = format!("routes[{i}]");
        ctx.id(&r.name, &format!("{field}.name"));
        if let Some(first) = seen.insert(r.name.get_ref().clone(), i) {
            ctx.issue(
                r.name.span(),
                format!("{field}.name"),
                format!(
                    "duplicate route name {:?} (also routes[{first}])",
                    r.name.get_ref()
                ),
            );
        }
        let points = r.points.get_ref();
        let pfield = format!("{field}.points");
        let flat: Vec<f64> = points.iter().flatten().copied().collect();
        let mut ok = ctx.finite_all(r.points.span(), &pfield, &flat);
        if points.len() < 2 {
            ctx.issue(
                r.points.span(),
                &pfield,
                format!("route needs at least 2 points, got {}", points.len()),
            );
            ok = false;
        }
        if ok {
            if let Some(k) = points.iter().position(|p| site.cell_at(*p).is_none()) {
                ctx.issue(
                    r.points.span(),
                    &pfield,
                    format!(
                        "point {k} ({}, {}) lies outside every cell",
                        points[k][0], points[k][1]
                    ),
                );
            }
            for (k, (a, b)) in geometry::polyline_segments(points, r.closed).enumerate() {
                if !site.drivable(a, b) {
                    ctx.issue(
                        r.points.span(),
                        &pfield,
                        format!(
                            "segment {k} from ({}, {}) to ({}, {}) runs through a wall or column",
                            a[0], a[1], b[0], b[1]
                        ),
                    );
                }
            }
        }
        let count = match &r.reference_points {
            Some(n) if !(1..=10_000).contains(n.get_ref()) => {
                ctx.issue(
                    n.span(),
                    format!("{field}.reference_points"),
                    format!("{} reference points: expected 1 to 10000", n.get_ref()),
                );
                1
            }
            Some(n) => *n.get_ref(),
            None => DEFAULT_REFERENCE_POINTS,
        };
        let speed = match &r.speed_m_s {
            Some(s) => {
                ctx.in_range(s, &format!("{field}.speed_m_s"), 0.01, 5.0, "m/s");
                *s.get_ref()
            }
            None => DEFAULT_ROUTE_SPEED_M_S,
        };
        let reference_points = if ok {
            reference_points_along(points, r.closed, count as usize)
        } else {
            Vec::new()
        };
        routes.push(Route {
            name: r.name.get_ref().clone(),
            points: points.clone(),
            closed: r.closed,
            reference_points,
            speed_m_s: speed,
        });
    }
    routes
}

/// `count` points evenly spaced by arc length, the first at the route's start;
/// on a closed route the last one stops short of the start (a tour's end).
fn reference_points_along(points: &[Point2], closed: bool, count: usize) -> Vec<Point2> {
    let length = geometry::polyline_length(points, closed);
    let spacing = if closed || count < 2 {
        length / count as f64
    } else {
        length / (count - 1) as f64
    };
    (0..count)
        .map(|k| geometry::point_at_arc_length(points, closed, k as f64 * spacing))
        .collect()
}

fn validate_robots(ctx: &mut Ctx, raw: &[RawRobot], site: &Site) -> Vec<RobotSpec> {
    let mut seen = HashSet::new();
    let mut robots = Vec::new();
    for (i, r) in raw.iter().enumerate() {
        let field = format!("robots[{i}]");
        ctx.id(&r.id, &format!("{field}.id"));
        if !seen.insert(r.id.get_ref().clone()) {
            ctx.issue(
                r.id.span(),
                format!("{field}.id"),
                format!("duplicate robot id {:?}", r.id.get_ref()),
            );
        }
        // A real site's robots drive no route: they give where they start.
        let route = match &r.route {
            Some(name) => {
                let route = site.route(name.get_ref());
                if route.is_none() {
                    ctx.issue(
                        name.span(),
                        format!("{field}.route"),
                        format!("no route named {:?}", name.get_ref()),
                    );
                }
                route
            }
            None => {
                if r.start.is_none() {
                    ctx.issue(
                        r.id.span(),
                        format!("{field}.start"),
                        "a robot without a route needs its start = [x_m, y_m, heading_deg] \
                         (where it is switched on)"
                            .to_string(),
                    );
                }
                None
            }
        };
        let start = match (&r.start, route) {
            (Some(s), _) => {
                let v = *s.get_ref();
                if ctx.finite_all(s.span(), &format!("{field}.start"), &v) {
                    if site.cell_at([v[0], v[1]]).is_none() {
                        ctx.issue(
                            s.span(),
                            format!("{field}.start"),
                            format!("start ({}, {}) lies outside every cell", v[0], v[1]),
                        );
                    }
                    // The world starts the robot on its route at the point
                    // nearest `start`; far from it, the pose given to the
                    // robot's filter would be wrong.
                    if let Some(route) = route.filter(|r| r.points.len() >= 2) {
                        let (q, _) = route.nearest_point([v[0], v[1]]);
                        let off_m = (q[0] - v[0]).hypot(q[1] - v[1]);
                        if off_m > MAX_START_OFF_ROUTE_M {
                            ctx.issue(
                                s.span(),
                                format!("{field}.start"),
                                format!(
                                    "start ({}, {}) is {off_m:.2} m from route {:?}: at most {MAX_START_OFF_ROUTE_M} m",
                                    v[0], v[1], route.name
                                ),
                            );
                        }
                    }
                }
                [v[0], v[1], v[2].to_radians()]
            }
            (None, Some(route)) if route.points.len() >= 2 => {
                let (a, b) = (route.points[0], route.points[1]);
                [a[0], a[1], (b[1] - a[1]).atan2(b[0] - a[0])]
            }
            _ => [0.0, 0.0, 0.0],
        };
        robots.push(RobotSpec {
            id: r.id.get_ref().clone(),
            route: r
                .route
                .as_ref()
                .map(|n| n.get_ref().clone())
                .unwrap_or_default(),
            start,
        });
    }
    robots
}
