use super::*;
use ickon_proto::msg::admin::{CellState, CoverageReport};
use ickon_proto::msg::robot::{FixQuality, RobotPose};

/// The summary of a robot whose newest pose is `pose` (no velocity, no fixes).
pub(super) fn summary_of(pose: RobotPose) -> Box<RobotSummary> {
    Box::new(RobotSummary {
        seq: 1,
        stamp: pose.stamp,
        x_m: pose.x_m,
        y_m: pose.y_m,
        theta_rad: pose.theta_rad,
        covariance: pose.covariance,
        estimator: pose.estimator,
        fix_seq: pose.fix_seq,
        status: pose.status,
        vx_m_s: 0.0,
        vy_m_s: 0.0,
        velocity_span_s: 0.0,
        fixes_solved: 0,
        fixes: Vec::new(),
    })
}

fn core() -> CentralCore {
    let site = Site::default_site();
    CentralCore::new(site, String::new(), CentralConfig::default(), Time(0)).unwrap()
}

/// A core whose four cells have all announced themselves.
fn all_alive() -> CentralCore {
    let mut c = core();
    for id in ["c1", "c2", "c3", "c4"] {
        c.cell_alive(id, true, Time(0));
    }
    assert_eq!(c.latest_schedule().active_cells.len(), 4);
    c
}

/// A fix of `robot` that says nothing of the survey (no signals used).
pub(super) fn fix_of(robot: &str) -> Event {
    Event::Fix {
        robot: robot.into(),
        fix: Box::new(Fix {
            stamp: Time(0),
            arrivals_seq: 0,
            x_m: 1.0,
            y_m: 1.0,
            z_m: 0.3,
            covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 0.0],
            heading_rad: 0.0,
            heading_valid: false,
            used: Vec::new(),
            rejected: Vec::new(),
            residuals_m: Vec::new(),
            quality: FixQuality::Minimal,
            survey_version: 0,
            unused: Vec::new(),
            unused_residuals_m: Vec::new(),
        }),
    }
}

/// A good fix in the lab's first room that the survey calibration takes.
pub(super) fn good_fix() -> Fix {
    let Event::Fix { fix, .. } = fix_of("r1") else {
        unreachable!()
    };
    Fix {
        x_m: 4.0,
        y_m: 1.25,
        used: vec![11, 12, 13, 14],
        residuals_m: vec![0.002, -0.001, 0.001, -0.002],
        quality: FixQuality::Good,
        ..*fix
    }
}

fn triggers(out: &[Output]) -> Vec<CycleTrigger> {
    out.iter()
        .filter_map(|o| match o {
            Output::Trigger(t) => Some(t.clone()),
            _ => None,
        })
        .collect()
}

fn schedule(out: &[Output]) -> Option<Schedule> {
    out.iter().find_map(|o| match o {
        Output::Schedule(s) => Some(s.clone()),
        _ => None,
    })
}

fn health(c: &CentralCore, id: &str) -> ickon_proto::msg::admin::CellHealth {
    c.status(Time(0))
        .cells
        .into_iter()
        .find(|h| h.id == id)
        .unwrap()
}

/// Runs `core` for `n` cycles from `now`, every cycle at its trigger time;
/// returns the time after them and the triggers.
/// Every scheduled cell fires (one burst each) in every triggered cycle.
fn run_cycles(c: &mut CentralCore, n: usize) -> Vec<CycleTrigger> {
    let mut all = Vec::new();
    for _ in 0..n {
        let now = c.next_wake();
        let fired = triggers(&c.tick(now));
        for t in &fired {
            let cells = c.schedule_for(t.cycle).active_cells.clone();
            for id in cells {
                c.on_burst(
                    &Burst {
                        cell_id: id,
                        tx_id: 0,
                        cycle: t.cycle,
                        scheduled: t.start,
                        actual: t.start,
                        epoch: c.epoch(),
                    },
                    now,
                );
            }
        }
        all.extend(fired);
    }
    all
}

#[test]
fn triggers_go_out_ahead_of_each_cycle_once() {
    let mut c = core();
    let lead = CentralConfig::default().trigger_lead;
    assert!(triggers(&c.tick(Time(0))).is_empty());
    let first = c.next_wake();
    let t = triggers(&c.tick(first));
    assert_eq!(t.len(), 1);
    assert_eq!(t[0].cycle, 0);
    assert_eq!(t[0].start, first + lead);
    assert!(triggers(&c.tick(first)).is_empty(), "no second trigger");
    let period = c.latest_schedule().cycle_period;
    let t = triggers(&c.tick(first + period));
    assert_eq!(t[0].cycle, 1);
    assert_eq!(t[0].start, first + lead + period);
}

#[test]
fn a_cell_that_goes_down_leaves_the_schedule_at_a_named_cycle() {
    let mut c = all_alive();
    run_cycles(&mut c, 3);
    let before = c.latest_schedule().version;
    // Lost right after the trigger of cycle 2: cycle 3's trigger is a whole
    // period away, so the new schedule can take effect there.
    let now = c.next_wake() - c.latest_schedule().cycle_period;
    let new = schedule(&c.cell_alive("c2", false, now)).expect("a new schedule");
    assert_eq!(new.version, before + 1);
    assert!(!new.active_cells.contains(&"c2".to_string()));
    assert_eq!(new.effective_cycle, 3);
    // Lost just before a trigger: too late to announce for that cycle.
    let mut d = all_alive();
    run_cycles(&mut d, 3);
    let late = d.next_wake() - Duration::from_millis(10);
    let s = schedule(&d.cell_alive("c2", false, late)).unwrap();
    assert_eq!(s.effective_cycle, 4);
    // Triggers before the switch name version 1, from it version 2.
    for t in run_cycles(&mut c, 5) {
        let expected = if t.cycle >= new.effective_cycle {
            new.version
        } else {
            before
        };
        assert_eq!(t.schedule_version, expected, "cycle {}", t.cycle);
    }
}

#[test]
fn a_lost_cell_is_down_at_once_and_comes_back_up_when_scheduled_again() {
    let mut c = all_alive();
    run_cycles(&mut c, 4);
    assert!((health(&c, "c3").state == CellState::Up));
    let now = c.next_wake() - Duration::from_millis(200);
    c.cell_alive("c3", false, now);
    let h = health(&c, "c3");
    assert_eq!(h.state, CellState::Down);
    assert_eq!(h.state_since_cycle, 3, "down in the cycle it was lost");
    run_cycles(&mut c, 3);
    // Back: alive at once, but up only from the cycle that schedules it.
    let now = c.next_wake() - Duration::from_millis(200);
    let without = c.latest_schedule().version;
    let back = schedule(&c.cell_alive("c3", true, now)).expect("re-admitted");
    assert_eq!(back.version, without + 1);
    assert_eq!(back.active_cells.len(), 4);
    assert!(!(health(&c, "c3").state == CellState::Up));
    let t = run_cycles(&mut c, 1);
    assert_eq!(t[0].cycle, back.effective_cycle);
    assert_eq!(t[0].schedule_version, back.version);
    let h = health(&c, "c3");
    assert_eq!(h.state, CellState::Up);
    assert_eq!(h.state_since_cycle, back.effective_cycle);
}

#[test]
fn missed_cycles_are_counted_for_live_cells_that_did_not_fire() {
    let mut c = core();
    c.cell_alive("c1", true, Time(0));
    for cycle in 0..6u64 {
        let now = c.next_wake();
        c.tick(now);
        if cycle % 2 == 0 {
            c.on_burst(
                &Burst {
                    cell_id: "c1".into(),
                    tx_id: 11,
                    cycle,
                    scheduled: Time(1_000),
                    actual: Time(1_000 + 50_000),
                    epoch: c.epoch(),
                },
                now,
            );
        }
    }
    let h = health(&c, "c1");
    assert_eq!(h.cycles_fired, 3);
    assert_eq!(h.cycles_missed, 2, "cycles 1 and 3 are over, 5 is not");
    assert_eq!((h.residual_samples, h.residual_max_ns), (3, 50_000));
}

#[test]
fn pause_stops_triggers_and_resume_restarts_them() {
    let mut c = core();
    assert!(c.set_paused(true).ok);
    let now = c.next_wake();
    assert!(triggers(&c.tick(now)).is_empty());
    assert!(c.status(now).paused);
    c.set_paused(false);
    let period = c.latest_schedule().cycle_period;
    let t = triggers(&c.tick(now + period));
    assert_eq!(t.len(), 1);
    assert_eq!(t[0].cycle, 1, "cycle numbers went on while paused");
}

#[test]
fn a_bad_reload_is_refused_and_the_site_stays() {
    let mut c = core();
    let bad = ickon_proto::site::DEFAULT_SITE_TOML.replacen("id = 12\n", "id = 11\n", 1);
    let (ack, out) = c.reload(&bad, "bad.toml", Time(0));
    assert!(!ack.ok);
    assert!(ack.messages[0].contains("bad.toml:"), "{:?}", ack.messages);
    assert!(out.is_none());
    assert_eq!(c.site_info().version, 1);
    let renamed =
        ickon_proto::site::DEFAULT_SITE_TOML.replacen("name = \"lab\"", "name = \"x\"", 1);
    let (ack, _) = c.reload(&renamed, "x.toml", Time(0));
    assert!(
        !ack.ok && ack.messages[0].contains("differs"),
        "{:?}",
        ack.messages
    );
    let (ack, out) = c.reload(ickon_proto::site::DEFAULT_SITE_TOML, "lab.toml", Time(0));
    assert!(ack.ok, "{:?}", ack.messages);
    assert!(matches!(out, Some(Output::Schedule(s)) if s.version == 2));
    assert_eq!(c.site_info().version, 2);
}

#[test]
fn coverage_follows_the_schedule_in_force() {
    let mut c = all_alive();
    let full = c.coverage(0.5);
    assert_eq!(full.schedule_version, c.latest_schedule().version);
    run_cycles(&mut c, 2);
    let now = c.next_wake() - c.latest_schedule().cycle_period;
    c.cell_alive("c4", false, now);
    run_cycles(&mut c, 2);
    let without_c4 = c.coverage(0.5);
    assert_eq!(without_c4.schedule_version, c.latest_schedule().version);
    let seen = |r: &CoverageReport| r.visible.iter().map(|&v| u64::from(v)).sum::<u64>();
    assert!(seen(&without_c4) < seen(&full));
}

#[test]
fn robots_are_reported_with_their_last_pose() {
    let mut c = core();
    c.robot_alive("r1", true);
    c.on_summary(
        "r1",
        &summary_of(RobotPose {
            stamp: Time(0),
            x_m: 1.5,
            y_m: 2.0,
            theta_rad: 0.1,
            covariance: [0.0; 9],
            estimator: "ickon-akf".into(),
            fix_seq: 3,
            status: ickon_proto::msg::robot::PoseStatus::Tracking,
        }),
        Time(0),
    );
    c.on_fix("r1", Time(0));
    let r = &c.status(Time(0)).robots[0];
    assert!(r.up && r.pose_valid);
    assert_eq!((r.x_m, r.estimator.as_str()), (1.5, "ickon-akf"));
    assert!(r.fixes_per_s > 0.0);
    assert_eq!(r.stale, "");
}

#[test]
fn a_live_robot_whose_poses_stop_is_stale_and_its_msus_word_is_shown() {
    let mut c = core();
    c.robot_alive("r1", true);
    assert_eq!(c.status(Time(0)).robots[0].stale, "no pose yet");
    let pose = |status, stamp_ms: i64| RobotPose {
        stamp: Time(stamp_ms * 1_000_000),
        x_m: 1.5,
        y_m: 2.0,
        theta_rad: 0.1,
        covariance: [0.0; 9],
        estimator: "tdoa-ekf".into(),
        fix_seq: 3,
        status,
    };
    c.on_summary(
        "r1",
        &summary_of(pose(ickon_proto::msg::robot::PoseStatus::Tracking, 0)),
        Time(0),
    );
    let later = Time(0) + crate::health::POSE_STALE_AFTER + Duration::from_millis(500);
    assert_eq!(c.status(later).robots[0].stale, "no pose for 2.1 s");
    c.on_summary(
        "r1",
        &summary_of(pose(ickon_proto::msg::robot::PoseStatus::NoFixes, 2_100)),
        later,
    );
    assert_eq!(c.status(later).robots[0].stale, "MSU: no fixes");
    let later = later + Duration::from_millis(500);
    c.on_summary(
        "r1",
        &summary_of(pose(ickon_proto::msg::robot::PoseStatus::Localising, 2_600)),
        later,
    );
    assert!(
        c.status(later).robots[0]
            .stale
            .starts_with("MSU: localising"),
        "{}",
        c.status(later).robots[0].stale
    );
}

#[test]
fn events_reach_the_same_state_as_the_methods_and_due_triggers_come_with_them() {
    let mut c = core();
    for id in ["c1", "c2", "c3", "c4"] {
        c.handle(
            Time(0),
            Event::CellAlive {
                id: id.into(),
                up: true,
            },
        );
    }
    assert_eq!(c.latest_schedule().active_cells.len(), 4);
    // A cell going away makes a new schedule at once.
    let out = c.handle(
        Time(1),
        Event::CellAlive {
            id: "c3".into(),
            up: false,
        },
    );
    let s = schedule(&out).expect("a schedule without c3");
    assert!(!s.active_cells.contains(&"c3".to_string()));
    // Any event at or past the wake-up time also emits the due trigger.
    let due = c.next_wake();
    let out = c.handle(due, fix_of("r1"));
    assert_eq!(triggers(&out).len(), 1);
    assert!(c.status(due).robots.iter().any(|r| r.id == "r1"));
    // Before it, nothing is emitted.
    let early = Time::from_nanos(c.next_wake().as_nanos() - 1);
    assert!(c.handle(early, Event::Tick).is_empty());
}

#[test]
fn robots_the_site_does_not_know_are_counted_not_tracked() {
    let mut c = core();
    for k in 0..10_000 {
        c.handle(Time(k), fix_of(&format!("x{k}")));
    }
    c.handle(
        Time(0),
        Event::RobotAlive {
            id: "x1".into(),
            up: true,
        },
    );
    c.handle(Time(1), fix_of("r1"));
    let ids: Vec<String> = c.status(Time(2)).robots.into_iter().map(|r| r.id).collect();
    assert_eq!(ids, vec!["r1".to_string()]);
    assert_eq!(c.unknown_robot_messages(), 10_001);
}

#[test]
fn a_live_cell_that_stops_firing_is_down_after_two_missed_cycles() {
    let mut c = all_alive();
    run_cycles(&mut c, 4);
    assert!((health(&c, "c2").state == CellState::Up));
    // c2 hangs: the others go on firing, c2 fires nothing, its token stays.
    let mut down_after = None;
    for k in 1..=6 {
        let now = c.next_wake();
        for t in triggers(&c.tick(now)) {
            for id in ["c1", "c3", "c4"] {
                c.on_burst(
                    &Burst {
                        cell_id: id.into(),
                        tx_id: 0,
                        cycle: t.cycle,
                        scheduled: t.start,
                        actual: t.start,
                        epoch: c.epoch(),
                    },
                    now,
                );
            }
        }
        if down_after.is_none() && !(health(&c, "c2").state == CellState::Up) {
            down_after = Some(k);
        }
    }
    // Checked two cycles after each: the second missed cycle is seen at
    // the fourth trigger after the hang.
    assert_eq!(down_after, Some(4));
    assert!((health(&c, "c1").state == CellState::Up) && (health(&c, "c3").state == CellState::Up));
    assert!(c.latest_schedule().active_cells.contains(&"c2".to_string()));
    // It fires again: up as soon as a fired cycle is checked.
    run_cycles(&mut c, 3);
    assert!((health(&c, "c2").state == CellState::Up));
}

#[test]
fn with_occupancy_the_triggers_name_only_what_a_tracked_robot_hears() {
    use crate::occupancy::FiringConfig;
    use ickon_proto::msg::robot::RobotPose;
    let (site, _) = Site::builtin("warehouse").unwrap();
    let config = CentralConfig {
        firing: FiringConfig {
            occupancy: true,
            ..FiringConfig::default()
        },
        ..CentralConfig::default()
    };
    let mut c = CentralCore::new(site.clone(), String::new(), config, Time(0)).unwrap();
    let all = c.latest_schedule().emissions.len();
    let robot = site.robots[0].id.clone();
    c.handle(
        Time(0),
        Event::RobotAlive {
            id: robot.clone(),
            up: true,
        },
    );
    // New robot, no pose: the whole schedule fires, named one by one.
    let first = triggers(&c.handle(Time::from_secs_f64(1.0), Event::Tick));
    assert!(!first.is_empty());
    assert!(first.iter().all(|t| t.firing.len() == all));
    let start = site.robots[0].start;
    let pose = RobotPose {
        stamp: Time(0),
        x_m: start[0],
        y_m: start[1],
        theta_rad: start[2],
        covariance: [0.0025, 0.0, 0.0, 0.0, 0.0025, 0.0, 0.0, 0.0, 0.01],
        estimator: "tdoa-ekf".into(),
        fix_seq: 1,
        status: ickon_proto::msg::robot::PoseStatus::Tracking,
    };
    // A pose its MSU has not confirmed (a restarted MSU at the site's start
    // pose) is as good as none: the whole schedule still fires.
    let unconfirmed = RobotPose {
        status: ickon_proto::msg::robot::PoseStatus::Localising,
        ..pose.clone()
    };
    c.handle(
        Time::from_secs_f64(1.0),
        Event::Summary {
            robot: robot.clone(),
            summary: summary_of(unconfirmed),
        },
    );
    let guessing = triggers(&c.handle(Time::from_secs_f64(1.5), Event::Tick));
    assert!(!guessing.is_empty());
    assert!(guessing.iter().all(|t| t.firing.len() == all));
    let now = Time::from_secs_f64(1.5);
    c.handle(
        now,
        Event::Summary {
            robot,
            summary: summary_of(RobotPose {
                stamp: Time(500_000_000),
                ..pose
            }),
        },
    );
    let later = triggers(&c.handle(Time::from_secs_f64(2.5), Event::Tick));
    let last = later.last().unwrap();
    assert!(
        last.firing.len() < all / 2,
        "{} of {all}",
        last.firing.len()
    );
    assert!(last.period(c.latest_schedule()) < c.latest_schedule().cycle_period);
    // The admin sees that cycle's firing set and rate.
    assert_eq!(c.current_firing().emissions.len(), last.firing.len());
}

/// A master clock set back by seconds (by an operator, or NTP) left the
/// site silent until the clock caught up with the next trigger time.
#[test]
fn a_clock_stepped_back_starts_a_new_epoch_at_once_instead_of_waiting() {
    let mut c = all_alive();
    let t = c.next_wake();
    let first = triggers(&c.tick(t));
    let epoch = c.epoch();
    let period = c.latest_schedule().cycle_period;
    // Back by less than a cycle: the same epoch goes on, one cycle later.
    let now = t - Duration::from_nanos(period.as_nanos() / 2);
    assert!(triggers(&c.handle(now, Event::Tick)).is_empty());
    assert_eq!(c.epoch(), epoch);
    // Back by two seconds: a new epoch, its schedule now, a trigger soon.
    let back = t - Duration::from_millis(2_000);
    let out = c.handle(back, Event::Tick);
    assert!(c.epoch() > epoch);
    assert!(
        out.iter()
            .any(|o| matches!(o, Output::Schedule(s) if s.epoch == c.epoch())),
        "{out:?}"
    );
    assert!(c.next_wake() <= back + Duration::from_millis(200));
    let next = triggers(&c.tick(c.next_wake()));
    assert_eq!(next.len(), 1);
    assert_eq!((next[0].epoch, next[0].cycle), (c.epoch(), 0));
    assert!(next[0].start > back && next[0].start < first[0].start);
}

/// Found by `fuzz_central_core`: a clock jump forward made one tick send
/// every cycle of the gap (the end of time: a loop without end).
#[test]
fn a_clock_jump_forward_skips_the_stale_cycles_instead_of_sending_each() {
    let mut c = all_alive();
    let first = triggers(&c.tick(c.next_wake()));
    assert_eq!(first.len(), 1);
    let period = c.latest_schedule().cycle_period;
    let later = c.next_wake() + Duration::from_millis(86_400_000);
    let sent = triggers(&c.tick(later));
    assert!(
        !sent.is_empty() && sent.len() <= 3,
        "{} triggers",
        sent.len()
    );
    // The count moved on with the time: cycle and start still agree.
    let last = sent.last().unwrap();
    let cycles = (last.start - first[0].start).as_nanos() / period.as_nanos();
    assert_eq!(last.cycle - first[0].cycle, cycles as u64);
    assert!(c.next_wake() > later);
    // The end of time ends the tick too.
    let end = Time::from_nanos(i64::MAX);
    assert!(triggers(&c.tick(end)).len() < 8);
}

/// Found by `fuzz_central_core`: a standby that followed a trigger from
/// long ago (or with a nonsense period) took over with its cycle 0 in the
/// past (the catch-up loop gave up after 100 000 periods).
#[test]
fn a_takeover_after_a_trigger_from_long_ago_starts_its_cycle_0_ahead() {
    let now = Time::from_nanos(1_700_000_000_000_000_000);
    let site = Site::default_site();
    let mut c = CentralCore::standby(site, String::new(), CentralConfig::default(), now).unwrap();
    let old = CycleTrigger {
        cycle: 3,
        start: Time::from_nanos(26_404_000_000_000),
        schedule_version: 1,
        epoch: 5,
        firing: Vec::new(),
        cycle_period: Duration::from_nanos(i64::MIN),
    };
    // Its lease ended long ago: it takes over at once.
    let out = c.handle(now, Event::TriggerSeen(old));
    assert!(c.is_active());
    assert!(schedule(&out).is_some());
    let period = c.latest_schedule().cycle_period;
    let wake = c.next_wake();
    assert!(wake >= now && wake <= now + period, "wake {wake} at {now}");
}

/// Found by `fuzz_central_core`: one forged trigger of a newer epoch
/// stamped an hour ahead made the active central unit stand by until
/// then; it now takes over again once three periods pass without a trigger.
#[test]
fn a_forged_newer_trigger_stamped_far_ahead_stops_the_site_for_three_periods_at_most() {
    let mut c = all_alive();
    let now = c.next_wake();
    c.handle(now, Event::Tick);
    let forged = CycleTrigger {
        cycle: 1,
        start: now + Duration::from_millis(3_600_000),
        schedule_version: 1,
        epoch: c.epoch() + 1,
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
    };
    c.handle(now, Event::TriggerSeen(forged));
    assert!(!c.is_active(), "a newer epoch is followed");
    let period = c.latest_schedule().cycle_period;
    let later = now + period * 3;
    assert!(
        c.handle(later - Duration::from_millis(1), Event::Tick)
            .is_empty()
    );
    let out = c.handle(later, Event::Tick);
    assert!(c.is_active(), "took over again");
    assert!(schedule(&out).is_some());
}

/// An epoch is a central unit's start: a newer one an hour ahead of the
/// clock was forged, and the active central unit does not stand by for it
/// (it counts it as foreign control); one a second ahead (another central
/// unit's clock) is followed.
#[test]
fn a_newer_epoch_far_ahead_of_the_clock_is_foreign_control_not_a_reason_to_stand_by() {
    let mut c = all_alive();
    let now = c.next_wake();
    c.handle(now, Event::Tick);
    let hour_ahead =
        ickon_proto::time::Time::from_nanos((now + Duration::from_millis(3_600_000)).as_nanos());
    let far = u64::try_from(hour_ahead.as_nanos()).unwrap();
    let trigger = CycleTrigger {
        cycle: 1,
        start: now + Duration::from_millis(100),
        schedule_version: 1,
        epoch: far,
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
    };
    let before = c.foreign_control();
    c.handle(now, Event::TriggerSeen(trigger.clone()));
    let forged_schedule = Schedule {
        epoch: far,
        ..c.latest_schedule().clone()
    };
    c.handle(now, Event::ScheduleSeen(forged_schedule));
    assert!(c.is_active());
    assert_eq!(c.foreign_control(), before + 2);
    // A second ahead: a real central unit whose clock runs a little ahead.
    let near = u64::try_from((now + Duration::from_millis(1_000)).as_nanos()).unwrap();
    c.handle(
        now,
        Event::TriggerSeen(CycleTrigger {
            epoch: near,
            ..trigger
        }),
    );
    assert!(!c.is_active());
}

/// Found by `fuzz_central_core`: a forged schedule claiming the last
/// version made the next membership schedule (or reload) overflow it.
#[test]
fn a_forged_last_version_does_not_overflow_the_next_schedule() {
    let mut c = all_alive();
    let now = c.next_wake();
    c.handle(now, Event::Tick);
    let forged = Schedule {
        version: u32::MAX,
        emissions: Vec::new(),
        ..c.latest_schedule().clone()
    };
    c.handle(now, Event::ScheduleSeen(forged));
    c.handle(
        now,
        Event::CellAlive {
            id: "c2".into(),
            up: false,
        },
    );
    c.handle(now + Duration::from_millis(500), Event::Tick);
    let (ack, _) = c.reload(ickon_proto::site::DEFAULT_SITE_TOML, "lab.toml", now);
    assert!(ack.ok || !ack.messages.is_empty());
}

#[test]
fn the_survey_calibration_is_published_with_the_epoch_and_learns_from_good_fixes() {
    use crate::survey_calibration::consensus::WINDOW_FIXES;
    let mut c = core();
    let now = c.next_wake();
    let out = c.tick(now);
    assert!(out.iter().any(|o| matches!(o, Output::Trigger(_))));
    // Not with the trigger (its computation would hold the trigger back)
    // but in the tick right after, at once.
    assert!(!out.iter().any(|o| matches!(o, Output::Survey(_))));
    assert!(c.tick_pending());
    let first = c
        .tick(now)
        .into_iter()
        .find_map(|o| match o {
            Output::Survey(s) => Some(s),
            _ => None,
        })
        .expect("a calibration right after the first trigger");
    assert!(!c.tick_pending(), "then the next trigger");
    assert_eq!(first.epoch, c.epoch());
    assert_eq!(first.fixes_taken, 0);
    assert_eq!(first.offsets.len(), c.site().transmitters.len());
    let good = good_fix();
    // A window of the robot's fixes and one more, a cycle apart: the
    // first is learnt from (a fleet of one: unchecked), the rest held.
    let mut now = now;
    for _ in 0..=WINDOW_FIXES {
        now = c.next_wake();
        c.tick(now);
        c.handle(
            now,
            Event::Fix {
                robot: "r1".into(),
                fix: Box::new(good.clone()),
            },
        );
    }
    // A version it never published: not read.
    let unknown = Fix {
        survey_version: first.version + 1_000,
        ..good.clone()
    };
    c.handle(
        now,
        Event::Fix {
            robot: "r1".into(),
            fix: Box::new(unknown),
        },
    );
    assert_eq!(c.survey().unwrap().calibration().fixes_taken(), 1);
    assert_eq!(c.survey().unwrap().fixes_held(), WINDOW_FIXES);
    assert_eq!(c.survey_skipped().get("unknown calibration"), Some(&1));
    let later = now + Duration::from_millis(1_500);
    let mut out = c.handle(later, Event::Tick);
    if c.tick_pending() {
        out.extend(c.handle(later, Event::Tick));
    }
    let next = out
        .into_iter()
        .find_map(|o| match o {
            Output::Survey(s) => Some(s),
            _ => None,
        })
        .expect("again a second later");
    assert!(next.version > first.version);
    assert_eq!(next.fixes_taken, 1);
    // Off: nothing learnt, nothing published.
    let mut off = CentralCore::new(
        Site::default_site(),
        String::new(),
        CentralConfig {
            survey: None,
            ..CentralConfig::default()
        },
        Time(0),
    )
    .unwrap();
    let now = off.next_wake();
    assert!(!off.tick(now).iter().any(|o| matches!(o, Output::Survey(_))));
    assert!(off.survey().is_none());
}

#[test]
fn the_cells_due_are_those_a_trigger_names_or_all_when_it_names_none() {
    let mut c = all_alive();
    run_cycles(&mut c, 2);
    let mut t = c.last_trigger().expect("triggered").clone();
    t.firing.clear();
    assert_eq!(c.cells_due(&t).len(), 4, "the whole schedule fires");
    t.firing = vec![ickon_proto::msg::control::Firing {
        tx_id: 11,
        offset: Duration::ZERO,
    }];
    let due: Vec<String> = c.cells_due(&t).into_iter().collect();
    assert_eq!(due, vec!["c1".to_string()]);
}

#[test]
fn robots_come_a_page_at_a_time_by_state_or_nearest_first_and_bad_pages_are_refused() {
    use ickon_proto::msg::admin::RobotsRequest;
    let mut c = core();
    let ids: Vec<String> = c.site().robots.iter().map(|r| r.id.clone()).collect();
    assert!(ids.len() >= 3, "{ids:?}");
    for (k, id) in ids.iter().enumerate() {
        c.robot_alive(id, true);
        c.on_summary(
            id,
            &summary_of(RobotPose {
                stamp: Time(0),
                x_m: k as f64,
                y_m: 0.0,
                theta_rad: 0.0,
                covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
                estimator: "tdoa-ekf".into(),
                fix_seq: 1,
                status: ickon_proto::msg::robot::PoseStatus::Tracking,
            }),
            Time(0),
        );
    }
    c.robot_alive(&ids[0], false);
    let ask = |request: RobotsRequest| c.robots_page(Time(0), &request);
    let all = ask(RobotsRequest {
        page_size: 1,
        ..RobotsRequest::default()
    });
    assert_eq!(all.error, "");
    assert_eq!(
        (all.pages, all.matching),
        (ids.len() as u64, ids.len() as u64)
    );
    assert_eq!(all.counts.down, 1);
    assert_eq!(all.counts.up, ids.len() as u64 - 1);
    assert_eq!(all.robots.len(), 1);
    let down = ask(RobotsRequest {
        state: "down".into(),
        ..RobotsRequest::default()
    });
    assert_eq!(
        down.robots
            .iter()
            .map(|r| r.id.as_str())
            .collect::<Vec<_>>(),
        [ids[0].as_str()]
    );
    // Nearest first to the last robot's place.
    let last = ids.len() - 1;
    let near = ask(RobotsRequest {
        near: true,
        near_x_m: last as f64,
        ..RobotsRequest::default()
    });
    assert_eq!(near.robots[0].id, ids[last]);
    assert_eq!(near.robots[1].id, ids[last - 1]);
    // Beyond the last page, negative, or an unknown state: a clear refusal.
    let beyond = ask(RobotsRequest {
        page: 1_000_000_000,
        ..RobotsRequest::default()
    });
    assert!(
        beyond.error.contains("beyond the last, 0"),
        "{}",
        beyond.error
    );
    assert!(beyond.robots.is_empty());
    let negative = ask(RobotsRequest {
        page: -1,
        ..RobotsRequest::default()
    });
    assert!(negative.error.contains("negative"), "{}", negative.error);
    let unknown = ask(RobotsRequest {
        state: "lost".into(),
        ..RobotsRequest::default()
    });
    assert!(
        unknown.error.contains("none of up, stale, down"),
        "{}",
        unknown.error
    );
}
