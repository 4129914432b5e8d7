//! The watch on synthetic flights that break plain filters: a geometry
//! with a mirror solution, bursts of late arrivals, an anchor that goes
//! silent, clock jumps. Every test asserts a bound on the error of every
//! published estimate.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::estimator::RangeDifferenceSample;
use crate::estimator::flight::{CvFilter, CvParams};

/// Eight anchors on the corners of a 6 x 6 x 3 m room.
fn corners() -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    for &z in &[0.2, 2.8] {
        for &(x, y) in &[(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (0.0, 6.0)] {
            v.push([x, y, z]);
        }
    }
    v
}

/// A circle of 1.5 m radius at 1.2 m height, 0.5 rad/s.
fn circle(t: f64) -> Vector3<f64> {
    Vector3::new(
        3.0 + 1.5 * (0.5 * t).cos(),
        3.0 + 1.5 * (0.5 * t).sin(),
        1.2,
    )
}

/// What a flight does to a measurement of pair `(a, b)` at true time `t`:
/// `None` drops it, else the added error in metres.
type Corrupt<'a> = &'a mut dyn FnMut(f64, usize, usize) -> Option<f64>;

/// The outcome of a flight.
struct Flown {
    /// Largest error of a published estimate, metres.
    worst_m: f64,
    /// Published estimates.
    published: usize,
    /// Measurements fed.
    fed: usize,
    counts: GuardCounts,
}

/// Round-robin pairs (k, k+1) at 200 Hz for `seconds` along `path`, 2 cm
/// of noise; `clock` maps true time to the receiver's clock.
#[allow(clippy::too_many_arguments)]
fn fly(
    guard: &mut Guarded<impl GuardedFilter>,
    anchors: &[[f64; 3]],
    path: impl Fn(f64) -> Vector3<f64>,
    seconds: f64,
    seed: u64,
    corrupt: Corrupt,
    clock: impl Fn(f64) -> f64,
) -> Flown {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.02).unwrap();
    let n = anchors.len();
    let mut out = Flown {
        worst_m: 0.0,
        published: 0,
        fed: 0,
        counts: GuardCounts::default(),
    };
    for k in 0..(seconds * 200.0) as usize {
        let t = k as f64 / 200.0;
        let (ia, ib) = (k % n, (k + 1) % n);
        let Some(extra) = corrupt(t, ia, ib) else {
            continue;
        };
        let p = path(t);
        let (a, b) = (anchors[ia], anchors[ib]);
        let d = (p - Vector3::from(b)).norm() - (p - Vector3::from(a)).norm();
        let m = RangeDifferenceSample {
            a_t_s: None,
            t_s: clock(t),
            a_m: a,
            b_m: b,
            d_m: d + noise.sample(&mut rng) + extra,
            sigma_m: 0.05,
            clocks: None,
            speed_rel_sigma: None,
        };
        out.fed += 1;
        if let Some(e) = guard.step(&m).published_m {
            out.published += 1;
            out.worst_m = out.worst_m.max((Vector3::from(e) - p).norm());
        }
    }
    out.counts = guard.counts();
    out
}

fn guarded(
    anchors: &[[f64; 3]],
    volume: Option<FlightVolume>,
    hint: Option<[f64; 3]>,
) -> Guarded<CvFilter> {
    let volume = volume.unwrap_or_else(|| FlightVolume::around(anchors, 0.5).unwrap());
    let filter = CvFilter::new(CvParams {
        shadow_prior_sigma_m: 0.0,
        ..CvParams::default()
    })
    .unwrap();
    Guarded::new(filter, volume, GuardParams::default(), hint)
}

fn clean(_: f64, _: usize, _: usize) -> Option<f64> {
    Some(0.0)
}

#[test]
fn nothing_is_published_before_a_consistent_window_and_then_everything_is_close() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    let f = fly(&mut g, &tx, circle, 20.0, 1, &mut clean, |t| t);
    assert!(f.worst_m < 0.1, "{}", f.worst_m);
    // Placed within the first fifth of a second.
    assert!(f.published + 40 >= f.fed, "{} of {}", f.published, f.fed);
    assert_eq!(f.counts.placements, 1);
}

/// Anchors in one horizontal plane: every range difference is the same
/// at the receiver's height and at its mirror image through the plane,
/// both inside the room. With no hint the watch says it is ambiguous and
/// publishes nothing; told where the receiver starts, it keeps that side
/// through a restart.
#[test]
fn mirror_solution_is_never_published() {
    let plane: Vec<[f64; 3]> = [
        (0.0, 0.0),
        (6.0, 0.0),
        (6.0, 6.0),
        (0.0, 6.0),
        (3.0, 0.0),
        (6.0, 3.0),
        (3.0, 6.0),
        (0.0, 3.0),
    ]
    .iter()
    .map(|&(x, y)| [x, y, 1.5])
    .collect();
    let room = FlightVolume::new([-0.5, -0.5, 0.0], [6.5, 6.5, 3.0]).unwrap();
    let low = |t: f64| circle(t) - Vector3::new(0.0, 0.0, 0.6);
    let mut blind = guarded(&plane, Some(room), None);
    let f = fly(&mut blind, &plane, low, 5.0, 2, &mut clean, |t| t);
    assert_eq!(f.published, 0);
    assert!(f.counts.ambiguous_windows > 10, "{:?}", f.counts);

    let mut told = guarded(&plane, Some(room), Some([4.5, 3.0, 0.6]));
    // A second of silence halfway: the filter restarts from a window,
    // which is as ambiguous as at the start.
    let mut gap = |t: f64, _: usize, _: usize| (!(10.0..11.5).contains(&t)).then_some(0.0);
    let f = fly(&mut told, &plane, low, 20.0, 3, &mut gap, |t| t);
    assert!(f.counts.lost_time_jump >= 1, "{:?}", f.counts);
    assert!(f.counts.placements >= 2, "{:?}", f.counts);
    assert!(f.worst_m < 0.3, "{}", f.worst_m);
    assert!(f.published > f.fed * 9 / 10, "{} of {}", f.published, f.fed);
}

/// Every two seconds one anchor is blocked for a second and arrives 0.3
/// to 1.5 m late, and 3 % of all measurements are wild.
#[test]
fn bursts_of_late_arrivals_do_not_move_the_estimate() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let late = rand_distr::Uniform::new(0.3, 1.5).unwrap();
    let wild = rand_distr::Uniform::new(-3.0, 3.0).unwrap();
    let coin = rand_distr::Uniform::new(0.0, 1.0).unwrap();
    let mut bursts = |t: f64, a: usize, b: usize| {
        let blocked = (t as usize / 2) % 8;
        let mut e = 0.0;
        if t % 2.0 < 1.0 {
            // Late at the blocked anchor: longer to B, or shorter to A.
            if b == blocked {
                e += late.sample(&mut rng);
            } else if a == blocked {
                e -= late.sample(&mut rng);
            }
        }
        if coin.sample(&mut rng) < 0.03 {
            e += wild.sample(&mut rng);
        }
        Some(e)
    };
    let f = fly(&mut g, &tx, circle, 40.0, 5, &mut bursts, |t| t);
    assert!(f.worst_m < 0.35, "{} {:?}", f.worst_m, f.counts);
    assert!(f.counts.set_aside > 0, "{:?}", f.counts);
    assert!(f.published > f.fed * 9 / 10, "{} of {}", f.published, f.fed);
}

#[test]
fn an_anchor_that_goes_silent_costs_nothing() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    // Anchor 3 dies after 5 s: its two pairs are never heard again.
    let mut silent = |t: f64, a: usize, b: usize| (t < 5.0 || (a != 3 && b != 3)).then_some(0.0);
    let f = fly(&mut g, &tx, circle, 30.0, 6, &mut silent, |t| t);
    assert!(f.worst_m < 0.15, "{}", f.worst_m);
    assert_eq!(f.counts.placements, 1, "{:?}", f.counts);
}

/// The receiver's clock steps 5 s forward at 10 s and 3 s back at 20 s
/// (a resynchronisation): the filter restarts each time instead of
/// coasting along its velocity, and what it publishes stays close.
#[test]
fn clock_jumps_restart_the_filter_without_a_jump_in_the_estimate() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    let clock = |t: f64| {
        if t < 10.0 {
            t
        } else if t < 20.0 {
            t + 5.0
        } else {
            t + 2.0
        }
    };
    let f = fly(&mut g, &tx, circle, 30.0, 7, &mut clean, clock);
    assert_eq!(f.counts.lost_time_jump, 2, "{:?}", f.counts);
    assert!(f.worst_m < 0.15, "{}", f.worst_m);
    assert!(f.published + 200 >= f.fed, "{} of {}", f.published, f.fed);
}

/// A filter certain of a wrong position (pushed there by a burst it let
/// in) passes its own gate on nothing; the consistent windows disagree and
/// the watch re-places it within a fraction of a second.
#[test]
fn a_filter_stuck_far_away_is_declared_lost_and_replaced() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    fly(&mut g, &tx, circle, 2.0, 8, &mut clean, |t| t);
    g.filter_mut()
        .reset(2.0, Vector3::new(5.0, 5.0, 0.3), 0.001);
    let after = |t: f64| circle(t + 2.0);
    let mut lost_for = 0;
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let noise = Normal::new(0.0, 0.02).unwrap();
    for k in 0..400 {
        let t = 2.0 + f64::from(k) / 200.0;
        let p = after(t - 2.0);
        let (a, b) = (tx[k as usize % 8], tx[(k as usize + 1) % 8]);
        let d = (p - Vector3::from(b)).norm() - (p - Vector3::from(a)).norm();
        let m = RangeDifferenceSample {
            a_t_s: None,
            t_s: t,
            a_m: a,
            b_m: b,
            d_m: d + noise.sample(&mut rng),
            sigma_m: 0.05,
            clocks: None,
            speed_rel_sigma: None,
        };
        match g.step(&m).published_m {
            Some(e) if (Vector3::from(e) - p).norm() > 0.2 => lost_for += 1,
            _ => {}
        }
    }
    let c = g.counts();
    assert!(c.lost_rejections + c.lost_disagreement >= 1, "{c:?}");
    // At most about half a second of bad estimates (at 200 Hz).
    assert!(lost_for < 100, "{lost_for}");
}

/// The receiver seems to teleport 4 m (the range differences switch to
/// another place at once): the consistent windows there are refused until
/// a receiver at its top speed could have got there, and then the filter
/// follows them.
#[test]
fn a_window_farther_than_the_motion_allows_waits_for_the_reach_to_grow() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    let jump = |t: f64| {
        if t < 10.0 {
            Vector3::new(2.0, 3.0, 1.2)
        } else {
            Vector3::new(2.0, 3.0, 1.2) + Vector3::new(4.0, 0.0, 0.0) * 0.9
        }
    };
    let f = fly(&mut g, &tx, jump, 16.0, 11, &mut clean, |t| t);
    assert!(f.counts.unreachable_windows > 0, "{:?}", f.counts);
    assert_eq!(f.counts.placements, 2, "{:?}", f.counts);
    let end = jump(16.0);
    assert!((g.filter().position_m() - end).norm() < 0.1);
}

/// A constant-velocity filter that claims to keep tracking while lost (as
/// an IMU-driven one does): over a quarter of a second its extrapolation
/// stays within centimetres on the circle.
struct Tracking(CvFilter);

impl GuardedFilter for Tracking {
    fn predict_to(&mut self, t_s: f64) {
        self.0.predict_to(t_s);
    }
    fn position_m(&self) -> Vector3<f64> {
        self.0.position_m()
    }
    fn position_sigma_m(&self) -> f64 {
        self.0.position_sigma_m()
    }
    fn position_covariance_m2(&self) -> nalgebra::Matrix3<f64> {
        self.0.position_covariance_m2()
    }
    fn predicted_m(&self, m: &RangeDifferenceSample) -> Option<f64> {
        self.0.predicted_m(m)
    }
    fn update(&mut self, m: &RangeDifferenceSample) -> crate::estimator::tdoa_ekf::Outcome {
        self.0.update(m)
    }
    fn reset(&mut self, t_s: f64, position_m: Vector3<f64>, sigma_m: f64) {
        self.0.reset(t_s, position_m, sigma_m);
    }
    fn constrain(&mut self, volume: &FlightVolume) -> bool {
        self.0.constrain(volume)
    }
    fn tracks_while_lost(&self) -> bool {
        true
    }
}

/// A quarter of a second in which every range difference is wild makes
/// the filter fail its gate and be declared lost. A filter that keeps
/// tracking is resumed where the first clean window agrees with it (not
/// restarted at rest); one that does not is re-placed.
#[test]
fn a_filter_that_tracks_while_lost_is_resumed_not_restarted() {
    let tx = corners();
    let burst = |seed: u64| {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let wild = rand_distr::Uniform::new(-3.0, 3.0).unwrap();
        move |t: f64, _: usize, _: usize| {
            Some(if (10.0..10.25).contains(&t) {
                wild.sample(&mut rng)
            } else {
                0.0
            })
        }
    };
    let volume = FlightVolume::around(&tx, 0.5).unwrap();
    let filter = CvFilter::new(CvParams::default()).unwrap();
    let mut tracking = Guarded::new(Tracking(filter), volume, GuardParams::default(), None);
    let f = fly(&mut tracking, &tx, circle, 20.0, 7, &mut burst(8), |t| t);
    assert!(f.counts.lost_rejections >= 1, "{:?}", f.counts);
    assert!(f.counts.resumed >= 1, "{:?}", f.counts);
    assert_eq!(f.counts.placements, 1, "{:?}", f.counts);
    assert!(f.worst_m < 0.3, "{} {:?}", f.worst_m, f.counts);

    let mut plain = guarded(&tx, None, None);
    let f = fly(&mut plain, &tx, circle, 20.0, 7, &mut burst(8), |t| t);
    assert!(f.counts.lost_rejections >= 1, "{:?}", f.counts);
    assert_eq!(f.counts.resumed, 0, "{:?}", f.counts);
    assert!(f.counts.placements >= 2, "{:?}", f.counts);
}
