//! Plane geometry of the floor plan: polygons, segments, line of sight.

/// A point on the floor, metres.
pub type Point2 = [f64; 2];

/// Signed area of a polygon (positive when counter-clockwise), m^2.
pub fn signed_area(polygon: &[Point2]) -> f64 {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let a = polygon[i];
            let b = polygon[(i + 1) % n];
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// Whether `p` lies inside `polygon` or on its boundary (within `tol_m`).
pub fn contains(polygon: &[Point2], p: Point2, tol_m: f64) -> bool {
    let n = polygon.len();
    if n < 3 {
        return false;
    }
    for i in 0..n {
        if distance_to_segment(p, polygon[i], polygon[(i + 1) % n]) <= tol_m {
            return true;
        }
    }
    // Even-odd ray casting towards +x.
    let mut inside = false;
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x_cross = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x_cross {
                inside = !inside;
            }
        }
    }
    inside
}

/// The point of the segment `a`-`b` nearest to `p`.
pub fn closest_on_segment(p: Point2, a: Point2, b: Point2) -> Point2 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [a[0] + t * ab[0], a[1] + t * ab[1]]
}

/// Distance from `p` to the segment `a`-`b`, metres.
pub fn distance_to_segment(p: Point2, a: Point2, b: Point2) -> f64 {
    let q = closest_on_segment(p, a, b);
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
}

/// Where segment `p`-`q` crosses segment `a`-`b`: the parameter `t` in `[0, 1]`
/// along `p`-`q`, or `None` if they do not cross (parallel segments never do).
pub fn segment_crossing(p: Point2, q: Point2, a: Point2, b: Point2) -> Option<f64> {
    let r = [q[0] - p[0], q[1] - p[1]];
    let s = [b[0] - a[0], b[1] - a[1]];
    let denom = r[0] * s[1] - r[1] * s[0];
    if denom.abs() < 1e-12 {
        return None;
    }
    let ap = [a[0] - p[0], a[1] - p[1]];
    let t = (ap[0] * s[1] - ap[1] * s[0]) / denom;
    let u = (ap[0] * r[1] - ap[1] * r[0]) / denom;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
}

/// Whether the polygon's edges cross each other (other than neighbours at their shared vertex).
pub fn self_intersects(polygon: &[Point2]) -> bool {
    let n = polygon.len();
    for i in 0..n {
        for j in (i + 1)..n {
            let neighbours = j == i + 1 || (i == 0 && j == n - 1);
            if neighbours {
                continue;
            }
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            let (c, d) = (polygon[j], polygon[(j + 1) % n]);
            if segment_crossing(a, b, c, d).is_some() {
                return true;
            }
        }
    }
    false
}

/// Total length of a polyline (closed: with the segment back to the start), metres.
pub fn polyline_length(points: &[Point2], closed: bool) -> f64 {
    polyline_segments(points, closed)
        .map(|(a, b)| ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt())
        .sum()
}

/// The segments of a polyline, closed or not.
pub fn polyline_segments(
    points: &[Point2],
    closed: bool,
) -> impl Iterator<Item = (Point2, Point2)> + '_ {
    let n = points.len();
    let count = if closed && n > 2 {
        n
    } else {
        n.saturating_sub(1)
    };
    (0..count).map(move |i| (points[i], points[(i + 1) % n]))
}

/// The point at arc length `s_m` along the polyline (clamped to its ends).
pub fn point_at_arc_length(points: &[Point2], closed: bool, s_m: f64) -> Point2 {
    let mut left = s_m.max(0.0);
    let mut last = points.first().copied().unwrap_or([0.0, 0.0]);
    for (a, b) in polyline_segments(points, closed) {
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        if left <= len && len > 0.0 {
            let t = left / len;
            return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        }
        left -= len;
        last = b;
    }
    last
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Point2; 4] = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];

    #[test]
    fn square_area_and_containment() {
        assert!((signed_area(&SQUARE) - 4.0).abs() < 1e-12);
        assert!(contains(&SQUARE, [1.0, 1.0], 0.0));
        assert!(contains(&SQUARE, [2.0, 1.0], 1e-9));
        assert!(!contains(&SQUARE, [2.5, 1.0], 1e-9));
    }

    #[test]
    fn crossing_segments_are_found_and_parallel_ones_are_not() {
        let t = segment_crossing([0.0, 0.0], [2.0, 2.0], [0.0, 2.0], [2.0, 0.0]).unwrap();
        assert!((t - 0.5).abs() < 1e-12);
        assert!(segment_crossing([0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]).is_none());
    }

    #[test]
    fn bow_tie_polygon_self_intersects() {
        assert!(self_intersects(&[
            [0.0, 0.0],
            [2.0, 2.0],
            [2.0, 0.0],
            [0.0, 2.0]
        ]));
        assert!(!self_intersects(&SQUARE));
    }

    #[test]
    fn arc_length_walks_a_closed_polyline() {
        assert!((polyline_length(&SQUARE, true) - 8.0).abs() < 1e-12);
        assert_eq!(point_at_arc_length(&SQUARE, true, 3.0), [2.0, 1.0]);
        assert_eq!(point_at_arc_length(&SQUARE, true, 7.0), [0.0, 1.0]);
    }
}
