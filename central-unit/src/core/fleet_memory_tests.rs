//! A fleet that appears and leaves leaves the central unit's per-robot
//! tables as small as it found them.

use super::*;
use crate::survey_calibration::Applied;
use crate::survey_calibration::tests::{Noise, fix_at, places, true_offsets};
use ickon_proto::msg::robot::{PoseStatus, RobotSummary};
use ickon_proto::site::RobotSpec;

/// Robots of the fleet: a thousand, as many as a debug test drives in
/// half a minute on a loaded machine.
const ROBOTS: usize = 1_000;
/// Summaries each robot sends while it is up: past the fleet check's
/// window, so that windows fill and fixes are learnt.
const ROUNDS: usize = 25;

fn summary(stamp: Time, at: [f64; 2], fix: Option<ickon_proto::msg::robot::Fix>) -> RobotSummary {
    RobotSummary {
        seq: 0,
        stamp,
        x_m: at[0],
        y_m: at[1],
        theta_rad: 0.0,
        covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
        estimator: "tdoa-ekf".into(),
        fix_seq: 0,
        status: PoseStatus::Tracking,
        vx_m_s: 0.0,
        vy_m_s: 0.0,
        velocity_span_s: 0.0,
        fixes_solved: u32::from(fix.is_some()),
        fixes: fix.into_iter().collect(),
    }
}

#[test]
fn a_fleet_that_comes_and_goes_leaves_the_per_robot_tables_as_it_found_them() {
    let mut site = Site::default_site();
    let template = site.robots[0].clone();
    site.robots = (0..ROBOTS)
        .map(|i| RobotSpec {
            id: format!("f{i:04}"),
            ..template.clone()
        })
        .collect();
    let ids: Vec<String> = site.robots.iter().map(|r| r.id.clone()).collect();
    let mut noise = Noise(0x5eed_f1ee_7000_0001);
    let at = places(ROBOTS, &mut noise);
    let truth = true_offsets(&site, true);
    let mut c = CentralCore::new(
        site.clone(),
        String::new(),
        CentralConfig::default(),
        Time(0),
    )
    .expect("a core");
    let idle = c.robot_footprint();
    assert_eq!(idle, RobotFootprint::default());

    let mut now = Time(0);
    for id in &ids {
        c.handle(
            now,
            Event::RobotAlive {
                id: id.clone(),
                up: true,
            },
        );
    }
    for _ in 0..ROUNDS {
        now = now + Duration::from_millis(500);
        while c.next_wake() <= now {
            let wake = c.next_wake();
            c.handle(wake, Event::Tick);
        }
        for (id, place) in ids.iter().zip(&at) {
            let fix = fix_at(&site, *place, &truth, &Applied::new(), 0, &mut noise);
            let s = summary(now, *place, fix);
            c.handle(
                now,
                Event::Summary {
                    robot: id.clone(),
                    summary: Box::new(s),
                },
            );
        }
    }
    let busy = c.robot_footprint();
    // The fleet filled every table (else the test below proves nothing).
    assert_eq!(busy.trackers, ROBOTS);
    assert!(busy.fix_reports >= ROBOTS, "{busy:?}");
    // Robots at places too few transmitters reach solve no fix, and some
    // fixes are not read (too few signals left): most robots are checked.
    assert!(busy.fix_shares > ROBOTS / 2, "{busy:?}");
    assert!(busy.checked > ROBOTS / 2, "{busy:?}");
    assert!(busy.fixes_held >= ROBOTS * 10, "{busy:?}");
    let learnt = c.survey().expect("survey on").calibration().fixes_taken();
    assert!(learnt > 0);

    for id in &ids {
        c.handle(
            now,
            Event::RobotAlive {
                id: id.clone(),
                up: false,
            },
        );
    }
    let gone = c.robot_footprint();
    // Down robots stay listed for the admin (the site's robots, no more);
    // everything that grew with their messages is gone.
    assert_eq!(
        gone,
        RobotFootprint {
            trackers: ROBOTS,
            ..idle
        }
    );
    // What they held for the fleet check, agreeing, was learnt from (a
    // robot still short of a window was not judged: its fixes are let go).
    assert!(c.survey().expect("survey on").calibration().fixes_taken() > learnt);
    let counts = c.status_summary(now).robot_counts;
    assert_eq!(counts.down, ROBOTS as u64, "{counts:?}");
}
