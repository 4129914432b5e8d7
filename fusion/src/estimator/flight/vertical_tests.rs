//! The constant-velocity filter's vertical share of the acceleration
//! density, on a synthetic flight reproducing a UTIL flight's worst
//! moment: the receiver flies level well above the floor anchors, a
//! ceiling anchor arrives late for a second (the range differences then
//! agree with a receiver lower down, a direction the excess paths already
//! make weakly observed: a height error and excess paths on the ceiling
//! anchors look alike), and a filter whose height is as free as its
//! horizontal position follows the run down.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::corners;
use super::*;
use crate::estimator::RangeDifferenceSample;
use crate::estimator::guard::GuardedFilter;

/// The truth at `t_s`: along x at 1 m/s at 2.2 m, with a vertical sine of
/// `sine_m` amplitude and 8 s period.
fn truth(t_s: f64, sine_m: f64) -> Vector3<f64> {
    let w = std::f64::consts::TAU / 8.0;
    Vector3::new(1.0 + t_s, 3.0, 2.2 + sine_m * (w * t_s).sin())
}

/// Flies 4 s, TDoA2 pairs `(k - 1, k)` at 400 Hz with 0.1 m of noise;
/// ceiling anchor 4 is `late_m` late from 2 to 3 s. The largest
/// height error from 1 s on (after the start settles), metres.
fn worst_height_error_m(vertical_psd_ratio: f64, sine_m: f64, late_m: f64) -> f64 {
    let anchors = corners();
    let n = anchors.len();
    let mut f = CvFilter::new(CvParams {
        vertical_psd_ratio,
        excess: ExcessParams {
            sigma_m: 0.1,
            correlation_s: 1.0,
        },
        ..CvParams::default()
    })
    .unwrap();
    f.reset(0.0, truth(0.0, sine_m), 0.05);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut worst_m = 0.0_f64;
    for i in 1..1600 {
        let t_s = f64::from(i) / 400.0;
        let p = truth(t_s, sine_m);
        let late = |id: usize| match (id, (2.0..3.0).contains(&t_s)) {
            (4, true) => late_m,
            _ => 0.0,
        };
        let range = |id: usize| (p - Vector3::from(anchors[id])).norm() + late(id);
        let (a, b) = ((i as usize + n - 1) % n, i as usize % n);
        f.predict_to(t_s);
        f.update(&RangeDifferenceSample {
            a_t_s: None,
            t_s,
            a_m: anchors[a],
            b_m: anchors[b],
            d_m: range(b) - range(a) + noise.sample(&mut rng),
            sigma_m: 0.1,
            clocks: None,
            speed_rel_sigma: None,
        });
        if t_s >= 1.0 {
            worst_m = worst_m.max((f.position_m().z - p.z).abs());
        }
    }
    worst_m
}

#[test]
fn a_late_run_on_a_ceiling_anchor_pulls_the_height_less_with_a_vertical_share() {
    // 0.6 m late for 1 s: six times the excess paths' sigma, a run the
    // excess path cannot take up alone.
    let isotropic = worst_height_error_m(1.0, 0.0, 0.6);
    let vertical = worst_height_error_m(0.1, 0.0, 0.6);
    assert!(
        vertical < 0.85 * isotropic,
        "height error {vertical} against {isotropic} m"
    );
}

#[test]
fn a_vertical_sine_of_the_flight_plans_is_still_followed() {
    // +-0.5 m every 8 s, no late run: the share costs little.
    let isotropic = worst_height_error_m(1.0, 0.5, 0.0);
    let vertical = worst_height_error_m(0.1, 0.5, 0.0);
    assert!(
        vertical < isotropic + 0.05,
        "height error {vertical} against {isotropic} m"
    );
}
