use super::*;
use crate::msg::control::Emission;

fn schedule(epoch: u64, version: u32, emissions: usize) -> Schedule {
    Schedule {
        version,
        effective_cycle: u64::from(version) * 10,
        cycle_period: Duration::from_millis(400),
        slot_length: Duration::from_millis(40),
        emissions: (0..emissions)
            .map(|i| Emission {
                tx_id: i as u32,
                cell_id: "c1".into(),
                offset: Duration::from_millis(40 * i as i64),
                slot: i as u32,
            })
            .collect(),
        active_cells: vec!["c1".into()],
        epoch,
    }
}

#[test]
fn a_shorter_schedule_under_the_current_version_is_refused_as_altered() {
    let mut book = ScheduleBook::new();
    assert_eq!(book.offer(schedule(5, 1, 4)), Ok(ScheduleOffer::NewEpoch));
    assert_eq!(
        book.offer(schedule(5, 1, 1)),
        Err(ScheduleRefused::Altered {
            epoch: 5,
            version: 1
        })
    );
    assert_eq!(book.refused(), 1);
    assert_eq!(book.latest().unwrap().emissions.len(), 4);
}

#[test]
fn a_re_announced_schedule_is_a_repeat_and_changes_nothing() {
    let mut book = ScheduleBook::new();
    book.offer(schedule(5, 1, 4)).unwrap();
    book.offer(schedule(5, 2, 3)).unwrap();
    assert_eq!(book.offer(schedule(5, 2, 3)), Ok(ScheduleOffer::Repeat));
    assert_eq!(book.offer(schedule(5, 1, 4)), Ok(ScheduleOffer::Repeat));
    assert_eq!(book.refused(), 0);
}

#[test]
fn versions_only_move_forward_within_an_epoch() {
    let mut book = ScheduleBook::new();
    book.offer(schedule(5, 3, 4)).unwrap();
    assert_eq!(
        book.offer(schedule(5, 2, 4)),
        Err(ScheduleRefused::Backwards { got: 2, newest: 3 })
    );
    assert_eq!(book.offer(schedule(5, 4, 4)), Ok(ScheduleOffer::New));
}

#[test]
fn a_newer_epoch_replaces_everything_and_an_older_one_is_refused() {
    let mut book = ScheduleBook::new();
    book.offer(schedule(5, 7, 4)).unwrap();
    // A restarted central unit numbers its versions from 1 again.
    assert_eq!(book.offer(schedule(9, 1, 2)), Ok(ScheduleOffer::NewEpoch));
    assert_eq!(book.epoch(), Some(9));
    assert!(book.get(7).is_none());
    assert_eq!(
        book.offer(schedule(5, 8, 4)),
        Err(ScheduleRefused::OldEpoch { got: 5, current: 9 })
    );
    assert!(book.get_in(9, 1).is_some());
    assert!(book.get_in(5, 1).is_none());
}

#[test]
fn impossible_numbers_are_refused_before_anything_else() {
    let mut book = ScheduleBook::new();
    let mut s = schedule(1, 1, 2);
    s.cycle_period = Duration::ZERO;
    assert!(matches!(
        book.offer(s),
        Err(ScheduleRefused::Invalid { .. })
    ));
    let mut s = schedule(1, 1, 2);
    s.emissions[1].offset = Duration::from_millis(-1);
    assert!(matches!(
        book.offer(s),
        Err(ScheduleRefused::Invalid { .. })
    ));
    let mut s = schedule(1, 1, 2);
    s.cycle_period = Duration::from_millis(3_600_000);
    assert!(matches!(
        book.offer(s),
        Err(ScheduleRefused::Invalid { .. })
    ));
    // A cycle of a nanosecond with a slot of a nanosecond and nothing to
    // fire: consistent with itself, but no burst fits in it.
    let mut s = schedule(1, 1, 0);
    s.cycle_period = Duration::from_nanos(1);
    s.slot_length = Duration::from_nanos(1);
    assert!(matches!(
        book.offer(s),
        Err(ScheduleRefused::Invalid { .. })
    ));
    // A sensible period with nothing to fire: every cycle of it is silent.
    assert!(matches!(
        book.offer(schedule(1, 1, 0)),
        Err(ScheduleRefused::Invalid { .. })
    ));
    // An emission of a cell the schedule leaves out.
    let mut s = schedule(1, 1, 2);
    s.emissions[1].cell_id = "c9".into();
    assert!(matches!(
        book.offer(s),
        Err(ScheduleRefused::Invalid { .. })
    ));
    assert_eq!(book.epoch(), None, "nothing was taken");
    assert_eq!(book.refused(), 6);
    let mut s = schedule(1, 1, 1);
    s.cycle_period = MIN_CYCLE_PERIOD;
    s.slot_length = MIN_CYCLE_PERIOD;
    assert_eq!(book.offer(s), Ok(ScheduleOffer::NewEpoch));
}

#[test]
fn the_book_keeps_a_bounded_number_of_versions() {
    let mut book = ScheduleBook::new();
    for v in 1..100 {
        book.offer(schedule(1, v, 1)).unwrap();
    }
    assert!(book.get(99).is_some());
    assert!(book.get(1).is_none());
    assert_eq!(book.for_cycle(u64::MAX).unwrap().version, 99);
}

#[test]
fn epochs_stay_ordered_when_the_clock_reads_less() {
    assert_eq!(epoch_of(Time::from_nanos(100), None), 100);
    assert_eq!(epoch_of(Time::from_nanos(100), Some(500)), 501);
    assert_eq!(epoch_of(Time::from_nanos(-5), None), 0);
    assert_eq!(epoch_of(Time::ZERO, Some(u64::MAX)), u64::MAX);
    assert_eq!(epoch_start(u64::MAX), Time::from_nanos(i64::MAX));
}
