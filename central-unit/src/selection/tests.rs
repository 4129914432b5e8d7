use super::*;
use crate::occupancy::tests::{pose, table};
use crate::occupancy::{FiringConfig, RobotView, plan};
use crate::spacing::Reverb;
use ickon_proto::msg::robot::RobotPose;
use ickon_proto::site::Site;

fn hall() -> (Site, SpacingTable) {
    let (site, _) = Site::builtin("hall").unwrap();
    let table = table(&site);
    (site, table)
}

fn needs_on() -> FiringConfig {
    FiringConfig {
        occupancy: true,
        needs: Some(NeedsConfig::default()),
        reverb: Some(Reverb::default()),
        ..FiringConfig::default()
    }
}

const NOW: Time = Time(10_000_000_000);
const CYCLE: Duration = Duration::from_millis(100);

fn plan_for(
    t: &SpacingTable,
    poses: &[RobotPose],
    config: &FiringConfig,
) -> Option<crate::occupancy::Plan> {
    let views: Vec<RobotView> = poses
        .iter()
        .map(|p| RobotView::Seen(p, NOW, None))
        .collect();
    plan(t, &views, config, NOW, CYCLE, &FiringHistory::default())
}

#[test]
fn one_robot_in_an_open_hall_gets_a_few_transmitters_in_good_geometry() {
    let (_, t) = hall();
    let p = pose(7.3, 12.1, 0.02);
    let needed = plan_for(&t, std::slice::from_ref(&p), &needs_on()).unwrap();
    let everything = plan_for(
        &t,
        std::slice::from_ref(&p),
        &FiringConfig {
            occupancy: true,
            ..FiringConfig::default()
        },
    )
    .unwrap();
    let n = needed.packing.offsets.len();
    assert!((4..=6).contains(&n), "{n} fire");
    assert!(everything.packing.offsets.len() >= 3 * n);
    assert_eq!(needed.hdops.len(), 1);
    assert!(needed.hdops[0] <= 3.0, "hdop {}", needed.hdops[0]);
    assert!(
        needed.packing.period.as_secs_f64() < everything.packing.period.as_secs_f64() / 3.0,
        "{:?} against {:?}",
        needed.packing.period,
        everything.packing.period
    );
}

#[test]
fn a_transmitter_serves_several_robots_and_each_gets_its_signals() {
    let (site, t) = hall();
    // Sixteen robots, one per cell, as `--robots 16` spreads them.
    let poses: Vec<RobotPose> = site.robots[..16]
        .iter()
        .map(|r| pose(r.start[0], r.start[1], 0.02))
        .collect();
    let config = needs_on();
    let p = plan_for(&t, &poses, &config).unwrap();
    assert_eq!(p.hdops.len(), 16);
    for (r, h) in p.hdops.iter().enumerate() {
        assert!(*h <= 3.0, "robot {r}: hdop {h}");
    }
    let fired: Vec<usize> = p.packing.offsets.iter().map(|o| o.0).collect();
    for q in &poses {
        let at = [q.x_m, q.y_m, site.msu.height_m];
        let heard = fired
            .iter()
            .filter(|&&k| {
                let tx = t.position(k);
                let d =
                    ((tx[0] - at[0]).powi(2) + (tx[1] - at[1]).powi(2) + (tx[2] - at[2]).powi(2))
                        .sqrt();
                d <= config.fire_range_m
            })
            .count();
        assert!(heard >= 4, "({}, {}) hears {heard}", q.x_m, q.y_m);
    }
    // Shared: fewer than four of its own per robot.
    assert!(fired.len() < 4 * 16, "{} fire", fired.len());
}

#[test]
fn every_transmitter_a_robot_can_hear_fires_within_the_rotation() {
    let (_, t) = hall();
    let p = pose(10.0, 10.0, 0.02);
    let config = needs_on();
    let rotation = config.needs.unwrap().rotation;
    let mut history = FiringHistory::default();
    let mut fired_at: Vec<Vec<Time>> = vec![Vec::new(); t.tx_ids.len()];
    let mut now = NOW;
    let end = NOW + Duration::from_secs_f64(5.0);
    while now < end {
        // The robot's summary comes every half second.
        let period_ns = ickon_proto::msg::robot::SUMMARY_PERIOD.as_nanos();
        let received = Time(NOW.0 + (now.0 - NOW.0) / period_ns * period_ns);
        let views = [RobotView::Seen(&p, received, None)];
        let planned = plan(&t, &views, &config, now, CYCLE, &history).unwrap();
        history.note(planned.packing.offsets.iter().map(|o| o.0), now);
        for &(k, _) in &planned.packing.offsets {
            fired_at[k].push(now);
        }
        now = now + planned.packing.period.max(Duration::from_millis(1));
    }
    // Those in range from the whole region (a region 0.5 m across).
    let candidates = heard_within(&t, [10.0, 10.0], config.fire_range_m - 1.0);
    assert!(candidates.len() > 8, "{} candidates", candidates.len());
    for k in candidates {
        let times = &fired_at[k];
        assert!(!times.is_empty(), "{} never fired", t.tx_ids[k]);
        // After the first round, never silent much longer than the rotation.
        for w in times.windows(2) {
            let gap = w[1].since(w[0]);
            assert!(
                gap <= rotation + Duration::from_millis(400),
                "{} silent for {gap:?}",
                t.tx_ids[k]
            );
        }
    }
}

/// Transmitters within `range_m` of the sample point nearest `at`.
fn heard_within(t: &SpacingTable, at: [f64; 2], range_m: f64) -> Vec<usize> {
    let (p, _) = t.nearest_point(at).unwrap();
    t.heard_at(p)
        .iter()
        .filter(|&&(_, d)| d <= range_m)
        .map(|&(k, _)| k)
        .collect()
}

#[test]
fn an_uncertain_stale_or_new_robot_still_gets_its_whole_neighbourhood() {
    let (_, t) = hall();
    let config = needs_on();
    let sure = pose(10.0, 10.0, 0.02);
    let one = plan_for(&t, std::slice::from_ref(&sure), &config).unwrap();
    // Lost (sigma over a metre): a sweep.
    let lost = pose(10.0, 10.0, 2.0);
    let swept = plan_for(&t, &[sure.clone(), lost], &config).unwrap();
    assert!(swept.packing.offsets.len() > 4 * one.packing.offsets.len());
    // Stale: a sweep too.
    let stale_views = [
        RobotView::Seen(&sure, NOW, None),
        RobotView::Seen(&sure, Time(NOW.as_nanos() - 5_000_000_000), None),
    ];
    let stale = plan(
        &t,
        &stale_views,
        &config,
        NOW,
        CYCLE,
        &FiringHistory::default(),
    )
    .unwrap();
    assert!(stale.packing.offsets.len() > 4 * one.packing.offsets.len());
    // New: everything.
    let new_views = [RobotView::Seen(&sure, NOW, None), RobotView::New];
    assert!(
        plan(
            &t,
            &new_views,
            &config,
            NOW,
            CYCLE,
            &FiringHistory::default()
        )
        .is_none()
    );
}

#[test]
fn a_pose_off_the_site_changes_nothing_for_the_others() {
    let (_, t) = hall();
    let config = needs_on();
    let sure = pose(10.0, 10.0, 0.02);
    let alone = plan_for(&t, std::slice::from_ref(&sure), &config).unwrap();
    for (x, y) in [(21.0, 10.0), (-0.5, -0.5), (10.0, 30.0), (1e9, -1e9)] {
        for sigma in [0.02, 3.0] {
            let off = pose(x, y, sigma);
            let with = plan_for(&t, &[sure.clone(), off], &config).unwrap();
            assert_eq!(with.packing, alone.packing, "({x}, {y}) sigma {sigma}");
        }
    }
}

#[test]
fn reverberation_spacing_is_shorter_than_the_guard_time_and_grows_with_the_decay_time() {
    let (site, t) = hall();
    let p = pose(7.3, 12.1, 0.02);
    let guard = FiringConfig {
        reverb: None,
        ..needs_on()
    };
    let room = plan_for(&t, std::slice::from_ref(&p), &needs_on()).unwrap();
    let fixed = plan_for(&t, std::slice::from_ref(&p), &guard).unwrap();
    assert!(room.packing.period < fixed.packing.period);
    // A slot is never shorter than the burst and the decoder window.
    for w in room.packing.offsets.windows(2) {
        let gap = w[1].1 - w[0].1;
        assert!(
            gap.as_secs_f64() >= site.burst_length_s + site.decoder_window_s,
            "{gap:?}"
        );
    }
    // A room that rings louder and ten times longer: the tails now reach
    // the next bursts, and the plan must wait them out.
    let slow = FiringConfig {
        reverb: Some(Reverb {
            decay_db_per_ms: 0.3,
            tail_db: 0.0,
            ..Reverb::default()
        }),
        ..needs_on()
    };
    let slower = plan_for(&t, std::slice::from_ref(&p), &slow).unwrap();
    assert!(slower.packing.period > room.packing.period);
    // A model that is not a number spaces bursts a second apart, never panics.
    let broken = Reverb {
        decay_db_per_ms: f64::NAN,
        ..Reverb::default()
    };
    assert_eq!(broken.guard_s(-10.0, -20.0), 1.0);
    assert_eq!(Reverb::default().guard_s(-20.0, -10.0), 0.0);
}
