//! The IMU filter under the watch on the synthetic flights of
//! `guard/tests.rs` that break plain filters (a geometry with a mirror
//! solution, bursts of late arrivals, an anchor that goes silent, clock
//! jumps), now with the IMU stream beside the range differences. Every
//! test asserts a bound on the error of every published estimate.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::corners;
use super::*;
use crate::estimator::RangeDifferenceSample;
use crate::estimator::guard::{FlightVolume, GuardCounts, GuardParams, Guarded};

/// A level circle of 1.5 m radius at `z_m`, 0.5 rad/s, facing +x: position
/// and acceleration.
fn circle(t: f64, z_m: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (r, w) = (1.5, 0.5);
    let (c, s) = ((w * t).cos(), (w * t).sin());
    (
        Vector3::new(3.0 + r * c, 3.0 + r * s, z_m),
        Vector3::new(-r * w * w * c, -r * w * w * s, 0.0),
    )
}

/// What a flight does to the measurement of pair `(a, b)` at true time
/// `t`: `None` drops it, else the added error in metres.
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

/// The IMU at 200 Hz (0.3 m/s^2 and 0.01 rad/s of noise), one
/// round-robin range difference after each sample, with 2 cm of noise; `clock` maps true time
/// to the receiver's clock, which stamps both streams.
#[allow(clippy::too_many_arguments)]
fn fly(
    guard: &mut Guarded<ImuFilter>,
    anchors: &[[f64; 3]],
    z_m: f64,
    seconds: f64,
    seed: u64,
    corrupt: Corrupt,
    clock: impl Fn(f64) -> f64,
) -> Flown {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let range_noise = Normal::new(0.0, 0.02).unwrap();
    let accel_noise = Normal::new(0.0, 0.3).unwrap();
    let gyro_noise = Normal::new(0.0, 0.01).unwrap();
    let n = anchors.len();
    let mut out = Flown {
        worst_m: 0.0,
        published: 0,
        fed: 0,
        counts: GuardCounts::default(),
    };
    for i in 0..(seconds * 200.0) as usize {
        let t = i as f64 * 0.005;
        let (p, a) = circle(t, z_m);
        let f = a + Vector3::new(0.0, 0.0, 9.81);
        guard.filter_mut().imu(&ImuSample {
            t_s: clock(t),
            accel_m_s2: std::array::from_fn(|j| f[j] + accel_noise.sample(&mut rng)),
            gyro_rad_s: std::array::from_fn(|_| gyro_noise.sample(&mut rng)),
        });
        let (ia, ib) = (i % n, (i + 1) % n);
        let Some(extra) = corrupt(t, ia, ib) else {
            continue;
        };
        let (pa, pb) = (Vector3::from(anchors[ia]), Vector3::from(anchors[ib]));
        let m = RangeDifferenceSample {
            a_t_s: None,
            t_s: clock(t),
            a_m: anchors[ia],
            b_m: anchors[ib],
            d_m: (p - pb).norm() - (p - pa).norm() + range_noise.sample(&mut rng) + extra,
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
) -> Guarded<ImuFilter> {
    let volume = volume.unwrap_or_else(|| FlightVolume::around(anchors, 0.5).unwrap());
    let filter = ImuFilter::new(ImuParams::default()).unwrap();
    Guarded::new(filter, volume, GuardParams::default(), hint)
}

fn clean(_: f64, _: usize, _: usize) -> Option<f64> {
    Some(0.0)
}

/// Anchors in one horizontal plane: the receiver below it and its mirror
/// image above explain every range difference. Told where it starts, the
/// watch keeps that side, through a second of silence that makes it
/// restart, and never publishes the mirror.
#[test]
fn imu_filter_never_publishes_the_mirror_solution() {
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
    let mut blind = guarded(&plane, Some(room), None);
    let f = fly(&mut blind, &plane, 0.9, 5.0, 2, &mut clean, |t| t);
    assert_eq!(f.published, 0, "{:?}", f.counts);
    assert!(f.counts.ambiguous_windows > 10, "{:?}", f.counts);

    let mut told = guarded(&plane, Some(room), Some([4.5, 3.0, 0.9]));
    let mut gap = |t: f64, _: usize, _: usize| (!(10.0..11.5).contains(&t)).then_some(0.0);
    let f = fly(&mut told, &plane, 0.9, 20.0, 3, &mut gap, |t| t);
    assert!(f.counts.lost_time_jump >= 1, "{:?}", f.counts);
    assert!(f.counts.placements >= 2, "{:?}", f.counts);
    assert!(f.worst_m < 0.3, "{} {:?}", f.worst_m, f.counts);
    assert!(f.published > f.fed * 8 / 10, "{} of {}", f.published, f.fed);
}

/// Every two seconds one anchor is blocked for a second and arrives 0.3
/// to 1.5 m late, and 3 % of all measurements are wild.
#[test]
fn imu_filter_rides_out_bursts_of_late_arrivals() {
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
    let f = fly(&mut g, &tx, 1.5, 40.0, 5, &mut bursts, |t| t);
    assert!(f.worst_m < 0.35, "{} {:?}", f.worst_m, f.counts);
    assert!(f.counts.set_aside > 0, "{:?}", f.counts);
    assert!(f.published > f.fed * 9 / 10, "{} of {}", f.published, f.fed);
}

#[test]
fn imu_filter_loses_nothing_when_an_anchor_goes_silent() {
    let tx = corners();
    let mut g = guarded(&tx, None, None);
    let mut silent = |t: f64, a: usize, b: usize| (t < 5.0 || (a != 3 && b != 3)).then_some(0.0);
    let f = fly(&mut g, &tx, 1.5, 30.0, 6, &mut silent, |t| t);
    assert!(f.worst_m < 0.15, "{} {:?}", f.worst_m, f.counts);
    assert_eq!(f.counts.placements, 1, "{:?}", f.counts);
}

/// The receiver's clock, which stamps the IMU and the range differences
/// alike, steps 5 s forward at 10 s and 3 s back at 20 s: the filter
/// restarts each time and integrates the IMU on the new clock (it must
/// not wait for the old time to come back), and what it publishes stays
/// close.
#[test]
fn imu_filter_restarts_on_clock_jumps_either_way() {
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
    let f = fly(&mut g, &tx, 1.5, 30.0, 7, &mut clean, clock);
    assert_eq!(f.counts.lost_time_jump, 2, "{:?}", f.counts);
    assert!(f.worst_m < 0.15, "{} {:?}", f.worst_m, f.counts);
    assert!(f.published + 400 >= f.fed, "{} of {}", f.published, f.fed);
}
