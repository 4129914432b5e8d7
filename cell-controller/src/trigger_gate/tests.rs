use super::*;

const PERIOD: Duration = Duration::from_millis(400);
const EPOCH: u64 = 1_000_000_000;

fn trigger(epoch: u64, cycle: u64, start_ms: i64) -> CycleTrigger {
    CycleTrigger {
        cycle,
        start: Time::from_nanos(start_ms * 1_000_000),
        schedule_version: 1,
        epoch,
        firing: Vec::new(),
        cycle_period: Duration::ZERO,
    }
}

/// A gate that has taken cycles 0..=9 of `EPOCH`, cycle k starting at
/// 2 s + k periods; returns it and the master time of cycle 10's trigger.
fn running() -> (TriggerGate, Time) {
    let mut g = TriggerGate::new();
    for k in 0..10 {
        let t = trigger(EPOCH, k, 2_000 + 400 * k as i64);
        g.admit(&t, Some(t.start - Duration::from_millis(60)), Some(PERIOD))
            .unwrap();
    }
    (g, Time::from_nanos((2_000 + 4_000 - 60) * 1_000_000))
}

#[test]
fn a_trigger_with_cycle_2_pow_62_is_refused_and_the_real_count_goes_on() {
    let (mut g, now) = running();
    let forged = trigger(EPOCH, 1 << 62, 6_000);
    assert!(matches!(
        g.admit(&forged, Some(now), Some(PERIOD)),
        Err(TriggerRefused::OffTheCount { .. })
    ));
    let real = trigger(EPOCH, 10, 6_000);
    assert_eq!(g.admit(&real, Some(now), Some(PERIOD)), Ok(false));
}

#[test]
fn a_restarted_central_units_cycle_0_is_taken_at_once_and_the_old_one_refused() {
    let (mut g, now) = running();
    let restarted = trigger(EPOCH + 5_000_000_000, 0, 6_000);
    assert_eq!(g.admit(&restarted, Some(now), Some(PERIOD)), Ok(true));
    assert_eq!(g.epoch(), Some(EPOCH + 5_000_000_000));
    let next = trigger(EPOCH + 5_000_000_000, 1, 6_400);
    assert_eq!(g.admit(&next, Some(now), Some(PERIOD)), Ok(false));
    let old = trigger(EPOCH, 11, 6_400);
    assert_eq!(
        g.admit(&old, Some(now), Some(PERIOD)),
        Err(TriggerRefused::OldEpoch {
            got: EPOCH,
            current: EPOCH + 5_000_000_000
        })
    );
}

#[test]
fn repeated_far_and_future_epoch_triggers_are_refused() {
    let (mut g, now) = running();
    let again = trigger(EPOCH, 9, 5_600);
    assert!(matches!(
        g.admit(&again, Some(now), Some(PERIOD)),
        Err(TriggerRefused::Repeated { .. })
    ));
    let far = trigger(EPOCH, 10, 60_000);
    assert!(matches!(
        g.admit(&far, Some(now), Some(PERIOD)),
        Err(TriggerRefused::Far { .. })
    ));
    let future = trigger(u64::MAX, 0, 6_000);
    assert_eq!(
        g.admit(&future, Some(now), Some(PERIOD)),
        Err(TriggerRefused::FutureEpoch(u64::MAX))
    );
    assert_eq!(g.epoch(), Some(EPOCH), "nothing moved the epoch");
}

#[test]
fn a_forged_first_trigger_costs_only_until_the_real_ones_agree() {
    let mut g = TriggerGate::new();
    let now = Time::from_nanos(1_940_000_000);
    // The forgery is the first trigger of the epoch the cell sees.
    g.admit(&trigger(EPOCH, 1 << 62, 2_000), Some(now), Some(PERIOD))
        .unwrap();
    let mut taken = Vec::new();
    for k in 0..6 {
        let t = trigger(EPOCH, k, 2_400 + 400 * k as i64);
        if g.admit(&t, Some(t.start), Some(PERIOD)).is_ok() {
            taken.push(k);
        }
    }
    assert_eq!(taken, vec![2, 3, 4, 5]);
}

#[test]
fn a_missed_trigger_or_a_period_change_is_within_the_count() {
    let (mut g, now) = running();
    // Cycle 10 lost; 11 comes one period later than 10 would have.
    let t = trigger(EPOCH, 11, 6_400);
    assert_eq!(g.admit(&t, Some(now), Some(PERIOD)), Ok(false));
    // The period shortens to 300 ms from cycle 12.
    let t = trigger(EPOCH, 12, 6_800);
    assert_eq!(
        g.admit(&t, Some(now), Some(Duration::from_millis(300))),
        Ok(false)
    );
    let t = trigger(EPOCH, 13, 7_100);
    assert_eq!(
        g.admit(&t, Some(now), Some(Duration::from_millis(300))),
        Ok(false)
    );
}
