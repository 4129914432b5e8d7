//! A robot that ranges the site's beacons instead of timing them: the
//! distances it reports are checked, fused, and confirm its pose.

use super::*;
use crate::beacons::{BeaconDistance, BeaconDistances};
use crate::events::{Event, InputKind, Output};
use ickon_fusion::estimator::tdoa_ekf::TdoaEkfParams;
use ickon_fusion::estimator::{EstimatorConfig, build};

const HEIGHT_M: f64 = 0.3;
const BEACONS: [(u32, [f64; 3]); 4] = [
    (2, [0.0, 0.0, 3.0]),
    (3, [6.0, 0.0, 3.0]),
    (4, [6.0, 6.0, 3.0]),
    (5, [0.0, 6.0, 3.0]),
];

fn core(estimator: &str) -> MsuCore {
    let config_of = match estimator {
        "tdoa-ekf" => EstimatorConfig::TdoaEkf(TdoaEkfParams {
            receiver_height_m: HEIGHT_M,
            initial_pose: None,
            ..TdoaEkfParams::default()
        }),
        other => EstimatorConfig::default_for(other).expect("known estimator"),
    };
    MsuCore::new(
        super::tests::config_with(HEIGHT_M, &BEACONS, [[0.0, 0.0], [6.0, 6.0]]),
        build(&config_of).expect("valid"),
    )
}

fn reading(k: i64, at: [f64; 2], tamper: impl Fn(&mut Vec<BeaconDistance>)) -> Event {
    let mut distances: Vec<BeaconDistance> = BEACONS
        .iter()
        .map(|(id, b)| BeaconDistance {
            tx_id: *id,
            distance_m: ((at[0] - b[0]).powi(2)
                + (at[1] - b[1]).powi(2)
                + (HEIGHT_M - b[2]).powi(2))
            .sqrt(),
            sigma_m: 0.02,
        })
        .collect();
    tamper(&mut distances);
    Event::BeaconDistances(BeaconDistances {
        stamp: Time::from_nanos(1_000_000_000 + k * 125_000_000),
        distances,
    })
}

#[test]
fn a_robot_ranging_four_beacons_is_found_without_a_start_pose() {
    let mut core = core("tdoa-ekf");
    let at = [2.0, 4.5];
    let mut last = None;
    for k in 0..40 {
        for out in core.handle(reading(k, at, |_| {})) {
            match out {
                Output::Pose(p) => last = Some(p),
                other => panic!("unexpected {other:?}"),
            }
        }
    }
    let p = last.expect("a pose");
    assert!((p.x_m - at[0]).hypot(p.y_m - at[1]) < 0.05, "{p:?}");
    assert_eq!(
        core.staleness(p.stamp).0,
        PoseStatus::Localising,
        "heading still unknown: not confirmed"
    );
}

#[test]
fn the_seed_filters_get_positions_from_the_ranges() {
    let mut core = core("msu-raw");
    let at = [4.0, 1.0];
    let mut last = None;
    for k in 0..40 {
        for out in core.handle(reading(k, at, |_| {})) {
            if let Output::Pose(p) = out {
                last = Some(p);
            }
        }
    }
    let p = last.expect("a pose from trilaterated fixes");
    assert!((p.x_m - at[0]).hypot(p.y_m - at[1]) < 0.05, "{p:?}");
}

#[test]
fn distances_the_site_cannot_explain_are_refused_and_the_rest_used() {
    let mut core = core("tdoa-ekf");
    let at = [3.0, 3.0];
    for k in 0..20 {
        core.handle(reading(k, at, |_| {}));
    }
    type Tamper = fn(&mut Vec<BeaconDistance>);
    let cases: [(&str, Tamper); 6] = [
        ("not a transmitter of this site", |d| d[0].tx_id = 99),
        ("not a positive number", |d| d[1].distance_m = 0.0),
        ("not a positive number", |d| d[1].distance_m = f64::NAN),
        ("shorter than the beacon's", |d| d[2].distance_m = 1.0),
        ("farther than the site allows", |d| d[3].distance_m = 400.0),
        ("sigma", |d| d[3].sigma_m = -1.0),
    ];
    for (k, (why, tamper)) in cases.into_iter().enumerate() {
        let out = core.handle(reading(20 + k as i64, at, tamper));
        let refused: Vec<_> = out
            .iter()
            .filter_map(|o| match o {
                Output::Refused { input, error } => Some((*input, error.to_string())),
                _ => None,
            })
            .collect();
        assert_eq!(refused.len(), 1, "{why}: {out:?}");
        assert_eq!(refused[0].0, InputKind::BeaconDistances);
        assert!(
            refused[0].1.starts_with("1 of 4 distance(s) refused"),
            "{}",
            refused[0].1
        );
        assert!(refused[0].1.contains(why), "{why}: {}", refused[0].1);
        let pose = out.iter().find_map(|o| match o {
            Output::Pose(p) => Some(p.clone()),
            _ => None,
        });
        let p = pose.expect("the good distances still move the pose");
        assert!((p.x_m - at[0]).hypot(p.y_m - at[1]) < 0.05, "{why}: {p:?}");
    }
}

#[test]
fn a_flood_of_distances_in_one_reading_is_refused_whole() {
    let mut core = core("tdoa-ekf");
    let out = core.handle(reading(0, [1.0, 1.0], |d| {
        let one = d[0];
        d.resize(1000, one);
    }));
    assert!(
        matches!(out.as_slice(), [Output::Refused { input: InputKind::BeaconDistances, error }] if error.to_string().contains("more than 16")),
        "{out:?}"
    );
}

#[test]
fn a_kits_own_positions_place_a_seed_filter_and_absurd_ones_are_refused() {
    use crate::beacons::KitPosition;
    let mut core = core("msu-raw");
    let at = [4.0, 2.0];
    let kit = |k: i64, x_m: f64, y_m: f64, sigma_m: f64| {
        Event::KitPosition(KitPosition {
            stamp: Time::from_nanos(1_000_000_000 + k * 125_000_000),
            x_m,
            y_m,
            sigma_m,
        })
    };
    let mut last = None;
    for k in 0..40 {
        for out in core.handle(kit(k, at[0], at[1], 0.02)) {
            match out {
                Output::Pose(p) => last = Some(p),
                other => panic!("unexpected {other:?}"),
            }
        }
    }
    let p = last.expect("a pose from the kit's positions");
    assert!((p.x_m - at[0]).hypot(p.y_m - at[1]) < 0.05, "{p:?}");
    let cases = [
        ("off the site's floor", kit(40, 60.0, 2.0, 0.02)),
        ("not a position", kit(41, f64::NAN, 2.0, 0.02)),
        ("not a positive number", kit(42, 4.0, 2.0, 0.0)),
    ];
    for (why, event) in cases {
        let out = core.handle(event);
        assert!(
            out.iter().any(|o| matches!(o, Output::Refused { input: InputKind::KitPosition, error } if error.to_string().contains(why))),
            "{why}: {out:?}"
        );
    }
}
