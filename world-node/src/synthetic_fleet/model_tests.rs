//! The made-up fleet drives its routes and solves fixes the central unit's
//! survey calibration can read.

use super::*;

fn warehouse_fleet(seed: u64) -> SyntheticFleet {
    let (site, _) = Site::builtin("warehouse").expect("built in");
    let ids: Vec<String> = site.robots.iter().take(16).map(|r| r.id.clone()).collect();
    SyntheticFleet::new(&site, &ids, 10e-6, 12.0, seed).expect("fleet")
}

#[test]
fn robots_start_where_the_site_puts_them_and_stay_on_their_routes() {
    let fleet = warehouse_fleet(1);
    let (site, _) = Site::builtin("warehouse").expect("built in");
    for i in 0..fleet.len() {
        let spec = &site.robots[i];
        let p0 = fleet.position(i, 0.0);
        assert!((p0[0] - spec.start[0]).hypot(p0[1] - spec.start[1]) < 0.5);
        let route = site.route(&spec.route).expect("route");
        for k in 0..200 {
            let p = fleet.position(i, k as f64 * 0.37);
            let (q, _) = route.nearest_point([p[0], p[1]]);
            assert!(
                (q[0] - p[0]).hypot(q[1] - p[1]) < 1e-6,
                "{} off its route",
                spec.id
            );
        }
        // It moves at the route's speed.
        let p1 = fleet.position(i, 0.5);
        let moved_m = (p1[0] - p0[0]).hypot(p1[1] - p0[1]);
        assert!(moved_m > 0.2 * route.speed_m_s && moved_m <= 0.5 * route.speed_m_s + 1e-9);
    }
}

#[test]
fn fixes_use_the_audible_fired_transmitters_and_leave_only_timing_noise() {
    let mut fleet = warehouse_fleet(1);
    let (site, _) = Site::builtin("warehouse").expect("built in");
    let every: Vec<u32> = site.transmitters.iter().map(|t| t.id).collect();
    let (mut fixes, mut worst_m) = (0, 0.0_f64);
    for i in 0..fleet.len() {
        for cycle in 0..20 {
            let t_s = cycle as f64 * 0.25;
            let Some(fix) = fleet.fix(i, t_s, Time::from_nanos(1), &every, 3) else {
                continue;
            };
            fixes += 1;
            assert!(fix.used.len() >= 4);
            assert_eq!(fix.used.len(), fix.residuals_m.len());
            assert_eq!(fix.survey_version, 3);
            assert_eq!(fix.quality, FixQuality::Good);
            for id in &fix.used {
                let tx = site.transmitter(*id).expect("a site transmitter");
                let receiver = [fix.x_m, fix.y_m, fix.z_m];
                assert!(site.line_of_sight(receiver, tx.position_m));
            }
            worst_m = fix.residuals_m.iter().fold(worst_m, |m, e| m.max(e.abs()));
            // What a least-squares fix leaves sums to zero (the common
            // offset's column).
            let sum: f64 = fix.residuals_m.iter().sum();
            assert!(sum.abs() < 1e-9, "residuals sum to {sum}");
        }
    }
    assert!(fixes > 16 * 20 * 9 / 10, "{fixes} fixes of {}", 16 * 20);
    // 10 us of timing noise is 3.4 mm of range: five sigmas at most.
    assert!(
        worst_m > 0.0 && worst_m < 0.02,
        "worst residual {worst_m} m"
    );
}

#[test]
fn too_few_fired_transmitters_give_no_fix_and_the_seed_sets_the_noise() {
    let mut fleet = warehouse_fleet(1);
    let (site, _) = Site::builtin("warehouse").expect("built in");
    let three: Vec<u32> = site.transmitters.iter().take(3).map(|t| t.id).collect();
    assert!(fleet.fix(0, 0.0, Time::from_nanos(1), &three, 0).is_none());
    assert!(fleet.fix(0, 0.0, Time::from_nanos(1), &[], 0).is_none());
    let every: Vec<u32> = site.transmitters.iter().map(|t| t.id).collect();
    let a = warehouse_fleet(5).fix(0, 1.0, Time::from_nanos(1), &every, 0);
    let b = warehouse_fleet(5).fix(0, 1.0, Time::from_nanos(1), &every, 0);
    let c = warehouse_fleet(6).fix(0, 1.0, Time::from_nanos(1), &every, 0);
    assert_eq!(a, b);
    assert_ne!(a.map(|f| f.residuals_m), c.map(|f| f.residuals_m));
}

#[test]
fn a_robot_the_site_does_not_have_is_refused() {
    let (site, _) = Site::builtin("warehouse").expect("built in");
    let e = SyntheticFleet::new(&site, &["nobody".to_string()], 1e-5, 12.0, 1)
        .expect_err("not in the site");
    assert!(e.to_string().contains("nobody"));
}
