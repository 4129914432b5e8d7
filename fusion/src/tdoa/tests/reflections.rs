//! Reflection rejection: late arrivals found by the physical check or by
//! leave-one-out, ambiguous roots resolved by the allowed area.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::{ceiling, room, signals_at};
use crate::tdoa::*;

fn cfg(mode: Mode) -> SolverConfig {
    SolverConfig {
        mode,
        sigma_range_m: 0.01,
        ..SolverConfig::default()
    }
}

#[test]
fn rejects_a_late_reflection_with_redundant_signals() {
    let p = Vector3::new(2.5, 2.0, 0.4);
    let mut s = signals_at(&ceiling(8), p, 2.0);
    s[3].pseudo_range_m += 0.2;
    let fix = solve(&s, &cfg(Mode::TwoD { height_m: 0.4 })).unwrap();
    assert_eq!(fix.rejected.len(), 1, "{fix:?}");
    let r = fix.rejected[0];
    assert_eq!(r.tx_id, s[3].tx_id);
    match r.reason {
        RejectReason::Residual { residual_m } => assert!((residual_m - 0.2).abs() < 1e-6),
        other => panic!("{other:?}"),
    }
    assert!((fix.position_m - p).norm() < 1e-6);
    assert_eq!(fix.quality, Quality::Good);
    assert!(!fix.used_tx_ids.contains(&s[3].tx_id));
    assert_eq!(fix.residuals_m.len(), 7);
}

#[test]
fn rejects_a_range_difference_longer_than_its_baseline_before_solving() {
    let p = Vector3::new(2.5, 2.0, 1.0);
    let mut s = signals_at(&room(), p, 0.0);
    s[5].pseudo_range_m += 30.0;
    let fix = solve(&s, &cfg(Mode::ThreeD)).unwrap();
    assert_eq!(fix.rejected.len(), 1, "{fix:?}");
    assert_eq!(fix.rejected[0].tx_id, s[5].tx_id);
    assert!(matches!(
        fix.rejected[0].reason,
        RejectReason::ExceedsBaseline { excess_m, .. } if excess_m > 15.0
    ));
    assert!((fix.position_m - p).norm() < 1e-6);
}

#[test]
fn rejects_two_reflections_when_redundancy_allows() {
    let p = Vector3::new(3.5, 2.0, 1.2);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let mut s = signals_at(&room(), p, 5.0);
    s.iter_mut()
        .for_each(|x| x.pseudo_range_m += noise.sample(&mut rng));
    s[1].pseudo_range_m += 0.25;
    s[6].pseudo_range_m += 0.6;
    let fix = solve(&s, &cfg(Mode::ThreeD)).unwrap();
    let mut ids: Vec<_> = fix.rejected.iter().map(|r| r.tx_id).collect();
    ids.sort_unstable();
    assert_eq!(ids, [s[1].tx_id, s[6].tx_id], "{fix:?}");
    assert!((fix.position_m - p).norm() < 0.05, "{fix:?}");
    assert_eq!(fix.quality, Quality::Good);
}

#[test]
fn finds_random_reflections_among_eight_noisy_signals() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let sigma = 0.01;
    let noise = Normal::new(0.0, sigma).unwrap();
    let tx = ceiling(8);
    let draws = 500;
    let mut found = 0;
    for _ in 0..draws {
        let p = Vector3::new(rng.random_range(0.5..5.5), rng.random_range(0.5..4.5), 0.3);
        let mut s = signals_at(&tx, p, rng.random_range(-20.0..20.0));
        s.iter_mut()
            .for_each(|x| x.pseudo_range_m += noise.sample(&mut rng));
        let k = rng.random_range(0..s.len());
        s[k].pseudo_range_m += rng.random_range(0.2..1.5);
        let fix = solve(&s, &cfg(Mode::TwoD { height_m: 0.3 })).unwrap();
        if fix.rejected.iter().any(|r| r.tx_id == s[k].tx_id) && fix.quality == Quality::Good {
            found += 1;
            assert!((fix.position_m - p).norm() < 0.1, "{fix:?} vs {p:?}");
        }
    }
    assert!(found * 100 >= draws * 98, "{found} of {draws}");
}

#[test]
fn keeps_a_suspect_fix_when_rejection_is_disabled() {
    let p = Vector3::new(2.5, 2.0, 0.4);
    let mut s = signals_at(&ceiling(8), p, 2.0);
    s[3].pseudo_range_m += 0.2;
    let config = SolverConfig {
        max_rejections: 0,
        ..cfg(Mode::TwoD { height_m: 0.4 })
    };
    let fix = solve(&s, &config).unwrap();
    assert!(fix.rejected.is_empty());
    assert_eq!(fix.quality, Quality::Suspect);
    assert_eq!(fix.used_tx_ids.len(), 8);
}

#[test]
fn an_early_outlier_is_left_to_the_consensus_when_only_late_ones_are_rejected_one_by_one() {
    let p = Vector3::new(2.5, 2.0, 0.4);
    let mut s = signals_at(&ceiling(8), p, 2.0);
    s[4].pseudo_range_m -= 0.2;
    let mode = Mode::TwoD { height_m: 0.4 };
    // Leave-one-out alone (the consensus needs two spare signals; with
    // `max_rejections` 0 and `late_only` it cannot act) keeps it Suspect...
    let fix = solve(
        &s[..5],
        &SolverConfig {
            max_rejections: 0,
            ..cfg(mode)
        },
    )
    .unwrap();
    assert_eq!(fix.quality, Quality::Suspect);
    // ...while both the consensus (late_only) and leave-one-out (not
    // late_only) find it among eight.
    for late_only in [true, false] {
        let fix = solve(
            &s,
            &SolverConfig {
                late_only,
                ..cfg(mode)
            },
        )
        .unwrap();
        assert_eq!(fix.rejected.len(), 1, "late_only {late_only}: {fix:?}");
        assert_eq!(fix.rejected[0].tx_id, s[4].tx_id);
        assert_eq!(fix.quality, Quality::Good);
        assert!((fix.position_m - p).norm() < 1e-6);
    }
}

#[test]
fn a_wrong_id_heard_early_no_longer_throws_the_whole_cycle_away() {
    // A burst decoded with another transmitter's id is placed at that
    // transmitter's slot: tens of metres early. Every other signal then
    // exceeds its baseline against it, and a physical check that dropped
    // the later side would leave one signal.
    let p = Vector3::new(2.5, 2.0, 0.4);
    let mut s = signals_at(&ceiling(10), p, 2.0);
    s[6].pseudo_range_m -= 48.7;
    let fix = solve(&s, &cfg(Mode::TwoD { height_m: 0.4 })).unwrap();
    assert_eq!(fix.quality, Quality::Good, "{fix:?}");
    assert!((fix.position_m - p).norm() < 1e-6, "{fix:?}");
    assert_eq!(fix.used_tx_ids.len(), 9);
    assert_eq!(
        fix.rejected.iter().map(|r| r.tx_id).collect::<Vec<_>>(),
        [s[6].tx_id]
    );
}

#[test]
fn four_reflections_are_more_than_leave_one_out_removes_but_not_more_than_the_consensus_finds() {
    let p = Vector3::new(3.2, 1.7, 0.4);
    let mut s = signals_at(&ceiling(12), p, -3.0);
    for (k, extra_m) in [(1, 0.35), (4, 1.2), (7, 0.6), (10, 0.9)] {
        s[k].pseudo_range_m += extra_m;
    }
    let mode = Mode::TwoD { height_m: 0.4 };
    let fix = solve(&s, &cfg(mode)).unwrap();
    assert_eq!(fix.quality, Quality::Good, "{fix:?}");
    assert!((fix.position_m - p).norm() < 1e-6, "{fix:?}");
    let mut ids: Vec<_> = fix.rejected.iter().map(|r| r.tx_id).collect();
    ids.sort_unstable();
    assert_eq!(ids, [s[1].tx_id, s[4].tx_id, s[7].tx_id, s[10].tx_id]);
}

#[test]
fn up_to_four_reflections_and_a_wrong_id_among_twelve_noisy_signals() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let sigma = 0.01;
    let noise = Normal::new(0.0, sigma).unwrap();
    let tx = ceiling(12);
    let mode = Mode::TwoD { height_m: 0.3 };
    let draws = 300;
    let (mut good, mut wrong) = (0, 0);
    for _ in 0..draws {
        let p = Vector3::new(rng.random_range(0.5..5.5), rng.random_range(0.5..4.5), 0.3);
        let mut s = signals_at(&tx, p, rng.random_range(-20.0..20.0));
        s.iter_mut()
            .for_each(|x| x.pseudo_range_m += noise.sample(&mut rng));
        let mut bad = std::collections::BTreeSet::new();
        for _ in 0..rng.random_range(0..=4) {
            let k = rng.random_range(0..s.len());
            if bad.insert(k) {
                s[k].pseudo_range_m += rng.random_range(0.2..1.5);
            }
        }
        if rng.random_bool(0.5) {
            let k = rng.random_range(0..s.len());
            if bad.insert(k) {
                s[k].pseudo_range_m += rng.random_range(-40.0..40.0);
            }
        }
        let Ok(fix) = solve(&s, &cfg(mode)) else {
            continue;
        };
        if fix.quality == Quality::Good {
            good += 1;
            if (fix.position_m - p).norm() > 0.1 {
                wrong += 1;
            }
        }
    }
    // A Good fix is a right one; nearly every cycle gives one.
    assert_eq!(wrong, 0, "{wrong} wrong of {good} good");
    assert!(good * 100 >= draws * 97, "{good} of {draws}");
}

#[test]
fn the_consensus_does_not_make_a_fix_out_of_noise() {
    // Ten pseudo-ranges drawn at random. Four of them fitting one point by
    // chance happens now and then, with or without the consensus (one spare
    // signal is weak evidence); the consensus wants a majority, six of ten,
    // and six never agree by chance (none in 3000 draws when this was
    // written).
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let tx = ceiling(10);
    let mode = Mode::TwoD { height_m: 0.3 };
    for _ in 0..1000 {
        let s: Vec<Signal> = tx
            .iter()
            .enumerate()
            .map(|(i, &t)| Signal {
                tx_id: i as u32,
                tx_m: t,
                pseudo_range_m: rng.random_range(0.0..8.0),
                t_s: 0.0,
            })
            .collect();
        if let Ok(fix) = solve(&s, &cfg(mode)) {
            let agreed = fix.used_tx_ids.len();
            assert!(fix.quality != Quality::Good || agreed < 6, "{fix:?}");
        }
    }
}

#[test]
fn allowed_area_picks_the_root_inside_when_two_fit() {
    // Outside the triangle of three transmitters both roots of the quadratic
    // are physical and fit exactly (found by a scan).
    let p = Vector3::new(-10.0, 7.42, 0.5);
    let s = signals_at(&ceiling(3), p, 1.0);
    let mode = Mode::TwoD { height_m: 0.5 };
    let fix = solve(&s, &cfg(mode)).unwrap();
    assert_eq!(fix.quality, Quality::Ambiguous);
    let other = fix.alternative_m.unwrap();
    let truth_found = [fix.position_m, other]
        .iter()
        .any(|c| (c - p).norm() < 1e-6);
    assert!(truth_found, "{fix:?}");

    let config = SolverConfig {
        allowed_area_m: Some(Aabb {
            min_m: Vector3::new(-20.0, -20.0, 0.0),
            max_m: Vector3::new(20.0, 20.0, 3.0),
        }),
        ..cfg(mode)
    };
    let fix = solve(&s, &config).unwrap();
    assert!((fix.position_m - p).norm() < 1e-6, "{fix:?}");
    assert_eq!(fix.quality, Quality::Minimal);
    assert_eq!(fix.alternative_m, None);
}

#[test]
fn reports_what_was_rejected_when_too_few_consistent_signals_remain() {
    let p = Vector3::new(2.5, 2.0, 0.4);
    let mut s = signals_at(&ceiling(4), p, 0.0);
    s[0].pseudo_range_m += 30.0;
    s[2].pseudo_range_m += 40.0;
    match solve(&s, &cfg(Mode::TwoD { height_m: 0.4 })) {
        Err(SolveError::TooFewConsistent {
            got: 2,
            need: 3,
            rejected,
        }) => {
            let mut ids: Vec<_> = rejected.iter().map(|r| r.tx_id).collect();
            ids.sort_unstable();
            assert_eq!(ids, [s[0].tx_id, s[2].tx_id]);
        }
        other => panic!("{other:?}"),
    }
}
