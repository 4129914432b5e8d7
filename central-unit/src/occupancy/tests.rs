use super::*;
use ickon_proto::site::Site;

fn table(site: &Site) -> SpacingTable {
    let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    SpacingTable::new(site, &cells)
}

fn pose(x_m: f64, y_m: f64, sigma_m: f64) -> RobotPose {
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

#[test]
fn a_tracked_robot_fires_only_what_it_can_hear_and_the_cycle_is_short() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let t = table(&site);
    // In the middle of aisle 1.
    let p = pose(20.0, 1.5, 0.05);
    let (packing, _) = firing_plan(&t, &[RobotView::Seen(&p, NOW)], &on(), NOW, CYCLE).unwrap();
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
            &[RobotView::Seen(&fresh, NOW), RobotView::New],
            &on(),
            NOW,
            CYCLE
        )
        .is_none()
    );
    assert!(firing_plan(&t, &[], &on(), NOW, CYCLE).is_none());
    let off = FiringConfig::default();
    assert!(firing_plan(&t, &[RobotView::Seen(&fresh, NOW)], &off, NOW, CYCLE).is_none());

    let tracked = firing_plan(&t, &[RobotView::Seen(&fresh, NOW)], &on(), NOW, CYCLE)
        .unwrap()
        .0
        .offsets
        .len();
    let long_ago = Time(NOW.as_nanos() - 5_000_000_000);
    let stale = firing_plan(&t, &[RobotView::Seen(&fresh, long_ago)], &on(), NOW, CYCLE)
        .unwrap()
        .0
        .offsets
        .len();
    let lost_pose = pose(20.0, 1.5, 3.0);
    let lost = firing_plan(&t, &[RobotView::Seen(&lost_pose, NOW)], &on(), NOW, CYCLE)
        .unwrap()
        .0
        .offsets
        .len();
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
    assert!(firing_plan(&t, &[RobotView::Seen(&nan, NOW)], &on(), NOW, CYCLE).is_none());
    let mut bad_cov = pose(4.0, 1.0, 0.05);
    bad_cov.covariance[0] = f64::INFINITY;
    assert!(largest_sigma_m(&bad_cov).is_infinite());
    // An infinite sigma is a lost robot: a sweep, not a panic.
    assert!(firing_plan(&t, &[RobotView::Seen(&bad_cov, NOW)], &on(), NOW, CYCLE).is_some());
    // Far off the floor: a sweep of nothing there, so everything fires.
    let away = pose(1e6, -1e6, 0.05);
    assert!(firing_plan(&t, &[RobotView::Seen(&away, NOW)], &on(), NOW, CYCLE).is_none());
    // A pose from the future counts as fresh.
    let fresh = pose(4.0, 1.0, 0.05);
    let future = Time(NOW.as_nanos() + 3_600_000_000_000);
    assert!(firing_plan(&t, &[RobotView::Seen(&fresh, future)], &on(), NOW, CYCLE).is_some());
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
