//! A position from distances to beacons (trilateration): the point on the
//! receiver's height that best explains three or more ranges, by weighted
//! Gauss-Newton from the beacons' centroid.
//!
//! Ranging systems (a Marvelmind kit's raw distances, radio ranging) give
//! what TDOA gives only up to a common offset; three ranges fix a point on
//! a known height, so no emission time is needed.

use nalgebra::{Matrix2, Vector2, Vector3};

use crate::estimator::BeaconRangeSample;

/// Gauss-Newton iterations: it converges in a handful from the centroid
/// when the receiver is among or under the beacons.
const ITERATIONS: usize = 20;

/// Distinct beacons needed: three ranges fix a point on a known height.
pub const MIN_BEACONS: usize = 3;

/// Where the ranges put the receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeFix {
    /// Position on the floor, metres.
    pub x_m: f64,
    /// See `x_m`.
    pub y_m: f64,
    /// Covariance of `x, y` from the ranges' sigmas and the geometry, m^2.
    pub covariance_xy_m2: Matrix2<f64>,
    /// RMS of the ranges' residuals at the solution, metres.
    pub rms_residual_m: f64,
}

/// The position at height `height_m` that best explains `ranges`, or
/// `None` when fewer than [`MIN_BEACONS`] distinct beacons are ranged, a
/// value is not finite, or the geometry fixes no position (beacons in a
/// line in plan, which a mirror point explains as well; the receiver on a
/// beacon).
pub fn trilaterate(ranges: &[BeaconRangeSample], height_m: f64) -> Option<RangeFix> {
    let usable = height_m.is_finite()
        && ranges.iter().all(|r| {
            r.range_m.is_finite() && r.sigma_m > 0.0 && r.beacon_m.iter().all(|v| v.is_finite())
        });
    let mut distinct: Vec<[f64; 3]> = Vec::new();
    for r in ranges {
        if !distinct.contains(&r.beacon_m) {
            distinct.push(r.beacon_m);
        }
    }
    if !usable || distinct.len() < MIN_BEACONS || in_a_line(&distinct) {
        return None;
    }
    let n = ranges.len() as f64;
    let mut p = Vector2::new(
        ranges.iter().map(|r| r.beacon_m[0]).sum::<f64>() / n,
        ranges.iter().map(|r| r.beacon_m[1]).sum::<f64>() / n,
    );
    for _ in 0..ITERATIONS {
        let (jtj, jtr, _) = normal_equations(ranges, p, height_m)?;
        let step = jtj.try_inverse()? * jtr;
        p -= step;
        if !p.iter().all(|v| v.is_finite()) {
            return None;
        }
        if step.norm() < 1e-7 {
            break;
        }
    }
    let (jtj, _, sq) = normal_equations(ranges, p, height_m)?;
    let covariance_xy_m2 = jtj.try_inverse()?;
    covariance_xy_m2
        .iter()
        .all(|v| v.is_finite())
        .then_some(RangeFix {
            x_m: p.x,
            y_m: p.y,
            covariance_xy_m2,
            rms_residual_m: (sq / n).sqrt(),
        })
}

/// Beacons closer than this to one line in plan leave the receiver's side
/// of it ambiguous, metres: two mirror points explain the ranges alike.
const MIN_SPREAD_M: f64 = 0.1;

/// Whether the beacons lie within [`MIN_SPREAD_M`] of one line in plan
/// (the smaller principal spread of their `x, y`).
fn in_a_line(beacons: &[[f64; 3]]) -> bool {
    let n = beacons.len() as f64;
    let mean = Vector2::new(
        beacons.iter().map(|b| b[0]).sum::<f64>() / n,
        beacons.iter().map(|b| b[1]).sum::<f64>() / n,
    );
    let scatter = beacons.iter().fold(Matrix2::zeros(), |acc, b| {
        let d = Vector2::new(b[0], b[1]) - mean;
        acc + d * d.transpose() / n
    });
    let smallest = scatter.symmetric_eigenvalues().min();
    smallest.max(0.0).sqrt() < MIN_SPREAD_M
}

/// `J^T W J`, `J^T W r` and the sum of squared residuals at `p`.
fn normal_equations(
    ranges: &[BeaconRangeSample],
    p: Vector2<f64>,
    height_m: f64,
) -> Option<(Matrix2<f64>, Vector2<f64>, f64)> {
    let (mut jtj, mut jtr, mut sq) = (Matrix2::zeros(), Vector2::zeros(), 0.0);
    for r in ranges {
        let d = Vector3::new(p.x, p.y, height_m) - Vector3::from(r.beacon_m);
        let dist = d.norm();
        if dist < 1e-6 {
            return None;
        }
        let w = 1.0 / (r.sigma_m * r.sigma_m);
        let j = Vector2::new(d.x / dist, d.y / dist);
        let res = dist - r.range_m;
        jtj += w * j * j.transpose();
        jtr += w * j * res;
        sq += res * res;
    }
    Some((jtj, jtr, sq))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn range(beacon_m: [f64; 3], at: [f64; 3], error_m: f64) -> BeaconRangeSample {
        BeaconRangeSample {
            t_s: 0.0,
            beacon_m,
            range_m: (Vector3::from(at) - Vector3::from(beacon_m)).norm() + error_m,
            sigma_m: 0.02,
        }
    }

    const CEILING: [[f64; 3]; 4] = [
        [0.0, 0.0, 3.0],
        [6.0, 0.0, 3.0],
        [6.0, 6.0, 3.0],
        [0.0, 6.0, 3.0],
    ];

    #[test]
    fn three_ranges_fix_a_point_on_the_receivers_height() {
        let at = [1.5, 4.0, 0.3];
        let ranges: Vec<_> = CEILING[..3].iter().map(|b| range(*b, at, 0.0)).collect();
        let fix = trilaterate(&ranges, 0.3).expect("three beacons");
        assert!(
            (fix.x_m - 1.5).abs() < 1e-6 && (fix.y_m - 4.0).abs() < 1e-6,
            "{fix:?}"
        );
        assert!(fix.rms_residual_m < 1e-6);
        let sigma = fix.covariance_xy_m2.trace().sqrt();
        assert!(sigma > 0.02 && sigma < 0.2, "{sigma}");
    }

    #[test]
    fn a_wrong_range_shows_in_the_residual() {
        let at = [4.0, 2.0, 0.3];
        let mut ranges: Vec<_> = CEILING.iter().map(|b| range(*b, at, 0.0)).collect();
        ranges[2].range_m += 0.5;
        let fix = trilaterate(&ranges, 0.3).expect("four beacons");
        assert!(fix.rms_residual_m > 0.05, "{fix:?}");
    }

    #[test]
    fn two_beacons_or_one_beacon_thrice_fix_nothing() {
        let at = [1.0, 1.0, 0.3];
        let two: Vec<_> = CEILING[..2].iter().map(|b| range(*b, at, 0.0)).collect();
        assert_eq!(trilaterate(&two, 0.3), None);
        let same = vec![range(CEILING[0], at, 0.0); 3];
        assert_eq!(trilaterate(&same, 0.3), None);
    }

    #[test]
    fn beacons_in_a_line_or_bad_numbers_fix_nothing() {
        let at = [1.0, 1.0, 0.3];
        let line: Vec<_> = [[0.0, 0.0, 3.0], [0.0, 3.0, 3.0], [0.0, 6.0, 3.0]]
            .iter()
            .map(|b| range(*b, at, 0.0))
            .collect();
        // Beacons in a line cannot tell one side of it from the other.
        assert_eq!(trilaterate(&line, 0.3), None);
        let mut bad: Vec<_> = CEILING.iter().map(|b| range(*b, at, 0.0)).collect();
        bad[1].range_m = f64::NAN;
        assert_eq!(trilaterate(&bad, 0.3), None);
        assert_eq!(
            trilaterate(
                &CEILING
                    .iter()
                    .map(|b| range(*b, at, 0.0))
                    .collect::<Vec<_>>(),
                f64::INFINITY
            ),
            None
        );
    }
}
