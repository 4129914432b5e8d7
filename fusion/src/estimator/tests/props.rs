//! Random input sequences: whatever arrives (random, extreme, non-finite,
//! missing, out of order), no estimator outputs NaN or a covariance that is
//! not positive definite, and none panics.

use nalgebra::Matrix2;
use proptest::prelude::*;

use super::runs::config;
use crate::estimator::{
    BeaconRangeSample, EncoderSample, GyroSample, Input, OdometrySample, RangeDifferenceSample,
    RangeSample, WheelGeometry, build, names,
};
use crate::tdoa::Fix;

fn number() -> BoxedStrategy<f64> {
    prop_oneof![
        4 => -10.0..10.0_f64,
        1 => -1e6..1e6_f64,
        1 => Just(0.0),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(1e300),
        1 => Just(-1e300),
        1 => Just(f64::MIN_POSITIVE),
        1 => any::<f64>(),
    ]
    .boxed()
}

fn maybe(n: BoxedStrategy<f64>) -> BoxedStrategy<Option<f64>> {
    prop_oneof![1 => Just(None), 3 => n.prop_map(Some)].boxed()
}

fn ticks() -> impl Strategy<Value = i64> {
    prop_oneof![4 => -5000..5000_i64, 1 => any::<i64>()]
}

/// An input at `t_s` with random content.
fn input(t_s: f64) -> BoxedStrategy<Input> {
    let geometry = (number(), number(), number()).prop_map(|(w, l, r)| WheelGeometry {
        wheel_base_m: w,
        left_m_per_tick: l,
        right_m_per_tick: r,
    });
    let nice_geometry = Just(super::sim::GEOMETRY);
    prop_oneof![
        (number(), number(), number()).prop_map(move |(x_m, y_m, theta_rad)| {
            Input::Odometry(OdometrySample {
                t_s,
                x_m,
                y_m,
                theta_rad,
            })
        }),
        (
            ticks(),
            ticks(),
            prop_oneof![3 => nice_geometry, 1 => geometry]
        )
            .prop_map(move |(left_ticks, right_ticks, geometry)| {
                Input::Encoders(EncoderSample {
                    t_s,
                    left_ticks,
                    right_ticks,
                    geometry,
                })
            }),
        number().prop_map(move |rate_rad_s| Input::Gyro(GyroSample { t_s, rate_rad_s })),
        (number(), number(), number(), number(), maybe(number())).prop_map(
            move |(x_m, y_m, a, b, heading_rad)| {
                Input::Fix(
                    Fix::from_position(t_s, x_m, y_m, Matrix2::new(a, b, b, a))
                        .with_heading(heading_rad),
                )
            }
        ),
        (
            maybe(number()),
            maybe(number()),
            maybe(number()),
            maybe(number()),
            maybe(number())
        )
            .prop_map(move |(lu, ru, li, ri, planned)| {
                Input::Range(RangeSample {
                    t_s,
                    left_ultrasonic_m: lu,
                    right_ultrasonic_m: ru,
                    left_ir_m: li,
                    right_ir_m: ri,
                    planned_heading_rad: planned,
                })
            }),
        (
            [number(), number(), number()],
            [number(), number(), number()],
            number(),
            number()
        )
            .prop_map(move |(a_m, b_m, d_m, sigma_m)| {
                Input::RangeDifference(RangeDifferenceSample {
                    a_t_s: None,
                    t_s,
                    a_m,
                    b_m,
                    d_m,
                    sigma_m,
                    clocks: None,
                    speed_rel_sigma: None,
                })
            }),
        ([number(), number(), number()], number(), number()).prop_map(
            move |(beacon_m, range_m, sigma_m)| {
                Input::BeaconRange(BeaconRangeSample {
                    t_s,
                    beacon_m,
                    range_m,
                    sigma_m,
                })
            }
        ),
    ]
    .boxed()
}

/// Mostly increasing times with some going back, some jumps and a few bad
/// values.
fn sequence() -> impl Strategy<Value = Vec<Input>> {
    let dt = prop_oneof![
        8 => 0.0..0.2_f64,
        2 => -0.5..0.0_f64,
        1 => 0.0..100.0_f64,
        1 => Just(f64::NAN),
    ];
    prop::collection::vec(dt, 1..80).prop_flat_map(|dts| {
        let mut t = 0.0;
        let times: Vec<f64> = dts
            .into_iter()
            .map(|d| {
                if d.is_nan() {
                    return f64::NAN;
                }
                t += d;
                t
            })
            .collect();
        times.into_iter().map(input).collect::<Vec<_>>()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn no_estimator_ever_outputs_nan_or_a_non_pd_covariance(inputs in sequence()) {
        for name in names() {
            let mut e = build(&config(name)).unwrap();
            for input in &inputs {
                let _ = e.handle(input);
                if let Some(p) = e.pose() {
                    prop_assert!(
                        [p.t_s, p.x_m, p.y_m, p.theta_rad].iter().all(|v| v.is_finite()),
                        "{name}: {p:?} after {input:?}"
                    );
                    prop_assert!(p.covariance.iter().all(|v| v.is_finite()), "{name}: {p:?}");
                    prop_assert!(p.covariance.cholesky().is_some(), "{name}: {p:?}");
                    prop_assert!((p.covariance - p.covariance.transpose()).abs().max() == 0.0);
                    prop_assert!(p.theta_rad > -std::f64::consts::PI);
                    prop_assert!(p.theta_rad <= std::f64::consts::PI);
                }
            }
        }
    }
}
