//! The excess-path states on a synthetic hover where one anchor's signal
//! arrives late for two seconds (a reflection), as on the UTIL flights.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::corners;
use super::*;
use crate::estimator::RangeDifferenceSample;
use crate::estimator::guard::GuardedFilter;

/// What [`hover`] measured.
struct Hover {
    /// Largest position error over the run, metres.
    worst_m: f64,
    /// Mean position error over the second half of the late run (3 to
    /// 4 s), when a filter has settled on whatever it makes of it, metres.
    late_mean_m: f64,
    /// The excess path the filter gives anchor 0 just before 4 s, metres.
    excess_m: f64,
}

/// Hovering at `truth`, TDoA2 pairs `(k - 1, k)` at 400 Hz for 6 s with
/// 0.05 m of noise; anchor 0 (on the floor) is `late_m` late from 2 to
/// 4 s.
fn hover(excess: ExcessParams, late_m: f64) -> Hover {
    let anchors = corners();
    let n = anchors.len();
    let truth = Vector3::new(2.5, 3.5, 1.2);
    let mut f = CvFilter::new(CvParams {
        excess,
        ..CvParams::default()
    })
    .unwrap();
    f.reset(0.0, truth, 0.05);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let range = |id: usize| (truth - Vector3::from(anchors[id])).norm();
    let (mut worst_m, mut late_sum, mut late_n, mut excess_m) = (0.0_f64, 0.0, 0.0, 0.0);
    for i in 1..2400 {
        let t_s = f64::from(i) / 400.0;
        let late = |id: usize| {
            if id == 0 && (2.0..4.0).contains(&t_s) {
                late_m
            } else {
                0.0
            }
        };
        let (a, b) = ((i as usize + n - 1) % n, i as usize % n);
        let d_m = range(b) + late(b) - range(a) - late(a) + noise.sample(&mut rng);
        f.predict_to(t_s);
        f.update(&RangeDifferenceSample {
            a_t_s: None,
            t_s,
            a_m: anchors[a],
            b_m: anchors[b],
            d_m,
            sigma_m: 0.05,
            clocks: None,
            speed_rel_sigma: None,
        });
        let err = (f.position_m() - truth).norm();
        worst_m = worst_m.max(err);
        if (3.0..4.0).contains(&t_s) {
            late_sum += err;
            late_n += 1.0;
            excess_m = f
                .excess_paths_m()
                .iter()
                .find(|e| e.0 == anchors[0])
                .map_or(0.0, |e| e.1);
        }
    }
    Hover {
        worst_m,
        late_mean_m: late_sum / late_n,
        excess_m,
    }
}

const ON: ExcessParams = ExcessParams {
    sigma_m: 0.1,
    correlation_s: 1.0,
};

#[test]
fn a_late_anchor_is_taken_up_by_its_excess_path_not_by_the_position() {
    // 0.2 m late: twice the model's sigma, well inside the 3-sigma gate of
    // a plain filter, so the plain filter takes it all into the position.
    let plain = hover(ExcessParams::default(), 0.2);
    let with = hover(ON, 0.2);
    assert!(
        with.late_mean_m < 0.5 * plain.late_mean_m,
        "settled error {} against {}",
        with.late_mean_m,
        plain.late_mean_m
    );
    assert!(
        with.worst_m < plain.worst_m,
        "{} against {}",
        with.worst_m,
        plain.worst_m
    );
    assert!(
        (0.1..=0.25).contains(&with.excess_m),
        "anchor 0's excess {} for 0.2 m late",
        with.excess_m
    );
}

#[test]
fn without_a_late_anchor_the_excess_paths_cost_little() {
    let plain = hover(ExcessParams::default(), 0.0);
    let with = hover(ON, 0.0);
    assert!(
        with.worst_m < plain.worst_m + 0.05,
        "{} against {}",
        with.worst_m,
        plain.worst_m
    );
    assert!(
        with.excess_m < 0.05,
        "an excess of {} from noise",
        with.excess_m
    );
}
