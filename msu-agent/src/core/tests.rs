use super::*;
use ickon_fusion::estimator::WheelGeometry;
use ickon_fusion::estimator::build_by_name;
use ickon_proto::msg::control::Emission;
use ickon_proto::msg::control::TransmitterEntry;
use ickon_proto::msg::robot::{Arrival, FixQuality};
use ickon_proto::time::{Duration, Time};

pub(super) const C: f64 = 343.0;
pub(super) const TX: [(u32, [f64; 3]); 5] = [
    (1, [0.0, 0.0, 2.8]),
    (2, [5.0, 0.0, 2.6]),
    (3, [5.0, 4.0, 2.8]),
    (4, [0.0, 4.0, 2.6]),
    (5, [2.5, 2.0, 2.7]),
];

fn core() -> MsuCore {
    core_with("msu-raw")
}

/// The test MSU's configuration: six receivers at `height_m`, the
/// `transmitters` at their positions, the floor `floor_m`.
pub(super) fn config_with(
    height_m: f64,
    transmitters: &[(u32, [f64; 3])],
    floor_m: [[f64; 2]; 2],
) -> MsuConfig {
    MsuConfig {
        speed_of_sound_m_s: C,
        height_m,
        receiver_angles_rad: (0..6).map(|i| f64::from(i) * 60f64.to_radians()).collect(),
        transmitters: transmitters
            .iter()
            .map(|(id, p)| TransmitterEntry {
                tx_id: *id,
                cell_id: "a".into(),
                x_m: p[0],
                y_m: p[1],
                z_m: p[2],
            })
            .collect(),
        wheels: WheelGeometry {
            wheel_base_m: 0.33,
            left_m_per_tick: 1e-4,
            right_m_per_tick: 1e-4,
        },
        timing_sigma_s: 10e-6,
        residual_gate_m: 0.05,
        floor_bounds_m: Some(floor_m),
        max_fix_sigma_m: 0.5,
        walls: Vec::new(),
        columns: Vec::new(),
    }
}

pub(crate) fn core_with(estimator: &str) -> MsuCore {
    let config = config_with(0.5, &TX, [[0.0, 0.0], [5.0, 4.0]]);
    let mut core = MsuCore::new(config, build_by_name(estimator).unwrap());
    core.set_schedule(schedule()).unwrap();
    core
}

pub(super) fn schedule() -> Schedule {
    Schedule {
        version: 1,
        effective_cycle: 0,
        cycle_period: Duration::from_millis(200),
        slot_length: Duration::from_millis(40),
        emissions: TX
            .iter()
            .enumerate()
            .map(|(i, (id, _))| Emission {
                tx_id: *id,
                cell_id: "a".into(),
                offset: Duration::from_millis(40 * i as i64),
                slot: i as u32,
            })
            .collect(),
        active_cells: vec!["a".into()],
        epoch: 1,
    }
}

pub(super) fn arrivals(p: [f64; 3], late_m: &[(u32, f64)]) -> UltrasoundArrivals {
    arrivals_from(&TX, p, late_m)
}

/// The arrivals at `p` from transmitters hanging at `tx` (the table's
/// positions, or where a wrong survey put them).
pub(super) fn arrivals_from(
    tx: &[(u32, [f64; 3])],
    p: [f64; 3],
    late_m: &[(u32, f64)],
) -> UltrasoundArrivals {
    let start_s = 10.0;
    let arrivals = tx
        .iter()
        .enumerate()
        .map(|(i, (id, t))| {
            let d = ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt();
            let extra = late_m
                .iter()
                .find(|(k, _)| k == id)
                .map_or(0.0, |(_, e)| *e);
            Arrival {
                tx_id: *id,
                receiver_id: 0,
                t_arrival: Time::from_secs_f64(start_s + 0.04 * i as f64 + (d + extra) / C),
            }
        })
        .collect();
    UltrasoundArrivals { seq: 7, arrivals }
}

#[test]
fn exact_arrivals_give_an_exact_fix_and_the_estimator_takes_it() {
    let mut core = core();
    let fix = core
        .on_arrivals(&arrivals([1.7, 2.9, 0.5], &[]))
        .unwrap()
        .unwrap();
    assert!(
        (fix.x_m - 1.7).abs() < 1e-5 && (fix.y_m - 2.9).abs() < 1e-5,
        "{fix:?}"
    );
    assert_eq!(fix.used.len(), 5);
    assert_eq!(fix.quality, FixQuality::Good);
    let pose = core.pose().unwrap();
    assert!((pose.x_m - 1.7).abs() < 1e-5);
    assert_eq!(pose.fix_seq, 7);
}

#[test]
fn a_reflected_arrival_is_rejected_when_the_others_agree() {
    let mut core = core();
    let fix = core
        .on_arrivals(&arrivals([3.2, 1.1, 0.5], &[(3, 0.6)]))
        .unwrap()
        .unwrap();
    assert_eq!(fix.rejected, vec![3]);
    assert!(
        (fix.x_m - 3.2).abs() < 1e-4 && (fix.y_m - 1.1).abs() < 1e-4,
        "{fix:?}"
    );
}

#[test]
fn a_tightly_coupled_estimator_converges_on_range_differences_alone() {
    let mut core = core_with("tdoa-ekf");
    let truth = [2.2, 1.4, 0.5];
    for k in 0..20 {
        let mut msg = arrivals(truth, &[]);
        msg.seq = k;
        for a in &mut msg.arrivals {
            a.t_arrival = a.t_arrival + ickon_proto::time::Duration::from_millis(200 * k as i64);
        }
        let _ = core.on_arrivals(&msg);
    }
    let pose = core
        .pose()
        .expect("the filter started from the differences");
    let err = ((pose.x_m - truth[0]).powi(2) + (pose.y_m - truth[1]).powi(2)).sqrt();
    assert!(err < 0.01, "error {err} m: {pose:?}");
}

#[test]
fn a_restarted_msu_takes_its_pose_from_its_first_fixes_not_the_start_pose() {
    // The MSU restarted with the site's start pose, 3 m from the robot.
    let truth = [3.6, 2.9, 0.5];
    for name in ["tdoa-ekf", "ickon-akf"] {
        let mut estimator = ickon_fusion::estimator::EstimatorConfig::default_for(name).unwrap();
        estimator.set_initial_pose([0.8, 1.0, 0.0]);
        if let ickon_fusion::estimator::EstimatorConfig::TdoaEkf(p) = &mut estimator {
            p.receiver_height_m = 0.5;
        }
        let mut core = core_with("msu-raw");
        core.host = FusionHost::new(vec![ickon_fusion::estimator::build(&estimator).unwrap()]);
        let mut placed = None;
        for k in 0..10_u64 {
            let mut msg = arrivals(truth, &[]);
            msg.seq = k;
            for a in &mut msg.arrivals {
                a.t_arrival = a.t_arrival + Duration::from_millis(200 * k as i64);
            }
            core.on_arrivals(&msg).unwrap();
            let pose = core.pose().expect("started at the start pose");
            let err = (pose.x_m - truth[0]).hypot(pose.y_m - truth[1]);
            // Until a fix confirms it, the pose says it is a guess; a
            // placed filter whose heading is still unknown (this robot
            // stands still, so its track never gives one) is not
            // confirmed either.
            if pose.status != PoseStatus::Localising {
                assert!(err < 0.05, "{name} cycle {k}: {pose:?}");
            } else if err < 0.05 {
                assert!(
                    pose.covariance[8].sqrt() > CONFIRMED_HEADING_SIGMA_RAD,
                    "{name} cycle {k}: placed and heading known: {pose:?}"
                );
            }
            if err < 0.05 {
                placed.get_or_insert(k);
            } else {
                assert!(
                    placed.is_none(),
                    "{name}: lost again at cycle {k}: {pose:?}"
                );
            }
        }
        // Placed at the second agreeing cycle (ickon-akf's start check);
        // tdoa-ekf asks three against a start pose, spanning a second
        // (cycles of 0.2 s here: the sixth).
        let want = if name == "tdoa-ekf" { 5 } else { 1 };
        assert_eq!(placed, Some(want), "{name}");
    }
}

#[test]
fn a_valid_fix_is_published_when_the_estimator_refuses_it() {
    for name in ["ickon-akf", "gyro-ckf", "tdoa-ekf"] {
        let mut core = core_with(name);
        // Gyro samples an hour ahead: the estimator's history moves past
        // every real input, so it refuses the cycle's fix as too late.
        for k in 0..3 {
            let _ = core.on_imu(&Imu {
                stamp: Time::from_secs_f64(3_600.0 + f64::from(k)),
                gyro_z_rad_s: 0.0,
            });
        }
        let refused_before = core.host().refused(0);
        let fix = core
            .on_arrivals(&arrivals([1.7, 2.9, 0.5], &[]))
            .unwrap()
            .unwrap_or_else(|| panic!("{name}: the cycle's fix is valid"));
        assert!((fix.x_m - 1.7).abs() < 1e-5, "{name}: {fix:?}");
        assert!(
            core.host().refused(0) > refused_before,
            "{name}: the estimator took an input from an hour ago"
        );
    }
}

#[test]
fn every_hosted_estimator_gets_the_same_fix() {
    let config = core().solver.config().clone();
    let names = ["msu-raw", "ickon-akf", "tdoa-ekf"];
    let mut core = MsuCore::with_estimators(
        config,
        names.iter().map(|n| build_by_name(n).unwrap()).collect(),
    );
    core.set_schedule(schedule()).unwrap();
    let fix = core
        .on_arrivals(&arrivals([3.1, 1.2, 0.5], &[]))
        .unwrap()
        .unwrap();
    assert_eq!(core.host().len(), 3);
    let raw = core.pose_of(0).unwrap();
    assert_eq!((raw.x_m, raw.y_m), (fix.x_m, fix.y_m));
    assert_eq!(raw.estimator, "msu-raw");
    assert_eq!(
        core.pose_of(2).map(|p| p.estimator),
        Some("tdoa-ekf".into())
    );
}

#[test]
fn one_sample_stamped_an_hour_ahead_does_not_silence_the_robot() {
    let mut core = core_with("tdoa-ekf");
    let fix = |core: &mut MsuCore, k: u64| {
        let mut msg = arrivals([2.2, 1.4, 0.5], &[]);
        msg.seq = k;
        for a in &mut msg.arrivals {
            a.t_arrival = a.t_arrival + Duration::from_millis(200 * k as i64);
        }
        core.on_arrivals(&msg)
    };
    for k in 0..5 {
        let _ = fix(&mut core, k);
    }
    let refused_before = core.host().refused(0);
    let bogus = core.on_imu(&Imu {
        stamp: Time::from_secs_f64(3_610.0),
        gyro_z_rad_s: 0.0,
    });
    assert!(
        matches!(bogus, Err(MsuError::FromTheFuture { .. })),
        "{bogus:?}"
    );
    assert_eq!(core.refused_from_the_future(), 1);
    // Real inputs go on being fused.
    for k in 5..10 {
        assert!(fix(&mut core, k).unwrap().is_some());
    }
    assert_eq!(core.host().refused(0), refused_before, "nothing wedged");
    let pose = core.pose().unwrap();
    assert!(pose.stamp.as_secs_f64() < 100.0, "{pose:?}");
}

#[test]
fn the_event_contract_publishes_the_fix_then_its_pose_and_reports_refusals() {
    use crate::events::{Event, InputKind, Output};
    let mut core = core_with("ickon-akf");
    let out = core.handle(Event::Arrivals(arrivals([1.7, 2.9, 0.5], &[])));
    assert!(
        matches!(out.as_slice(), [Output::Fix(f), Output::Pose(p)] if f.stamp == p.stamp),
        "{out:?}"
    );
    let out = core.handle(Event::Imu(Imu {
        stamp: Time::from_secs_f64(3_610.0),
        gyro_z_rad_s: 0.0,
    }));
    assert!(
        matches!(
            out.as_slice(),
            [Output::Refused {
                input: InputKind::Imu,
                error: MsuError::FromTheFuture { .. }
            }]
        ),
        "{out:?}"
    );
    let out = core.handle(Event::Arrivals(UltrasoundArrivals {
        seq: 8,
        arrivals: vec![],
    }));
    assert!(
        matches!(
            out.as_slice(),
            [Output::Refused {
                input: InputKind::Arrivals,
                ..
            }]
        ),
        "{out:?}"
    );
}

#[test]
fn a_pose_carries_the_exact_nanosecond_of_the_input_it_answers() {
    use crate::events::{Event, Output};
    let mut core = core_with("odometry");
    // Unix time with odd nanoseconds: as f64 seconds it keeps only
    // about a quarter of a microsecond.
    let t0 = Time::from_nanos(1_764_000_000_123_456_789);
    for k in 0..20_i64 {
        let stamp = t0 + Duration::from_nanos(k * 10_000_001);
        let out = core.handle(Event::Odometry(Odometry {
            stamp,
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            left_ticks: 10 * k,
            right_ticks: 11 * k,
        }));
        match out.as_slice() {
            [Output::Pose(p)] => assert_eq!(p.stamp, stamp, "sample {k}"),
            other => panic!("sample {k}: {other:?}"),
        }
    }
}

#[test]
fn arrivals_before_any_schedule_are_an_error() {
    let mut c = core();
    c.solver.clear_schedule();
    assert_eq!(
        c.on_arrivals(&arrivals([1.0, 1.0, 0.5], &[])),
        Err(MsuError::NoSchedule)
    );
}

#[test]
fn an_empty_schedule_under_the_current_version_is_refused_and_fixes_go_on() {
    let mut c = core();
    let empty = Schedule {
        emissions: Vec::new(),
        ..schedule()
    };
    assert_refused_and_fixes_go_on(&mut c, empty);
}

/// Nothing in it could be fired, so nothing in it is taken, whatever its
/// epoch and version claim.
#[test]
fn an_unfireable_schedule_of_a_newer_epoch_is_refused_and_fixes_go_on() {
    let mut c = core();
    let base = schedule();
    let newer = |s: Schedule| Schedule {
        epoch: base.epoch + 1,
        version: base.version + 1,
        ..s
    };
    let empty = newer(Schedule {
        emissions: Vec::new(),
        ..base.clone()
    });
    assert_refused_and_fixes_go_on(&mut c, empty);
    let one_ns = newer(Schedule {
        cycle_period: Duration::from_nanos(1),
        slot_length: Duration::from_nanos(1),
        ..base.clone()
    });
    assert_refused_and_fixes_go_on(&mut c, one_ns);
}

fn assert_refused_and_fixes_go_on(c: &mut MsuCore, bad: Schedule) {
    let out = c.handle(crate::events::Event::Schedule(bad));
    assert!(
        matches!(
            out.as_slice(),
            [crate::events::Output::Refused {
                input: crate::events::InputKind::Schedule,
                error: MsuError::Schedule(_)
            }]
        ),
        "{out:?}"
    );
    assert!(matches!(
        c.on_arrivals(&arrivals([1.0, 1.0, 0.5], &[])),
        Ok(Some(_))
    ));
}
