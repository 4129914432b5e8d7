use ickon_proto::msg::admin::RobotHealth;

use super::*;

fn robot(k: usize, up: bool, fixes_per_s: f64) -> RobotHealth {
    RobotHealth {
        id: format!("r{k:05}"),
        up,
        fixes_per_s,
        estimator: "tdoa-ekf".into(),
        pose_valid: k.is_multiple_of(2),
        x_m: 0.0,
        y_m: 0.0,
        theta_rad: 0.0,
        stale: String::new(),
        fixes_over_rate: 0,
        survey_check: String::new(),
        fixes_quarantined: 0,
        survey_misfit_m: -1.0,
        survey_bound_m: -1.0,
        receivers: String::new(),
        summaries_dropped: 0,
    }
}

/// Of a fleet of 10,000, the status lists the worst few in id order and
/// counts them all.
#[test]
fn the_worst_of_a_large_fleet_are_listed_and_all_counted() {
    let fleet = (0..10_000).map(|k| {
        let mut r = robot(k, k != 9_000, 3.0 + (k % 7) as f64);
        if k == 4_000 {
            r.stale = "no summary for 2.0 s".into();
        }
        if k == 123 {
            r.fixes_per_s = 0.5;
        }
        r
    });
    let (listed, counts, posed) = worst(fleet, 3);
    let ids: Vec<&str> = listed.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(ids, ["r00123", "r04000", "r09000"]);
    assert_eq!(
        counts,
        RobotCounts {
            up: 9_998,
            stale: 1,
            down: 1
        }
    );
    assert_eq!(posed, 5_000);
}

/// A fleet smaller than the bound is listed whole, in id order.
#[test]
fn a_small_fleet_is_listed_whole() {
    let fleet = [
        robot(2, true, 1.0),
        robot(0, false, 4.0),
        robot(1, true, 4.0),
    ];
    let (listed, counts, posed) = worst(fleet, 100);
    let ids: Vec<&str> = listed.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(ids, ["r00000", "r00001", "r00002"]);
    assert_eq!((counts.up, counts.down), (2, 1));
    assert_eq!(posed, 2);
    assert!(worst([robot(0, true, 1.0)], 0).0.is_empty());
}
