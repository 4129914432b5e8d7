//! Control messages on the central unit's own keys that it did not send
//! (forged): each counted, reported, and answered so that they heal.

use super::*;

fn core() -> CentralCore {
    let site = Site::default_site();
    CentralCore::new(site, String::new(), CentralConfig::default(), Time(5_000)).unwrap()
}

fn schedules(out: &[Output]) -> Vec<Schedule> {
    out.iter()
        .filter_map(|o| match o {
            Output::Schedule(s) => Some(s.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn everything_published_carries_the_epoch_of_the_start() {
    let mut c = core();
    assert_eq!(c.epoch(), 5_000);
    assert_eq!(c.latest_schedule().epoch, 5_000);
    let now = c.next_wake();
    let out = c.tick(now);
    assert!(out.iter().all(|o| match o {
        Output::Trigger(t) => t.epoch == 5_000,
        Output::Schedule(s) => s.epoch == 5_000,
        Output::Survey(s) => s.epoch == 5_000,
    }));
    assert_eq!(
        CentralCore::clock_reply(c.epoch(), Time(1), Time(2), Time(3)).epoch,
        5_000
    );
    assert_eq!(c.status(now).epoch, 5_000);
}

#[test]
fn its_own_schedule_and_triggers_coming_back_are_not_foreign() {
    let mut c = core();
    let now = c.next_wake();
    let out = c.tick(now);
    for o in out {
        let back = match o {
            Output::Trigger(t) => Event::TriggerSeen(t),
            Output::Schedule(s) => Event::ScheduleSeen(s),
            Output::Survey(_) => continue,
        };
        c.handle(now, back);
    }
    c.handle(now, Event::ScheduleSeen(c.latest_schedule().clone()));
    assert_eq!(c.foreign_control(), 0);
}

#[test]
fn its_own_trigger_echoed_back_many_cycles_late_is_not_foreign_a_changed_one_is() {
    let mut c = core();
    let mut sent = Vec::new();
    while sent.len() < 200 {
        let now = c.next_wake();
        sent.extend(c.tick(now).into_iter().filter_map(|o| match o {
            Output::Trigger(t) => Some(t),
            _ => None,
        }));
    }
    let now = c.next_wake();
    // The first of them, back after 200 cycles (a router under load).
    c.handle(now, Event::TriggerSeen(sent[0].clone()));
    assert_eq!(c.foreign_control(), 0);
    let forged = CycleTrigger {
        cycle_period: sent[0].cycle_period + Duration::from_nanos(1),
        ..sent[0].clone()
    };
    c.handle(now, Event::TriggerSeen(forged));
    assert_eq!(c.foreign_control(), 1);
}

#[test]
fn an_empty_schedule_under_the_current_version_is_counted_and_answered_at_once() {
    let mut c = core();
    let mine = c.latest_schedule().clone();
    let forged = Schedule {
        emissions: Vec::new(),
        ..mine.clone()
    };
    let out = c.handle(Time(6_000), Event::ScheduleSeen(forged));
    assert_eq!(schedules(&out), vec![mine], "its own again");
    assert_eq!(c.foreign_control(), 1);
    assert_eq!(c.status(Time(6_000)).foreign_control, 1, "reported");
}

#[test]
fn an_unfireable_schedule_of_a_newer_epoch_does_not_make_it_stand_by() {
    let mut c = core();
    let mine = c.latest_schedule().clone();
    let forged = Schedule {
        epoch: 5_500,
        emissions: Vec::new(),
        cycle_period: Duration::from_nanos(1),
        ..mine.clone()
    };
    let out = c.handle(Time(6_000), Event::ScheduleSeen(forged));
    assert!(c.is_active(), "still the active central unit");
    assert_eq!(schedules(&out), vec![mine], "its own again");
    assert_eq!(c.foreign_control(), 1);
    // A fireable one of the same newer epoch is another central unit.
    let other = Schedule {
        epoch: 5_500,
        ..c.latest_schedule().clone()
    };
    c.handle(Time(6_000), Event::ScheduleSeen(other));
    assert!(!c.is_active(), "stands by for the newer epoch");
}

#[test]
fn a_forged_newer_version_is_displaced_by_a_higher_one_with_the_real_content() {
    let mut c = core();
    let mine = c.latest_schedule().clone();
    let forged = Schedule {
        version: 40,
        emissions: Vec::new(),
        ..mine.clone()
    };
    let out = c.handle(Time(6_000), Event::ScheduleSeen(forged));
    let healed = schedules(&out);
    assert_eq!(healed.len(), 1);
    assert_eq!(healed[0].version, 41);
    assert_eq!(healed[0].emissions, mine.emissions);
    assert_eq!(c.latest_schedule().version, 41);
    // The last version there is: a new epoch instead.
    let forged = Schedule {
        version: u32::MAX,
        ..mine
    };
    let out = c.handle(Time(7_000), Event::ScheduleSeen(forged));
    let fresh = schedules(&out);
    assert!(fresh[0].epoch > 5_000 && fresh[0].version == 1, "{fresh:?}");
}

#[test]
fn a_trigger_it_did_not_send_is_counted() {
    let mut c = core();
    let forged = CycleTrigger {
        cycle: 1 << 62,
        start: Time(600_000_000),
        schedule_version: 1,
        epoch: c.epoch(),
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
    };
    c.handle(Time(6_000), Event::TriggerSeen(forged));
    assert_eq!(c.foreign_control(), 1);
}

#[test]
fn the_schedule_is_re_announced_every_period() {
    let mut c = core();
    let period = CentralConfig::default().schedule_reannounce;
    let mut announced = Vec::new();
    let mut now = Time(5_000);
    let end = now + period * 5;
    while now < end {
        now = c.next_wake();
        for s in schedules(&c.tick(now)) {
            announced.push(now);
            assert_eq!(s, *c.latest_schedule());
        }
    }
    assert!((4..=5).contains(&announced.len()), "{announced:?}");
}

#[test]
fn bursts_of_another_epoch_are_not_counted_as_fired() {
    let mut c = core();
    c.cell_alive("c1", true, Time(0));
    c.on_burst(
        &Burst {
            cell_id: "c1".into(),
            tx_id: 11,
            cycle: 0,
            scheduled: Time(0),
            actual: Time(0),
            epoch: 1,
        },
        Time(0),
    );
    let h = c
        .status(Time(0))
        .cells
        .into_iter()
        .find(|h| h.id == "c1")
        .unwrap();
    assert_eq!(h.cycles_fired, 0);
}

#[test]
fn a_robot_flooding_fixes_gets_one_a_cycle_into_the_survey_calibration() {
    let mut c = core();
    let start = c.next_wake();
    c.tick(start);
    let good = super::tests::good_fix();
    let send = |c: &mut CentralCore, robot: &str, at: Time| {
        c.handle(
            at,
            Event::Fix {
                robot: robot.into(),
                fix: Box::new(good.clone()),
            },
        );
    };
    // r1 floods: 100 fixes every cycle for 20 cycles; r2 gives its one.
    for _ in 0..20 {
        let at = c.next_wake();
        c.tick(at);
        for _ in 0..100 {
            send(&mut c, "r1", at);
        }
        send(&mut c, "r2", at);
    }
    // Admitted: taken, or held for the fleet's check.
    let admitted = |c: &CentralCore| {
        let survey = c.survey().unwrap();
        survey.calibration().fixes_taken() + survey.fixes_held() as u64
    };
    let taken = admitted(&c);
    // r2's 20, and r1's burst of 3 and 1.25 a cycle after it.
    assert!((42..=47).contains(&taken), "{taken}");
    let over = c
        .survey_skipped()
        .get("over its rate")
        .copied()
        .unwrap_or(0);
    assert_eq!(over + taken, 2_020);
    // All of them r1's, for its warning, and shown by robot in the admin.
    assert_eq!(c.survey_fix_rate.refused("r1"), over);
    let status = c.status(start);
    let over_rate = |id: &str| {
        status
            .robots
            .iter()
            .find(|r| r.id == id)
            .map(|r| r.fixes_over_rate)
    };
    assert_eq!(over_rate("r1"), Some(over));
    assert_eq!(over_rate("r2"), Some(0));
    // Ids the site does not list share one share, however many.
    for k in 0..500 {
        send(&mut c, &format!("forged-{k}"), start);
    }
    assert_eq!(admitted(&c), taken + 3);
    assert!(c.survey_fix_rate.len() <= c.site().robots.len() + 1);
    assert_eq!(c.survey_fix_rate.refused(""), 497);
}

#[test]
fn a_robot_whose_fixes_disagree_with_the_fleet_is_quarantined_and_shown_so() {
    use crate::survey_calibration::consensus::WINDOW_FIXES;
    let mut c = core();
    let honest = super::tests::good_fix();
    // Every transmitter it heard 20 cm off, up and down in turn.
    let forged = Fix {
        residuals_m: vec![0.2, -0.2, 0.2, -0.2],
        ..honest.clone()
    };
    let send = |c: &mut CentralCore, robot: &str, fix: &Fix| {
        let at = c.next_wake();
        c.tick(at);
        c.handle(
            at,
            Event::Fix {
                robot: robot.into(),
                fix: Box::new(fix.clone()),
            },
        );
    };
    // A robot alone cannot be checked, and is shown so.
    for _ in 0..WINDOW_FIXES {
        send(&mut c, "r1", &honest);
    }
    let robot = |c: &CentralCore, id: &str| {
        c.status(Time(0))
            .robots
            .into_iter()
            .find(|r| r.id == id)
            .unwrap()
    };
    assert_eq!(
        robot(&c, "r1").survey_check,
        "unchecked: no other robot to compare"
    );
    for _ in 0..3 * WINDOW_FIXES {
        send(&mut c, "r2", &honest);
        send(&mut c, "r3", &forged);
        send(&mut c, "r1", &honest);
    }
    let forger = robot(&c, "r3");
    assert_eq!(forger.survey_check, "quarantined");
    // The window it was judged on, then every fix that left its window.
    assert_eq!(forger.fixes_quarantined, 2 * WINDOW_FIXES as u64);
    assert!(forger.survey_misfit_m > 0.1, "{forger:?}");
    assert!(forger.survey_bound_m < 0.05, "{forger:?}");
    for id in ["r1", "r2"] {
        let r = robot(&c, id);
        assert_eq!(r.survey_check, "agrees", "{r:?}");
        assert_eq!(r.fixes_quarantined, 0);
    }
    // Every fix taken is an honest robot's: of the forger's, the last
    // window is held (to judge its release), the rest kept out.
    let survey = c.survey().unwrap();
    let honest_fixes = (WINDOW_FIXES + 6 * WINDOW_FIXES) as u64;
    assert_eq!(
        survey.calibration().fixes_taken() + survey.fixes_held() as u64,
        honest_fixes + WINDOW_FIXES as u64
    );
}
