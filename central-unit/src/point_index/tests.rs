use super::*;

/// A seeded stream of numbers in [lo, hi) (xorshift: the test needs no
/// more than spread).
struct Draws(u64);

impl Draws {
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The answers of a scan of every point, as the index must give them.
fn scan_within(points: &[[f64; 2]], c: [f64; 2], r: f64) -> Vec<usize> {
    (0..points.len())
        .filter(|&k| {
            let (dx, dy) = (points[k][0] - c[0], points[k][1] - c[1]);
            dx * dx + dy * dy <= r * r
        })
        .collect()
}

fn scan_nearest(points: &[[f64; 2]], at: [f64; 2]) -> Option<(usize, f64)> {
    points
        .iter()
        .enumerate()
        .map(|(k, p)| (k, (p[0] - at[0]).powi(2) + (p[1] - at[1]).powi(2)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, d)| (k, d.sqrt()))
}

/// A floor of two rooms with a gap between them, on the sample grid.
fn two_rooms() -> Vec<[f64; 2]> {
    let mut points = Vec::new();
    for i in 0..40 {
        for j in 0..20 {
            points.push([i as f64 * 0.25, j as f64 * 0.25]);
            points.push([20.0 + i as f64 * 0.25, 3.0 + j as f64 * 0.25]);
        }
    }
    points
}

#[test]
fn within_and_nearest_agree_with_a_scan_of_every_point() {
    let points = two_rooms();
    let index = PointIndex::new(&points);
    let mut rng = Draws(0x9e37_79b9_7f4a_7c15);
    for _ in 0..2_000 {
        // Inside, between and well outside the rooms.
        let at = [rng.range(-10.0, 40.0), rng.range(-10.0, 20.0)];
        let r = rng.range(0.0, 6.0);
        let mut found = index.within(at, r);
        found.sort_unstable();
        assert_eq!(found, scan_within(&points, at, r), "within {r} of {at:?}");
        let (k, d) = index.nearest(at).expect("points");
        let (k_scan, d_scan) = scan_nearest(&points, at).expect("points");
        assert_eq!((k, d), (k_scan, d_scan), "nearest to {at:?}");
    }
}

#[test]
fn a_tie_goes_to_the_lowest_index_as_a_scan_gives_it() {
    // Two points at the same distance in different buckets.
    let points = vec![[3.0, 0.0], [1.0, 0.0], [5.0, 0.0]];
    let index = PointIndex::new(&points);
    assert_eq!(index.nearest([2.0, 0.0]), Some((0, 1.0)));
    assert_eq!(index.nearest([4.0, 0.0]), Some((0, 1.0)));
}

#[test]
fn what_is_not_a_number_finds_nothing() {
    let index = PointIndex::new(&[[0.0, 0.0], [f64::NAN, 1.0], [1.0, 1.0]]);
    assert_eq!(index.nearest([f64::NAN, 0.0]), None);
    assert!(index.within([0.0, f64::INFINITY], 1.0).is_empty());
    assert!(index.within([0.0, 0.0], f64::NAN).is_empty());
    // The point that is not a number is never an answer.
    let mut all = index.within([0.0, 0.0], f64::INFINITY);
    all.sort_unstable();
    assert_eq!(all, vec![0, 2]);
    assert_eq!(index.nearest([0.0, 5.0]), Some((2, 17f64.sqrt())));
}

#[test]
fn an_empty_floor_has_no_points() {
    let index = PointIndex::new(&[]);
    assert_eq!(index.nearest([0.0, 0.0]), None);
    assert!(index.within([0.0, 0.0], 100.0).is_empty());
}
