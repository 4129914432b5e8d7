//! The site and the fleet as Foxglove 3D scenes (`foxglove.SceneUpdate`),
//! in the `map` frame: pure functions of the site model and the web map's
//! [`Snapshot`], so that what the live server sends is tested without a
//! socket.
//!
//! Walls and columns (racks, pillars) are extruded to their height, cells
//! are outlines on the floor coloured by state, transmitters are spheres
//! on the ceiling that light up while their burst is the latest of their
//! cell's, and every robot is an arrow with its 2-sigma ellipse, its raw
//! fix, a label with its state and, in a simulation, its true pose.

use foxglove::messages::{
    ArrowPrimitive, Color, CubePrimitive, LinePrimitive, Point3, Pose, Quaternion, SceneEntity,
    SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp, TriangleListPrimitive, Vector3,
    line_primitive,
};
use ickon_proto::site::Site;

use crate::http::view::{CellSnapshot, Ellipse, PoseView, RobotSnapshot, Snapshot};

/// The fixed frame of everything: the site's own coordinates, metres.
pub const MAP_FRAME: &str = "map";

/// Points on a drawn ellipse: smooth at any zoom, small on the wire.
const ELLIPSE_POINTS: usize = 36;
/// Height at which floor outlines and robots are drawn, metres: just above
/// the grid so that they are not hidden in it.
const FLOOR_Z_M: f64 = 0.02;
/// Size of a transmitter's sphere, metres (the real ones are ~5 cm; this
/// is drawn to be seen from across a warehouse).
const TX_SIZE_M: f64 = 0.25;
/// Length of a robot's arrow, metres (a typical AMR's footprint).
const ROBOT_ARROW_M: f64 = 0.6;

/// The colour of a cell outline in `state` (`up`, `idle`, `down`).
pub fn cell_color(state: &str) -> Color {
    match state {
        "up" => rgba(0.18, 0.62, 0.28, 1.0),
        "idle" => rgba(0.55, 0.55, 0.55, 1.0),
        _ => rgba(0.86, 0.15, 0.15, 1.0),
    }
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

fn point(x: f64, y: f64, z: f64) -> Point3 {
    Point3 { x, y, z }
}

/// A pose at (x, y, z) turned by `yaw_rad` about the vertical.
pub fn yaw_pose(x: f64, y: f64, z: f64, yaw_rad: f64) -> Pose {
    Pose {
        position: Some(Vector3 { x, y, z }),
        orientation: Some(yaw_quaternion(yaw_rad)),
    }
}

/// The rotation by `yaw_rad` about +z.
pub fn yaw_quaternion(yaw_rad: f64) -> Quaternion {
    let half = 0.5 * yaw_rad;
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: half.sin(),
        w: half.cos(),
    }
}

fn entity(id: String, stamp: Timestamp) -> SceneEntity {
    SceneEntity {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.to_string(),
        id,
        // Zero lifetime: kept until replaced by an entity of the same id.
        ..Default::default()
    }
}

fn line(kind: line_primitive::Type, points: Vec<Point3>, color: Color, px: f64) -> LinePrimitive {
    LinePrimitive {
        r#type: kind as i32,
        pose: Some(yaw_pose(0.0, 0.0, 0.0, 0.0)),
        thickness: px,
        scale_invariant: true,
        points,
        color: Some(color),
        ..Default::default()
    }
}

/// A prism over the polygon `base` from the floor to `height_m`: its sides
/// and its top (a fan from the first vertex, exact for the convex racks and
/// pillars sites are drawn with).
fn prism(base: &[[f64; 2]], height_m: f64, color: Color) -> TriangleListPrimitive {
    let mut points = Vec::with_capacity(base.len() * 6 + base.len().saturating_sub(2) * 3);
    for (k, a) in base.iter().enumerate() {
        let b = base[(k + 1) % base.len()];
        let (a0, a1) = (point(a[0], a[1], 0.0), point(a[0], a[1], height_m));
        let (b0, b1) = (point(b[0], b[1], 0.0), point(b[0], b[1], height_m));
        points.extend([a0, b0, b1, a0, b1, a1]);
    }
    for k in 1..base.len().saturating_sub(1) {
        let [a, b, c] = [base[0], base[k], base[k + 1]];
        points.extend([
            point(a[0], a[1], height_m),
            point(b[0], b[1], height_m),
            point(c[0], c[1], height_m),
        ]);
    }
    TriangleListPrimitive {
        pose: Some(yaw_pose(0.0, 0.0, 0.0, 0.0)),
        points,
        color: Some(color),
        ..Default::default()
    }
}

/// The site's fixed parts: walls, columns (racks and pillars) and, when
/// `with_routes` (a simulation: the routes are what its robots drive),
/// the routes. Sent again now and then for clients that join later.
pub fn site_scene(site: &Site, with_routes: bool, stamp: Timestamp) -> SceneUpdate {
    let mut walls = entity("walls".into(), stamp);
    for w in &site.walls {
        let (dx, dy) = (w.to[0] - w.from[0], w.to[1] - w.from[1]);
        let length = dx.hypot(dy);
        if !(length.is_finite() && length > 0.0) {
            continue;
        }
        let height = if w.height_m > 0.0 {
            w.height_m
        } else {
            site.ceiling_height_m
        };
        walls.cubes.push(CubePrimitive {
            pose: Some(yaw_pose(
                0.5 * (w.from[0] + w.to[0]),
                0.5 * (w.from[1] + w.to[1]),
                0.5 * height,
                dy.atan2(dx),
            )),
            size: Some(Vector3 {
                x: length,
                y: 0.1,
                z: height,
            }),
            color: Some(rgba(0.6, 0.6, 0.65, 0.35)),
        });
    }
    let mut columns = entity("columns".into(), stamp);
    for c in &site.columns {
        let height = if c.height_m > 0.0 {
            c.height_m
        } else {
            site.ceiling_height_m
        };
        columns
            .triangles
            .push(prism(&c.polygon, height, rgba(0.45, 0.42, 0.38, 0.8)));
    }
    let mut entities = vec![walls, columns];
    if with_routes {
        let mut routes = entity("routes".into(), stamp);
        for r in &site.routes {
            let points = r
                .points
                .iter()
                .map(|p| point(p[0], p[1], FLOOR_Z_M))
                .collect();
            let kind = if r.closed {
                line_primitive::Type::LineLoop
            } else {
                line_primitive::Type::LineStrip
            };
            routes
                .lines
                .push(line(kind, points, rgba(0.3, 0.45, 0.9, 0.6), 1.5));
        }
        entities.push(routes);
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

/// Whether the latest burst of `cell` falls in the current cycle (its age
/// less than one cycle period), i.e. its transmitter is firing now.
pub fn fired_this_cycle(cell: &CellSnapshot, cycle_period_ms: f64) -> bool {
    cell.last_burst_ms.is_some_and(|ms| ms < cycle_period_ms)
}

/// The period of one cycle, ms, from the rate in force (a second when the
/// rate is not a positive number).
pub fn cycle_period_ms(update_rate_hz: f64) -> f64 {
    if update_rate_hz.is_finite() && update_rate_hz > 0.0 {
        1e3 / update_rate_hz
    } else {
        1e3
    }
}

/// The state a cell is drawn in, as the central unit judges it: `up` (due
/// in the last cycle), `idle` (alive, not asked to fire) or `down`.
pub fn cell_state(cell: &CellSnapshot) -> &'static str {
    cell.health.state
}

/// Every cell's outline coloured by state, with its transmitters (lit
/// while firing), one entity per cell (`cell/<id>`, carrying `state` in
/// its metadata).
pub fn cells_scene(site: &Site, snapshot: &Snapshot, stamp: Timestamp) -> SceneUpdate {
    let period = cycle_period_ms(snapshot.update_rate_hz);
    let entities = snapshot
        .cells
        .iter()
        .filter_map(|c| {
            let shape = site.cell(&c.health.id)?;
            let state = cell_state(c);
            let firing = fired_this_cycle(c, period);
            let mut e = entity(format!("cell/{}", c.health.id), stamp);
            e.metadata.push(foxglove::messages::KeyValuePair {
                key: "state".into(),
                value: state.into(),
            });
            let outline = shape
                .polygon
                .iter()
                .map(|p| point(p[0], p[1], FLOOR_Z_M))
                .collect();
            e.lines.push(line(
                line_primitive::Type::LineLoop,
                outline,
                cell_color(state),
                3.0,
            ));
            let (cx, cy) = centroid(&shape.polygon);
            e.texts
                .push(text(cx, cy, 0.3, &c.health.id, cell_color(state)));
            for t in site.transmitters.iter().filter(|t| t.cell == c.health.id) {
                let lit = firing && c.last_tx == Some(t.id);
                let color = if lit {
                    rgba(1.0, 0.85, 0.1, 1.0)
                } else {
                    rgba(0.35, 0.35, 0.4, 0.9)
                };
                let size = if lit { 2.0 * TX_SIZE_M } else { TX_SIZE_M };
                e.spheres.push(SpherePrimitive {
                    pose: Some(yaw_pose(
                        t.position_m[0],
                        t.position_m[1],
                        t.position_m[2],
                        0.0,
                    )),
                    size: Some(Vector3 {
                        x: size,
                        y: size,
                        z: size,
                    }),
                    color: Some(color),
                });
            }
            Some(e)
        })
        .collect();
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

fn centroid(polygon: &[[f64; 2]]) -> (f64, f64) {
    let n = polygon.len().max(1) as f64;
    let (sx, sy) = polygon
        .iter()
        .fold((0.0, 0.0), |(sx, sy), p| (sx + p[0], sy + p[1]));
    (sx / n, sy / n)
}

/// A label at (x, y, z) facing the viewer.
pub(super) fn text(x: f64, y: f64, z: f64, label: &str, color: Color) -> TextPrimitive {
    TextPrimitive {
        pose: Some(yaw_pose(x, y, z, 0.0)),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(color),
        text: label.to_string(),
    }
}

/// The state a robot is shown in: `down` (its liveliness token is gone),
/// `stale` (live, but its poses stopped or an input stalled),
/// `localising` (no fix has confirmed its pose yet), `dead_reckoning` (no
/// fix absorbed for a while), `tracking`, or `unknown` before any pose.
pub fn robot_state(r: &RobotSnapshot) -> &'static str {
    match (r.health.state, r.pose_status) {
        ("down", _) => "down",
        ("stale", _) => "stale",
        (_, Some("localising")) => "localising",
        (_, Some("no_fixes")) => "dead_reckoning",
        (_, Some("no_odometry") | Some("tracking")) => "tracking",
        _ => "unknown",
    }
}

fn robot_color(state: &str) -> Color {
    match state {
        "tracking" => rgba(0.1, 0.45, 0.85, 1.0),
        "localising" | "dead_reckoning" => rgba(0.95, 0.6, 0.1, 1.0),
        _ => rgba(0.86, 0.15, 0.15, 1.0),
    }
}

fn ellipse_line(x: f64, y: f64, e: &Ellipse, color: Color) -> LinePrimitive {
    let points = (0..ELLIPSE_POINTS)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / ELLIPSE_POINTS as f64;
            let (u, v) = (e.a_m * t.cos(), e.b_m * t.sin());
            let (s, c) = e.angle_rad.sin_cos();
            point(x + c * u - s * v, y + s * u + c * v, FLOOR_Z_M)
        })
        .collect();
    line(line_primitive::Type::LineLoop, points, color, 2.0)
}

fn arrow(p: &PoseView, color: Color) -> ArrowPrimitive {
    ArrowPrimitive {
        pose: Some(yaw_pose(p.x_m, p.y_m, FLOOR_Z_M, p.theta_rad)),
        shaft_length: 0.7 * ROBOT_ARROW_M,
        shaft_diameter: 0.08,
        head_length: 0.3 * ROBOT_ARROW_M,
        head_diameter: 0.2,
        color: Some(color),
    }
}

/// Every robot as one entity (`robot/<id>`, with `state` in its
/// metadata): the fused pose as an arrow with its 2-sigma ellipse and a
/// label, the raw fix as a dot with its ellipse, and the truth as a grey
/// arrow when there is one. A robot with nothing to draw yet is left out.
pub fn robots_scene(snapshot: &Snapshot, stamp: Timestamp) -> SceneUpdate {
    let entities = snapshot
        .robots
        .iter()
        .filter(|r| r.fused.is_some() || r.fix.is_some() || r.truth.is_some())
        .map(|r| {
            let state = robot_state(r);
            let color = robot_color(state);
            let mut e = entity(format!("robot/{}", r.health.id), stamp);
            e.metadata.push(foxglove::messages::KeyValuePair {
                key: "state".into(),
                value: state.into(),
            });
            if let Some(p) = &r.fused {
                e.arrows.push(arrow(p, color));
                if let Some(el) = &r.fused_ellipse {
                    e.lines.push(ellipse_line(p.x_m, p.y_m, el, color));
                }
                let label = format!("{} {}", r.health.id, state);
                e.texts.push(text(p.x_m, p.y_m, 0.6, &label, color));
            }
            if let Some(f) = &r.fix {
                let fix_color = rgba(0.1, 0.7, 0.3, 0.9);
                e.spheres.push(SpherePrimitive {
                    pose: Some(yaw_pose(f.x_m, f.y_m, FLOOR_Z_M, 0.0)),
                    size: Some(Vector3 {
                        x: 0.08,
                        y: 0.08,
                        z: 0.08,
                    }),
                    color: Some(fix_color),
                });
                if let Some(el) = &f.ellipse {
                    e.lines.push(ellipse_line(f.x_m, f.y_m, el, fix_color));
                }
            }
            if let Some(t) = r.truth_at_pose.as_ref().or(r.truth.as_ref()) {
                e.arrows.push(arrow(t, rgba(0.5, 0.5, 0.5, 0.6)));
            }
            e
        })
        .collect();
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
