use super::*;
use ickon_proto::site::Site;

/// The spacing table of every cell of `site`.
pub(crate) fn table(site: &Site) -> SpacingTable {
    let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    SpacingTable::new(site, &cells)
}

/// A tracked pose at `(x_m, y_m)` with `sigma_m` on each axis.
pub(crate) fn pose(x_m: f64, y_m: f64, sigma_m: f64) -> RobotPose {
    let v = sigma_m * sigma_m;
    RobotPose {
        stamp: Time(0),
        x_m,
        y_m,
        theta_rad: 0.0,
        covariance: [v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, 0.01],
        estimator: "tdoa-ekf".into(),
        fix_seq: 1,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    }
}

fn on() -> FiringConfig {
    FiringConfig {
        occupancy: true,
        ..FiringConfig::default()
    }
}

const NOW: Time = Time(10_000_000_000);
const CYCLE: Duration = Duration::from_millis(100);

/// The plan at `NOW` for one robot last seen at `p`, received at
/// `received`, no velocity known, occupancy on.
fn plan(t: &SpacingTable, p: &RobotPose, received: Time) -> Option<(Packing, NeedMatrix)> {
    firing_plan(t, &[RobotView::Seen(p, received, None)], &on(), NOW, CYCLE)
}

#[test]
fn a_tracked_robot_fires_only_what_it_can_hear_and_the_cycle_is_short() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let t = table(&site);
    // In the middle of aisle 1.
    let p = pose(20.0, 1.5, 0.05);
    let (packing, _) = plan(&t, &p, NOW).unwrap();
    let n = packing.offsets.len();
    // Four or more: enough for a 2D fix with the height known, and a redundant one.
    assert!((4..20).contains(&n), "{n} transmitters fire");
    let at = [20.0, 1.5, site.msu.height_m];
    for &(i, _) in &packing.offsets {
        let tx = t.position(i);
        let d =
            ((tx[0] - at[0]).powi(2) + (tx[1] - at[1]).powi(2) + (tx[2] - at[2]).powi(2)).sqrt();
        assert!(
            d < on().fire_range_m + 2.0,
            "transmitter {} at {d} m",
            t.tx_ids[i]
        );
    }
    assert!(
        packing.period.as_secs_f64() < t.pack_all().period.as_secs_f64() / 2.0,
        "{:?}",
        packing.period
    );
}

#[test]
fn new_robots_make_everything_fire_and_stale_or_lost_ones_get_a_sweep() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let t = table(&site);
    let fresh = pose(20.0, 1.5, 0.05);
    assert!(firing_plan(&t, &[RobotView::New], &on(), NOW, CYCLE).is_none());
    assert!(
        firing_plan(
            &t,
            &[RobotView::Seen(&fresh, NOW, None), RobotView::New],
            &on(),
            NOW,
            CYCLE
        )
        .is_none()
    );
    assert!(firing_plan(&t, &[], &on(), NOW, CYCLE).is_none());
    let off = FiringConfig::default();
    assert!(firing_plan(&t, &[RobotView::Seen(&fresh, NOW, None)], &off, NOW, CYCLE).is_none());

    let firing = |p: &RobotPose, received: Time| plan(&t, p, received).unwrap().0.offsets.len();
    let tracked = firing(&fresh, NOW);
    let stale = firing(&fresh, Time(NOW.as_nanos() - 5_000_000_000));
    let lost = firing(&pose(20.0, 1.5, 3.0), NOW);
    assert!(
        stale > tracked && lost > tracked,
        "{tracked} {stale} {lost}"
    );
}

#[test]
fn garbage_poses_make_everything_fire() {
    let (site, _) = Site::builtin("lab").unwrap();
    let t = table(&site);
    let nan = pose(f64::NAN, 1.0, 0.05);
    assert!(plan(&t, &nan, NOW).is_none());
    let mut bad_cov = pose(4.0, 1.0, 0.05);
    bad_cov.covariance[0] = f64::INFINITY;
    assert!(largest_sigma_m(&bad_cov).is_infinite());
    // An infinite sigma is a lost robot: a sweep, not a panic.
    assert!(plan(&t, &bad_cov, NOW).is_some());
    // Far off the floor: a sweep of nothing there, so everything fires.
    let away = pose(1e6, -1e6, 0.05);
    assert!(plan(&t, &away, NOW).is_none());
    // A pose from the future counts as fresh.
    let fresh = pose(4.0, 1.0, 0.05);
    let future = Time(NOW.as_nanos() + 3_600_000_000_000);
    assert!(plan(&t, &fresh, future).is_some());
}

#[test]
fn largest_sigma_is_the_major_axis() {
    let mut p = pose(0.0, 0.0, 0.0);
    p.covariance[0] = 4.0;
    p.covariance[4] = 1.0;
    assert!((largest_sigma_m(&p) - 2.0).abs() < 1e-12);
    p.covariance[1] = 2.0;
    p.covariance[3] = 2.0;
    assert!((largest_sigma_m(&p) - 5f64.sqrt()).abs() < 1e-12);
}

/// A robot whose acceleration stays under `max_accel_m_s2` (turns
/// included) never leaves the disc its velocity predicts, during the whole
/// next cycle; and that disc is smaller than the top-speed one.
#[test]
fn the_predicted_region_holds_a_robot_within_its_acceleration_and_is_smaller() {
    let config = on();
    let a = config.max_accel_m_s2 / 2f64.sqrt();
    let (w1, w2, phase) = (1.3, 1.7, 0.4);
    // Acceleration a (cos(w1 t + phase), sin(w2 t)): at most max_accel; speed
    // at most about 1.03 m/s.
    let at = |t: f64| {
        [
            -a * (w1 * t + phase).cos() / (w1 * w1),
            -a * (w2 * t).sin() / (w2 * w2),
        ]
    };
    let (age, cycle) = (Duration::from_millis(50), Duration::from_millis(180));
    let (mut predicted_sum, mut anywhere_sum, mut checks) = (0.0, 0.0, 0);
    for k in 0..3_000 {
        let t = k as f64 * 0.02;
        let xy = at(t);
        // What a summary reports: the mean velocity over the last half
        // second of poses.
        if t < 0.5 {
            continue;
        }
        let back = at(t - 0.5);
        let v = crate::velocity::Velocity {
            v_m_s: [(xy[0] - back[0]) / 0.5, (xy[1] - back[1]) / 0.5],
            span_s: 0.5,
        };
        let (centre, drift) = reach(xy, 0.0, Some(v), age, cycle, &config);
        for j in 0..=20 {
            let s = t + age.as_secs_f64() + cycle.as_secs_f64() * f64::from(j) / 20.0;
            let q = at(s);
            let off = (q[0] - centre[0]).hypot(q[1] - centre[1]);
            assert!(
                off <= drift + 1e-9,
                "t {t:.2} s + {s:.3}: {off} m > {drift} m"
            );
        }
        predicted_sum += drift;
        anywhere_sum += config.max_speed_m_s * (age + cycle).as_secs_f64();
        checks += 1;
    }
    assert!(checks > 2_900, "{checks}");
    assert!(
        predicted_sum < 0.8 * anywhere_sum,
        "{predicted_sum} {anywhere_sum}"
    );
}

#[test]
fn a_velocity_beyond_the_top_speed_is_not_believed() {
    let config = on();
    let (age, cycle) = (Duration::from_millis(50), Duration::from_millis(180));
    let fast = crate::velocity::Velocity {
        v_m_s: [3.0, 0.0],
        span_s: 0.5,
    };
    let (centre, drift) = reach([1.0, 2.0], 0.02, Some(fast), age, cycle, &config);
    assert_eq!(centre, [1.0, 2.0]);
    assert!((drift - config.max_speed_m_s * 0.23).abs() < 1e-12);
    // Not a number: the same.
    let nan = crate::velocity::Velocity {
        v_m_s: [f64::NAN, 0.0],
        span_s: 0.5,
    };
    assert_eq!(
        reach([1.0, 2.0], 0.02, Some(nan), age, cycle, &config).0,
        [1.0, 2.0]
    );
}

/// A moving robot's transmitters are those ahead of it: the plan with its
/// velocity fires no more than the one without, and a shorter or equal cycle.
#[test]
fn a_moving_robot_with_a_velocity_gets_a_plan_no_larger() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let t = table(&site);
    let p = pose(20.0, 1.5, 0.02);
    let v = crate::velocity::Velocity {
        v_m_s: [1.0, 0.0],
        span_s: 0.5,
    };
    let received = Time(NOW.as_nanos() - 50_000_000);
    let cycle = Duration::from_millis(180);
    let with = firing_plan(
        &t,
        &[RobotView::Seen(&p, received, Some(v))],
        &on(),
        NOW,
        cycle,
    )
    .unwrap()
    .0;
    let without = firing_plan(
        &t,
        &[RobotView::Seen(&p, received, None)],
        &on(),
        NOW,
        cycle,
    )
    .unwrap()
    .0;
    assert!(with.offsets.len() <= without.offsets.len());
    assert!(
        with.period <= without.period,
        "{:?} {:?}",
        with.period,
        without.period
    );
}

/// A region smaller than the floor grid (a still, well-known robot with no
/// margin) takes the nearest sample point: a handful of transmitters, not
/// a sweep of the whole area.
#[test]
fn a_region_between_sample_points_takes_the_nearest_one() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let t = table(&site);
    let tight = FiringConfig {
        margin_m: 0.0,
        max_speed_m_s: 0.0,
        ..on()
    };
    // Between the grid's points, known to a millimetre.
    let p = pose(20.11, 1.61, 0.001);
    let (packing, _) =
        firing_plan(&t, &[RobotView::Seen(&p, NOW, None)], &tight, NOW, CYCLE).unwrap();
    let usual = plan(&t, &p, NOW).unwrap().0;
    assert!(
        (4..=usual.offsets.len()).contains(&packing.offsets.len()),
        "{} of usual {}",
        packing.offsets.len(),
        usual.offsets.len()
    );
}
