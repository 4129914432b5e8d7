//! Every malformed or unsolvable input gives its typed error, never a panic
//! or a NaN.

use nalgebra::Vector3;

use super::{ceiling, room, signals_at};
use crate::tdoa::*;

fn p() -> Vector3<f64> {
    Vector3::new(2.0, 1.5, 0.5)
}

fn cfg(mode: Mode) -> SolverConfig {
    SolverConfig {
        mode,
        ..SolverConfig::default()
    }
}

#[test]
fn rejects_too_few_signals_for_the_mode() {
    let s = signals_at(&room(), p(), 0.0);
    assert_eq!(
        solve(&s[..3], &cfg(Mode::ThreeD)),
        Err(SolveError::TooFewSignals { got: 3, need: 4 })
    );
    let two_d = Mode::TwoD { height_m: 0.5 };
    assert_eq!(
        closed_form(&s[..2], two_d),
        Err(SolveError::TooFewSignals { got: 2, need: 3 })
    );
    assert_eq!(
        solve(&[], &cfg(two_d)).unwrap_err().kind(),
        ErrorKind::NoFix
    );
}

#[test]
fn rejects_coplanar_transmitters_in_3d() {
    let s = signals_at(&ceiling(8), p(), 0.0);
    let err = solve(&s, &cfg(Mode::ThreeD)).unwrap_err();
    assert!(
        matches!(err, SolveError::DegenerateGeometry { two_d: false, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("coplanar"));
    // The same constellation is fine with the height known.
    assert!(solve(&s, &cfg(Mode::TwoD { height_m: 0.5 })).is_ok());
}

#[test]
fn rejects_transmitters_collinear_seen_from_above_in_2d() {
    let tx: Vec<_> = (0..5)
        .map(|i| Vector3::new(i as f64, 0.5 * i as f64, 2.0 + 0.3 * i as f64))
        .collect();
    let err = closed_form(&signals_at(&tx, p(), 0.0), Mode::TwoD { height_m: 0.5 }).unwrap_err();
    assert!(
        matches!(err, SolveError::DegenerateGeometry { two_d: true, .. }),
        "{err}"
    );
}

#[test]
fn rejects_duplicate_transmitter_ids() {
    let mut s = signals_at(&room(), p(), 0.0);
    s[5].tx_id = s[2].tx_id;
    let err = solve(&s, &cfg(Mode::ThreeD)).unwrap_err();
    assert_eq!(err, SolveError::DuplicateTransmitter { tx_id: s[2].tx_id });
    assert!(err.is_bad_input());
}

#[test]
fn rejects_non_finite_input() {
    for (k, bad) in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY]
        .iter()
        .enumerate()
    {
        let mut s = signals_at(&room(), p(), 0.0);
        s[k].pseudo_range_m = *bad;
        assert_eq!(
            solve(&s, &cfg(Mode::ThreeD)),
            Err(SolveError::NonFinite {
                field: "pseudo_range_m",
                index: k
            })
        );
        let mut s = signals_at(&room(), p(), 0.0);
        s[k + 1].tx_m.y = *bad;
        let err = closed_form(&s, Mode::ThreeD).unwrap_err();
        assert!(err.is_bad_input(), "{err}");
    }
    let s = signals_at(&ceiling(5), p(), 0.0);
    assert!(solve(&s, &cfg(Mode::TwoD { height_m: f64::NAN })).is_err_and(|e| e.is_bad_input()));
}

#[test]
fn rejects_more_signals_than_the_subset_mask_holds() {
    let tx: Vec<_> = (0..MAX_SIGNALS + 1)
        .map(|i| Vector3::new((i % 8) as f64, (i / 8) as f64, 2.0 + (i % 3) as f64))
        .collect();
    assert_eq!(
        solve(&signals_at(&tx, p(), 0.0), &cfg(Mode::ThreeD)),
        Err(SolveError::TooManySignals {
            got: MAX_SIGNALS + 1,
            max: MAX_SIGNALS
        })
    );
}

#[test]
fn rejects_invalid_configuration() {
    let s = signals_at(&room(), p(), 0.0);
    let base = cfg(Mode::ThreeD);
    let area = Aabb {
        min_m: Vector3::new(1.0, 0.0, 0.0),
        max_m: Vector3::new(0.0, 5.0, 3.0),
    };
    for (bad, field) in [
        (
            SolverConfig {
                sigma_range_m: 0.0,
                ..base
            },
            "sigma_range_m",
        ),
        (
            SolverConfig {
                sigma_range_m: f64::NAN,
                ..base
            },
            "sigma_range_m",
        ),
        (
            SolverConfig {
                gate: Gate::Metres(-1.0),
                ..base
            },
            "gate",
        ),
        (
            SolverConfig {
                allowed_area_m: Some(area),
                ..base
            },
            "allowed_area_m",
        ),
        (
            SolverConfig {
                max_iterations: 0,
                ..base
            },
            "max_iterations",
        ),
    ] {
        match solve(&s, &bad) {
            Err(SolveError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: {other:?}"),
        }
    }
}

#[test]
fn reports_hyperbolas_that_do_not_intersect() {
    // Found by a scan: one range difference 1.5 m too long here leaves the
    // quadratic in r_1 without a real root.
    let mode = Mode::TwoD { height_m: 0.5 };
    let mut s = signals_at(&ceiling(3), Vector3::new(-10.0, -10.0, 0.5), 1.0);
    s[1].pseudo_range_m += 1.5;
    let err = closed_form(&s, mode).unwrap_err();
    assert!(matches!(err, SolveError::NoRealRoot { discriminant } if discriminant < 0.0));
    assert_eq!(err.kind(), ErrorKind::NoFix);
}

#[test]
fn reports_roots_with_negative_distances() {
    // Found by a scan: both roots put a transmitter at negative range.
    let mode = Mode::TwoD { height_m: 0.5 };
    let mut s = signals_at(&ceiling(3), Vector3::new(4.56, 0.27, 0.5), 1.0);
    s[1].pseudo_range_m += 1.5;
    assert_eq!(closed_form(&s, mode), Err(SolveError::NoPhysicalRoot));
}

#[test]
fn reports_a_fix_outside_the_allowed_area() {
    let s = signals_at(&room(), Vector3::new(9.0, 9.0, 1.0), 0.0);
    let config = SolverConfig {
        allowed_area_m: Some(Aabb {
            min_m: Vector3::zeros(),
            max_m: Vector3::new(6.0, 5.0, 3.0),
        }),
        ..cfg(Mode::ThreeD)
    };
    let err = solve(&s, &config).unwrap_err();
    assert!(
        matches!(err, SolveError::OutsideAllowedArea { position_m } if (position_m[0] - 9.0).abs() < 1e-6),
        "{err}"
    );
}

#[test]
fn unsolvable_cycles_never_yield_a_nan_position() {
    // Pseudo-ranges that fit no position at all, in many shapes.
    let tx = room();
    for k in 0..200 {
        let s: Vec<_> = tx
            .iter()
            .enumerate()
            .map(|(i, &t)| Signal {
                tx_id: i as u32,
                tx_m: t,
                pseudo_range_m: ((k * 31 + i * 17) % 23) as f64 * 0.7 - 3.0,
                t_s: 0.0,
            })
            .collect();
        for mode in [Mode::ThreeD, Mode::TwoD { height_m: 0.5 }] {
            if let Ok(fix) = solve(&s, &cfg(mode)) {
                assert!(fix.position_m.iter().all(|v| v.is_finite()), "{fix:?}");
                assert!(fix.covariance_m2.iter().all(|v| v.is_finite()), "{fix:?}");
            }
        }
    }
}
