use super::*;
use crate::core::Event;
use ickon_proto::site::Site;

fn active(now: Time) -> CentralCore {
    CentralCore::new(
        Site::default_site(),
        String::new(),
        CentralConfig::default(),
        now,
    )
    .unwrap()
}

fn standby(now: Time) -> CentralCore {
    CentralCore::standby(
        Site::default_site(),
        String::new(),
        CentralConfig::default(),
        now,
    )
    .unwrap()
}

fn triggers(out: &[Output]) -> Vec<CycleTrigger> {
    out.iter()
        .filter_map(|o| match o {
            Output::Trigger(t) => Some(t.clone()),
            _ => None,
        })
        .collect()
}

/// Runs the active core for `cycles` triggers, handing everything it
/// publishes to the standby; returns the last trigger.
/// The outputs but the survey calibration (a central unit that becomes
/// active publishes its own at once).
fn without_survey(out: Vec<Output>) -> Vec<Output> {
    out.into_iter()
        .filter(|o| !matches!(o, Output::Survey(_)))
        .collect()
}

fn run_both(a: &mut CentralCore, s: &mut CentralCore, cycles: usize) -> CycleTrigger {
    let mut last = None;
    let mut n = 0;
    while n < cycles {
        let now = a.next_wake();
        for o in a.tick(now) {
            let ev = match o {
                Output::Trigger(t) => {
                    last = Some(t.clone());
                    n += 1;
                    Event::TriggerSeen(t)
                }
                Output::Schedule(sc) => Event::ScheduleSeen(sc),
                Output::Survey(_) => continue,
            };
            assert!(s.handle(now, ev).is_empty(), "a standby publishes nothing");
        }
    }
    last.unwrap()
}

#[test]
fn a_standby_follows_and_takes_over_within_one_cycle_in_a_newer_epoch() {
    let mut a = active(Time(1_000));
    let mut s = standby(Time(2_000));
    s.handle(
        Time(2_000),
        Event::ScheduleSeen(a.latest_schedule().clone()),
    );
    let last = run_both(&mut a, &mut s, 10);
    assert!(!s.is_active() && a.is_active());
    assert_eq!(s.followed_epoch(), Some(a.epoch()));
    assert!(!s.status(last.start).active);
    // The active one dies right after its last trigger.
    let now = last.start;
    let out = without_survey(s.handle(now, Event::ActiveGone));
    assert!(s.is_active());
    assert!(s.epoch() > a.epoch(), "fenced: a newer epoch");
    assert!(
        matches!(out.as_slice(), [Output::Schedule(sc)] if sc.version == 1 && sc.epoch == s.epoch())
    );
    // Its cycle 0 starts one period after the last followed cycle: no cycle lost.
    let t0 = triggers(&s.tick(s.next_wake()));
    let period = a.latest_schedule().cycle_period;
    assert_eq!(t0.len(), 1);
    assert_eq!((t0[0].cycle, t0[0].start), (0, last.start + period));
}

#[test]
fn a_hung_active_is_replaced_after_its_lease_and_steps_down_when_it_wakes() {
    let mut a = active(Time(1_000));
    let mut s = standby(Time(2_000));
    let last = run_both(&mut a, &mut s, 5);
    // No trigger comes any more (SIGSTOP): the lease runs out.
    let lease = s.next_wake();
    let period = a.latest_schedule().cycle_period;
    assert_eq!(lease, last.start + period * LEASE_CYCLES);
    assert!(
        s.handle(lease - Duration::from_millis(1), Event::Tick)
            .is_empty()
    );
    let out = s.handle(lease, Event::Tick);
    assert!(s.is_active(), "{out:?}");
    // The old one wakes and hears the new epoch: it stands by.
    let t = triggers(&s.tick(s.next_wake()))[0].clone();
    a.handle(t.start, Event::TriggerSeen(t));
    assert!(!a.is_active());
    assert!(
        triggers(&a.tick(a.next_wake())).is_empty(),
        "no second active"
    );
}

#[test]
fn a_standby_alone_becomes_active_after_its_first_lease() {
    let mut s = standby(Time(0));
    assert!(s.handle(Time(1), Event::Tick).is_empty());
    let out = without_survey(s.handle(Time(0) + FIRST_LEASE, Event::Tick));
    assert!(s.is_active());
    assert_eq!(out.len(), 1);
}

#[test]
fn a_standby_publishes_nothing_when_cells_come_and_go() {
    let mut s = standby(Time(0));
    for id in ["c1", "c2"] {
        let out = s.handle(
            Time(1),
            Event::CellAlive {
                id: id.into(),
                up: true,
            },
        );
        assert!(out.is_empty(), "{out:?}");
    }
}

#[test]
fn a_central_unit_restarted_while_another_is_active_stands_by() {
    // The first central unit dies; the standby takes over.
    let mut first = active(Time(1_000));
    let mut s = standby(Time(2_000));
    let last = run_both(&mut first, &mut s, 5);
    s.handle(last.start, Event::ActiveGone);
    assert!(s.is_active());
    // The first is restarted (a newer start, so a newer epoch were it
    // active) and sees the token of the one that took over.
    let now = last.start + Duration::from_millis(500);
    let mut restarted = CentralCore::starting(
        Site::default_site(),
        String::new(),
        CentralConfig::default(),
        now,
        false,
        true,
    )
    .unwrap();
    assert!(!restarted.is_active());
    // It follows the active one, publishes nothing, and the active one
    // never hears a newer epoch to step down for.
    run_both(&mut s, &mut restarted, 10);
    assert!(s.is_active() && !restarted.is_active());
    assert_eq!(restarted.followed_epoch(), Some(s.epoch()));
    // Without another central unit it starts active, as before.
    let alone = CentralCore::starting(
        Site::default_site(),
        String::new(),
        CentralConfig::default(),
        now,
        false,
        false,
    )
    .unwrap();
    assert!(alone.is_active());
}

#[test]
fn a_copy_behaves_as_the_original_and_apart_from_it() {
    let mut a = active(Time(1_000));
    let mut s = standby(Time(2_000));
    run_both(&mut a, &mut s, 3);
    let (mut a2, mut s2) = (a.clone(), s.clone());
    // The same events give the same outputs: the copy holds the whole state.
    let now = a.next_wake();
    assert_eq!(a2.next_wake(), now);
    let out = a.tick(now);
    assert!(!triggers(&out).is_empty());
    assert_eq!(a2.tick(now), out);
    let gone = now + Duration::from_millis(1);
    let took = s.handle(gone, Event::ActiveGone);
    assert!(!took.is_empty(), "the standby takes over");
    assert_eq!(s2.handle(gone, Event::ActiveGone), took);
    assert_eq!(s2.epoch(), s.epoch());
    // And the original's later events leave the copy as it was.
    let mut a3 = a.clone();
    a.set_paused(true);
    let later = a.next_wake();
    assert!(triggers(&a.tick(later)).is_empty(), "paused");
    assert!(
        !triggers(&a3.tick(later)).is_empty(),
        "the copy was not paused"
    );
}

#[test]
fn a_forged_far_future_empty_schedule_is_not_taken_over() {
    let now = Time::from_nanos(1_700_000_000_000_000_000);
    // An active unit counts such a schedule as foreign control and does not
    // stand by for it; a standby follows what it hears, and must not take
    // it over.
    let mut checked = active(now);
    let mut a = standby(now);
    let own = checked.latest_schedule().clone();
    let forged = Schedule {
        epoch: u64::MAX,
        version: 1,
        emissions: Vec::new(),
        active_cells: Vec::new(),
        cycle_period: Duration::from_nanos(11),
        slot_length: Duration::from_nanos(1),
        ..own.clone()
    };
    assert!(
        checked
            .handle(now, Event::ScheduleSeen(forged.clone()))
            .len()
            <= 1
    );
    assert!(checked.is_active());
    assert_eq!(checked.foreign_control(), 1);
    // The standby follows it, then its lease runs out.
    assert!(a.handle(now, Event::ScheduleSeen(forged)).is_empty());
    assert!(!a.is_active());
    let later = a.next_wake();
    let out = a.handle(later, Event::Tick);
    assert!(a.is_active(), "it takes over when the lease ends");
    // In an epoch the cells accept (near its clock, below the forged one),
    // with the site's own schedule, and nothing left due.
    assert!(ickon_proto::epoch::plausible_epoch(a.epoch(), later));
    assert!(a.epoch() < u64::MAX);
    let Some(Output::Schedule(s)) = out.first() else {
        panic!("a schedule first: {out:?}");
    };
    assert_eq!(s.epoch, a.epoch());
    assert_eq!(s.emissions, own.emissions);
    assert!(a.next_wake() > later);
}

#[test]
fn a_standby_takes_each_robots_fix_a_cycle_into_its_survey_calibration() {
    // Its share of the fleet's fixes refills with the cycles it hears: a
    // standby that counted only its own (none) would learn three fixes a
    // robot and take over with a calibration of nothing.
    let t0 = Time::from_secs_f64(100.0);
    let mut a = active(t0);
    let mut s = standby(t0 + Duration::from_millis(10));
    let fix = crate::core::tests::good_fix();
    for _ in 0..30 {
        run_both(&mut a, &mut s, 1);
        let now = a.next_wake();
        for c in [&mut a, &mut s] {
            c.handle(
                now,
                Event::Fix {
                    robot: "r1".into(),
                    fix: Box::new(fix.clone()),
                },
            );
        }
    }
    // Taken, or held for the fleet's check.
    let taken = |c: &CentralCore| {
        let survey = c.survey().unwrap();
        survey.calibration().fixes_taken() + survey.fixes_held() as u64
    };
    assert_eq!(taken(&a), 30);
    assert_eq!(taken(&s), 30);
}
