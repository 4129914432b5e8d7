use super::*;
use ickon_proto::msg::robot::PoseStatus;

fn summary(stamp_ms: i64, x_m: f64) -> RobotSummary {
    RobotSummary {
        seq: 0,
        stamp: Time(stamp_ms * 1_000_000),
        x_m,
        y_m: 2.0,
        theta_rad: 0.0,
        covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-3],
        estimator: "tdoa-ekf".into(),
        fix_seq: 0,
        status: PoseStatus::Tracking,
        vx_m_s: 0.0,
        vy_m_s: 0.0,
        velocity_span_s: 0.0,
        fixes_solved: 0,
        fixes: Vec::new(),
    }
}

fn at(ms: i64) -> Time {
    Time(ms * 1_000_000)
}

#[test]
fn a_robot_driving_at_its_rate_is_always_taken() {
    let mut gate = SummaryGate::default();
    // 1.2 m/s, a summary every 500 ms on a clock 40 s off the central
    // unit's, delivered with 0-150 ms of jitter.
    for k in 0..100i64 {
        let stamp = 40_000 + k * 500;
        let jitter = (k * 37) % 150;
        let s = summary(stamp, k as f64 * 0.6);
        assert_eq!(gate.check(&s, at(k * 500 + jitter)), Ok(()), "{k}");
    }
}

#[test]
fn floods_repeats_the_future_and_impostors_are_dropped_and_the_robot_goes_on() {
    let mut gate = SummaryGate::default();
    assert_eq!(gate.check(&summary(1_000, 1.0), at(0)), Ok(()));
    // A flood: 10 ms later.
    assert_eq!(
        gate.check(&summary(1_010, 1.0), at(10)),
        Err(Dropped::Flood)
    );
    // Stamps far ahead that arrive close: from the future.
    for k in 1..=3 {
        assert_eq!(
            gate.check(&summary(1_000 + k * 500, 1.0), at(10 * k)),
            if k < 3 { Ok(()) } else { Err(Dropped::Future) },
            "{k}"
        );
    }
    let mut gate = SummaryGate::default();
    assert_eq!(gate.check(&summary(1_000, 1.0), at(0)), Ok(()));
    // A repeat, and one older.
    assert_eq!(gate.check(&summary(1_000, 1.0), at(300)), Err(Dropped::Old));
    assert_eq!(gate.check(&summary(900, 1.0), at(300)), Err(Dropped::Old));
    // An hour ahead after 300 ms.
    assert_eq!(
        gate.check(&summary(3_601_000, 1.0), at(300)),
        Err(Dropped::Future)
    );
    // Another robot's place under this id: 20 m away 300 ms later.
    assert_eq!(
        gate.check(&summary(1_300, 21.0), at(300)),
        Err(Dropped::Jump)
    );
    // A vast claimed uncertainty does not widen the allowance beyond 2 m.
    let mut vague = summary(1_300, 21.0);
    vague.covariance[0] = 1e6;
    assert_eq!(gate.check(&vague, at(300)), Err(Dropped::Jump));
    // Too many fixes.
    let mut stuffed = summary(1_300, 1.0);
    stuffed.fixes = vec![
        ickon_proto::msg::robot::Fix {
            stamp: Time(0),
            arrivals_seq: 0,
            x_m: 0.0,
            y_m: 0.0,
            z_m: 0.0,
            covariance: [0.0; 9],
            heading_rad: 0.0,
            heading_valid: false,
            used: vec![],
            rejected: vec![],
            residuals_m: vec![],
            quality: ickon_proto::msg::robot::FixQuality::Good,
            survey_version: 0,
            unused: Vec::new(),
            unused_residuals_m: Vec::new(),
        };
        MAX_SUMMARY_FIXES + 1
    ];
    assert_eq!(gate.check(&stuffed, at(300)), Err(Dropped::Malformed));
    // The robot's own next summary is taken.
    assert_eq!(gate.check(&summary(1_500, 1.1), at(500)), Ok(()));
}

#[test]
fn a_robot_silent_for_long_or_reset_is_taken_from_its_next_summary() {
    let mut gate = SummaryGate::default();
    assert_eq!(gate.check(&summary(50_000, 1.0), at(0)), Ok(()));
    // Its MSU restarted with a clock stepped back, somewhere else: dropped
    // at first, taken once nothing was taken for REANCHOR_AFTER.
    assert_eq!(
        gate.check(&summary(1_000, 30.0), at(500)),
        Err(Dropped::Old)
    );
    assert_eq!(gate.check(&summary(4_000, 30.0), at(3_000)), Ok(()));
    // Its token went and came back: a new start.
    gate.reset();
    assert_eq!(gate.check(&summary(10, -5.0), at(3_200)), Ok(()));
}

#[test]
fn a_summary_carries_no_more_fixes_than_the_survey_calibration_takes_at_once() {
    // More would be refused as over the robot's share every time.
    assert!(MAX_SUMMARY_FIXES as f64 <= crate::survey_calibration::fix_rate::BURST_FIXES);
}

#[test]
fn summaries_queued_behind_a_stalled_loop_are_all_taken() {
    let mut gate = SummaryGate::default();
    assert_eq!(gate.check(&summary(1_000, 1.0), at(0)), Ok(()));
    // Three summaries half a second apart handled 1 ms apart after a stall.
    for k in 1..=3i64 {
        let s = summary(1_000 + k * 500, 1.0 + k as f64 * 0.5);
        assert_eq!(gate.check(&s, at(1_500 + k)), Ok(()), "{k}");
    }
}
