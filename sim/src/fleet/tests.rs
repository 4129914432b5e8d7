use super::*;
use ickon_central::occupancy::FiringConfig;

fn config(robots: usize, occupancy: bool) -> FleetConfig {
    FleetConfig {
        robots,
        duration_s: 8.0,
        warm_up_s: 3.0,
        profile: NoiseProfile::paper(),
        seed: 1,
        estimator: "tdoa-ekf".into(),
        central: CentralConfig {
            firing: FiringConfig {
                occupancy,
                ..FiringConfig::default()
            },
            ..CentralConfig::default()
        },
        filter: FilterOptions::default(),
        transmitter_faults: Vec::new(),
    }
}

#[test]
fn firing_only_where_the_robots_are_makes_cycles_shorter_and_still_fixes_every_robot() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let all = run_fleet(&site, &config(2, false)).unwrap();
    let near = run_fleet(&site, &config(2, true)).unwrap();
    assert_eq!(all.mean_firing, all.transmitters as f64);
    assert!(near.mean_firing < 0.6 * all.transmitters as f64, "{near:?}");
    assert!(
        near.cycles_per_s > 1.5 * all.cycles_per_s,
        "{near:?} {all:?}"
    );
    for r in &near.robots {
        assert!(
            r.fixes_per_s > 1.5 * all.robots[0].fixes_per_s.min(all.robots[1].fixes_per_s),
            "{r:?}"
        );
        assert!(r.mean_err_mm < 300.0, "{r:?}");
        assert!(r.collisions.lost_share() < 0.02, "{r:?}");
    }
}

#[test]
fn a_fleet_larger_than_the_site_is_refused() {
    let site = Site::default_site();
    let n = site.robots.len();
    assert!(matches!(
        run_fleet(&site, &config(n + 1, true)),
        Err(RunError::FleetSize { .. })
    ));
    assert!(matches!(
        run_fleet(&site, &config(0, true)),
        Err(RunError::FleetSize { .. })
    ));
}

#[test]
fn the_fleets_fixes_teach_the_central_unit_and_its_calibration_reaches_every_msu() {
    let site = Site::default_site();
    let on = run_fleet(&site, &config(2, true)).unwrap();
    assert!(on.survey_fixes_taken.unwrap() > 10, "{on:?}");
    for r in &on.robots {
        assert!(r.calibrated_fixes > 0, "{r:?}");
    }
    let mut off_config = config(2, true);
    off_config.central.survey = None;
    let off = run_fleet(&site, &off_config).unwrap();
    assert_eq!(off.survey_fixes_taken, None);
    assert!(
        off.robots.iter().all(|r| r.calibrated_fixes == 0),
        "{off:?}"
    );
}
