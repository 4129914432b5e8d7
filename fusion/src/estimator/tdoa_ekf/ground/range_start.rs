//! A start from ranges to beacons, for a robot that ranges instead of
//! timing differences and has no start pose: the position that best
//! explains the ranges to three or more beacons heard together
//! ([`crate::ranging::trilaterate`]).
//!
//! Starting at the centroid with a wide covariance and fusing the ranges
//! one by one does not do: the first updates linearise metres from the
//! truth, the covariance collapses before the position gets there, and
//! later ranges are gated out of a confident, wrong filter.

use crate::estimator::BeaconRangeSample;
use crate::ranging;

/// Ranges this much older than the newest are dropped, seconds: a
/// Marvelmind kit ranges up to four beacons per cycle at 1-16 Hz, so half
/// a second holds a cycle at the slowest useful rate, and a robot at
/// walking speed moves under a metre meanwhile.
const WINDOW_S: f64 = 0.5;

/// A start is refused when the ranges disagree with its position by more
/// than this RMS, beyond three of their sigmas, metres: what a robot at
/// 1 m/s moves within [`WINDOW_S`].
const MOTION_ALLOWANCE_M: f64 = 0.5;

/// The ranges heard before the start.
#[derive(Debug, Clone, Default)]
pub(super) struct RangeStart {
    ranges: Vec<BeaconRangeSample>,
}

/// Where to start: position and its one-sigma, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct StartFix {
    pub x_m: f64,
    pub y_m: f64,
    pub sigma_m: f64,
}

impl RangeStart {
    /// Adds a range (the newest per beacon is kept) and tries a start from
    /// the receiver height `height_m`.
    pub(super) fn add(&mut self, r: &BeaconRangeSample, height_m: f64) -> Option<StartFix> {
        let usable = r.t_s.is_finite()
            && r.range_m.is_finite()
            && r.sigma_m > 0.0
            && r.beacon_m.iter().all(|v| v.is_finite());
        if !usable {
            return None;
        }
        self.ranges.retain(|o| o.beacon_m != r.beacon_m);
        self.ranges.push(*r);
        let newest = self.ranges.iter().map(|o| o.t_s).fold(f64::MIN, f64::max);
        self.ranges.retain(|o| o.t_s >= newest - WINDOW_S);
        if self.ranges.len() < ranging::MIN_BEACONS {
            return None;
        }
        let fix = solve(&self.ranges, height_m)?;
        self.ranges.clear();
        Some(fix)
    }
}

fn solve(ranges: &[BeaconRangeSample], height_m: f64) -> Option<StartFix> {
    let fix = ranging::trilaterate(ranges, height_m)?;
    let worst_sigma = ranges.iter().map(|r| r.sigma_m).fold(0.0, f64::max);
    if fix.rms_residual_m > 3.0 * worst_sigma + MOTION_ALLOWANCE_M {
        return None;
    }
    let cov = fix.covariance_xy_m2;
    let sigma_m = (cov[(0, 0)].max(cov[(1, 1)]) + MOTION_ALLOWANCE_M.powi(2)).sqrt();
    sigma_m.is_finite().then_some(StartFix {
        x_m: fix.x_m,
        y_m: fix.y_m,
        sigma_m,
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;

    fn range(t_s: f64, beacon_m: [f64; 3], at: [f64; 3]) -> BeaconRangeSample {
        BeaconRangeSample {
            t_s,
            beacon_m,
            range_m: (Vector3::from(at) - Vector3::from(beacon_m)).norm(),
            sigma_m: 0.02,
        }
    }

    #[test]
    fn three_beacons_heard_together_give_the_position() {
        let at = [1.5, 4.0, 0.3];
        let mut s = RangeStart::default();
        assert_eq!(s.add(&range(0.0, [0.0, 0.0, 3.0], at), 0.3), None);
        assert_eq!(s.add(&range(0.1, [6.0, 0.0, 3.0], at), 0.3), None);
        let fix = s
            .add(&range(0.2, [6.0, 6.0, 3.0], at), 0.3)
            .expect("three beacons");
        assert!(
            (fix.x_m - 1.5).abs() < 1e-6 && (fix.y_m - 4.0).abs() < 1e-6,
            "{fix:?}"
        );
        assert!(fix.sigma_m >= MOTION_ALLOWANCE_M);
    }

    #[test]
    fn ranges_older_than_the_window_do_not_count() {
        let at = [1.5, 4.0, 0.3];
        let mut s = RangeStart::default();
        s.add(&range(0.0, [0.0, 0.0, 3.0], at), 0.3);
        s.add(&range(1.0, [6.0, 0.0, 3.0], at), 0.3);
        assert_eq!(s.add(&range(1.1, [6.0, 6.0, 3.0], at), 0.3), None);
    }

    #[test]
    fn ranges_that_no_position_explains_start_nothing() {
        let mut s = RangeStart::default();
        let r = |t, b: [f64; 3], range_m| BeaconRangeSample {
            t_s: t,
            beacon_m: b,
            range_m,
            sigma_m: 0.02,
        };
        s.add(&r(0.0, [0.0, 0.0, 3.0], 1.0), 0.3);
        s.add(&r(0.1, [6.0, 0.0, 3.0], 1.0), 0.3);
        assert_eq!(s.add(&r(0.2, [6.0, 6.0, 3.0], 1.0), 0.3), None);
    }
}
