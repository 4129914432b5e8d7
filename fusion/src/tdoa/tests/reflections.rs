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
fn early_outliers_are_rejected_only_when_late_only_is_off() {
    let p = Vector3::new(2.5, 2.0, 0.4);
    let mut s = signals_at(&ceiling(8), p, 2.0);
    s[4].pseudo_range_m -= 0.2;
    let mode = Mode::TwoD { height_m: 0.4 };
    let fix = solve(&s, &cfg(mode)).unwrap();
    assert_eq!(fix.quality, Quality::Suspect);
    let fix = solve(
        &s,
        &SolverConfig {
            late_only: false,
            ..cfg(mode)
        },
    )
    .unwrap();
    assert_eq!(fix.rejected.len(), 1);
    assert_eq!(fix.rejected[0].tx_id, s[4].tx_id);
    assert_eq!(fix.quality, Quality::Good);
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
