//! A bucket grid over the floor's sample points: the points within a
//! disc and the point nearest to a place, in time proportional to the
//! points near it rather than to the whole floor.
//!
//! The firing plan asks both for every robot every cycle; scanning every
//! sample point of the site for each (tens of thousands on `warehouse`)
//! made the plan's time the floor times the fleet.

/// Side of a bucket, metres: four sample spacings (0.25 m), so that a
/// robot's region (about a metre across) spans a few buckets of about
/// sixteen points each.
pub const BUCKET_M: f64 = 1.0;

/// The sample points of a floor, bucketed on a square grid.
#[derive(Debug, Clone, PartialEq)]
pub struct PointIndex {
    points: Vec<[f64; 2]>,
    /// Lower corner of bucket (0, 0), metres.
    origin: [f64; 2],
    /// Buckets along x and y (at least one each when there are points).
    nx: usize,
    ny: usize,
    /// Bucket `b`'s points are `order[start[b]..start[b + 1]]`, ascending.
    start: Vec<usize>,
    order: Vec<usize>,
}

impl PointIndex {
    /// The index of `points` (their indices are those of the slice). Points
    /// that are not numbers are left out of every answer.
    pub fn new(points: &[[f64; 2]]) -> Self {
        let finite = |p: &[f64; 2]| p[0].is_finite() && p[1].is_finite();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points.iter().filter(|p| finite(p)) {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let span = |k: usize| {
            if hi[k] >= lo[k] {
                // A site is at most kilometres across; the cap keeps a
                // corrupt one from asking for an absurd allocation.
                (((hi[k] - lo[k]) / BUCKET_M).floor() as usize + 1).min(1 << 12)
            } else {
                0
            }
        };
        let (nx, ny) = (span(0), span(1));
        let mut index = Self {
            points: points.to_vec(),
            origin: if nx > 0 { lo } else { [0.0; 2] },
            nx,
            ny,
            start: vec![0; nx * ny + 1],
            order: Vec::with_capacity(points.len()),
        };
        let bucket_of: Vec<Option<usize>> = points
            .iter()
            .map(|p| finite(p).then(|| index.bucket(index.cell_of(*p))))
            .collect();
        for b in bucket_of.iter().flatten() {
            index.start[b + 1] += 1;
        }
        for b in 0..nx * ny {
            index.start[b + 1] += index.start[b];
        }
        let mut next = index.start.clone();
        index.order = vec![0; index.start[nx * ny]];
        for (k, b) in bucket_of.iter().enumerate() {
            if let Some(b) = *b {
                index.order[next[b]] = k;
                next[b] += 1;
            }
        }
        index
    }

    /// How many points the index holds (indices `0..len`).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether it holds no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The bucket coordinates holding `p`, clamped to the grid.
    fn cell_of(&self, p: [f64; 2]) -> (usize, usize) {
        let along = |v: f64, o: f64, n: usize| {
            let c = ((v - o) / BUCKET_M).floor();
            if c.is_nan() || c < 0.0 {
                0
            } else {
                (c as usize).min(n.saturating_sub(1))
            }
        };
        (
            along(p[0], self.origin[0], self.nx),
            along(p[1], self.origin[1], self.ny),
        )
    }

    fn bucket(&self, (i, j): (usize, usize)) -> usize {
        j * self.nx + i
    }

    fn bucket_points(&self, cell: (usize, usize)) -> &[usize] {
        let b = self.bucket(cell);
        &self.order[self.start[b]..self.start[b + 1]]
    }

    /// The points within `radius_m` of `centre` (indices, by bucket then
    /// ascending). Nothing for a centre or radius that is not a number.
    pub fn within(&self, centre: [f64; 2], radius_m: f64) -> Vec<usize> {
        let mut found = Vec::new();
        if self.nx == 0 || !(centre[0].is_finite() && centre[1].is_finite()) || radius_m.is_nan() {
            return found;
        }
        let r = radius_m.max(0.0);
        let (i0, j0) = self.cell_of([centre[0] - r, centre[1] - r]);
        let (i1, j1) = self.cell_of([centre[0] + r, centre[1] + r]);
        // Squared distances: `hypot`'s care for overflow is needless at a
        // site's scale and was most of a plan's time.
        let r_sq = r * r;
        for j in j0..=j1 {
            for i in i0..=i1 {
                found.extend(self.bucket_points((i, j)).iter().copied().filter(|&k| {
                    let p = self.points[k];
                    let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
                    dx * dx + dy * dy <= r_sq
                }));
            }
        }
        found
    }

    /// The point nearest to `at` and its distance, metres (`None` without
    /// points or for a place that is not a number; the lowest index on a
    /// tie).
    ///
    /// Searched in square rings of buckets around `at`'s (clamped onto the
    /// grid): a point in ring `r + 1` or beyond is at least `r` buckets from
    /// the clamped place, and no nearer to `at` itself (a projection onto a
    /// box brings no two points further apart), so the search stops once
    /// the best point found is that close.
    pub fn nearest(&self, at: [f64; 2]) -> Option<(usize, f64)> {
        if self.nx == 0 || !(at[0].is_finite() && at[1].is_finite()) {
            return None;
        }
        let (ci, cj) = self.cell_of(at);
        let mut best: Option<(usize, f64)> = None;
        let rings = self.nx.max(self.ny);
        for r in 0..=rings {
            for (i, j) in ring((ci, cj), r, (self.nx, self.ny)) {
                for &k in self.bucket_points((i, j)) {
                    let p = self.points[k];
                    let (dx, dy) = (p[0] - at[0], p[1] - at[1]);
                    let d_sq = dx * dx + dy * dy;
                    if best.is_none_or(|(bk, bd)| d_sq < bd || (d_sq == bd && k < bk)) {
                        best = Some((k, d_sq));
                    }
                }
            }
            let bound = r as f64 * BUCKET_M;
            if best.is_some_and(|(_, d_sq)| d_sq < bound * bound) {
                break;
            }
        }
        best.map(|(k, d_sq)| (k, d_sq.sqrt()))
    }
}

/// The buckets at Chebyshev distance exactly `r` from `centre` on an
/// `nx` by `ny` grid.
fn ring(
    (ci, cj): (usize, usize),
    r: usize,
    (nx, ny): (usize, usize),
) -> impl Iterator<Item = (usize, usize)> {
    let (ci, cj, r) = (ci as i64, cj as i64, r as i64);
    let (nx, ny) = (nx as i64, ny as i64);
    (cj - r..=cj + r)
        .filter(move |&j| (0..ny).contains(&j))
        .flat_map(move |j| {
            let edge = (j - cj).abs() == r;
            let step = if edge || r == 0 { 1 } else { 2 * r };
            (ci - r..=ci + r)
                .step_by(step as usize)
                .map(move |i| (i, j))
        })
        .filter(move |&(i, _)| (0..nx).contains(&i))
        .map(|(i, j)| (i as usize, j as usize))
}

#[cfg(test)]
mod tests;
