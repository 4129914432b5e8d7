//! The fleet's survey calibration moves the transmitters the fix solver
//! uses and takes their lateness from their pseudo-ranges; a calibration
//! that cannot be right changes nothing.

use super::tests::{TX, arrivals_from, core_with};
use super::*;
use crate::events::{Event, InputKind, Output};
use ickon_fusion::estimator::build_by_name;
use ickon_proto::msg::control::TransmitterOffset;

/// Transmitter 5 really hangs 4 cm higher than surveyed.
fn true_tx() -> Vec<(u32, [f64; 3])> {
    TX.iter()
        .map(|&(id, [x, y, z])| (id, [x, y, if id == 5 { z + 0.04 } else { z }]))
        .collect()
}

fn calibration(version: u32, dz_5: f64) -> SurveyCalibration {
    SurveyCalibration {
        epoch: 1,
        version,
        fixes_taken: 100,
        offsets: TX
            .iter()
            .map(|&(tx_id, _)| TransmitterOffset {
                tx_id,
                offset_m: [0.0, 0.0, if tx_id == 5 { dz_5 } else { 0.0 }],
                sigma_m: [0.005; 3],
                late_m: 0.0,
                late_sigma_m: 0.003,
                left_out: false,
            })
            .collect(),
        speed_of_sound_m_s: 0.0,
        speed_of_sound_sigma_m_s: 0.0,
    }
}

fn worst_residual_m(fix: &Fix) -> f64 {
    fix.residuals_m.iter().fold(0.0, |m, r| m.max(r.abs()))
}

#[test]
fn a_calibration_moves_the_transmitter_and_the_fix_names_it() {
    let mut core = core_with("msu-raw");
    let at = [2.2, 1.1, 0.5];
    let before = core
        .on_arrivals(&arrivals_from(&true_tx(), at, &[]))
        .unwrap()
        .unwrap();
    assert_eq!(before.survey_version, 0);
    assert!(worst_residual_m(&before) > 5e-3, "{before:?}");
    assert_eq!(core.on_survey_calibration(&calibration(7, 0.04)), Ok(true));
    assert_eq!(core.survey_calibration(), Some((1, 7)));
    let after = core
        .on_arrivals(&arrivals_from(&true_tx(), at, &[]))
        .unwrap()
        .unwrap();
    assert_eq!(after.survey_version, 7);
    assert!(worst_residual_m(&after) < 1e-5, "{after:?}");
    assert!((after.x_m - at[0]).abs() < 1e-4 && (after.y_m - at[1]).abs() < 1e-4);
    // The same again, or an older one: nothing to do.
    assert_eq!(core.on_survey_calibration(&calibration(7, 0.04)), Ok(false));
    assert_eq!(core.on_survey_calibration(&calibration(6, 0.0)), Ok(false));
    assert_eq!(core.survey_calibration(), Some((1, 7)));
}

/// A core that has heard its robot (a calibration before the robot's
/// first input is not taken).
fn core_heard() -> MsuCore {
    let mut core = core_with("msu-raw");
    core.on_arrivals(&arrivals_from(&true_tx(), [2.2, 1.1, 0.5], &[]))
        .unwrap();
    core
}

#[test]
fn a_calibration_that_cannot_be_right_is_refused_and_changes_nothing() {
    let mut core = core_heard();
    // Version 0 names the surveyed positions: no calibration has it.
    assert!(matches!(
        core.on_survey_calibration(&calibration(0, 0.01)),
        Err(MsuError::Survey { .. })
    ));
    assert_eq!(core.on_survey_calibration(&calibration(3, 0.01)), Ok(true));
    let mut unknown = calibration(4, 0.0);
    unknown.offsets[0].tx_id = 99;
    let mut twice = calibration(4, 0.0);
    twice.offsets[1].tx_id = twice.offsets[0].tx_id;
    let mut other_epoch = calibration(4, 0.0);
    other_epoch.epoch = 2;
    let mut negative_sigma = calibration(4, 0.0);
    negative_sigma.offsets[2].sigma_m[1] = -1.0;
    let late = |late_m: f64, late_sigma_m: f64| {
        let mut c = calibration(4, 0.0);
        c.offsets[1].late_m = late_m;
        c.offsets[1].late_sigma_m = late_sigma_m;
        c
    };
    let speed = |m_s: f64, sigma_m_s: f64| {
        let mut c = calibration(4, 0.0);
        c.speed_of_sound_m_s = m_s;
        c.speed_of_sound_sigma_m_s = sigma_m_s;
        c
    };
    let site_m_s = core.solver.site_speed_of_sound_m_s();
    for bad in [
        speed(f64::NAN, 0.1),
        speed(f64::INFINITY, 0.1),
        speed(site_m_s * 1.06, 0.1),
        speed(site_m_s * 0.94, 0.1),
        speed(-343.0, 0.1),
        speed(site_m_s, -0.1),
        speed(site_m_s, f64::NAN),
        calibration(4, f64::NAN),
        // Beyond what even a transmitter surveyed again by the fleet may be.
        calibration(4, 1.1),
        calibration(4, -1e300),
        unknown,
        twice,
        other_epoch,
        negative_sigma,
        late(f64::NAN, 0.003),
        late(0.26, 0.003),
        late(-1e300, 0.003),
        late(0.01, -0.001),
        late(0.01, f64::INFINITY),
    ] {
        let out = core.handle(Event::Survey(bad.clone()));
        assert!(
            matches!(
                out.as_slice(),
                [Output::Refused {
                    input: InputKind::Survey,
                    error: MsuError::Survey { .. }
                }]
            ),
            "{bad:?}: {out:?}"
        );
        assert_eq!(core.survey_calibration(), Some((1, 3)), "{bad:?}");
    }
    let z5 = |core: &MsuCore| {
        core.solver
            .config()
            .transmitters
            .iter()
            .find(|t| t.tx_id == 5)
            .unwrap()
            .z_m
    };
    assert!((z5(&core) - 2.71).abs() < 1e-12);
    assert_eq!(core.speed_of_sound_m_s(), site_m_s);
    // Within its bound the learnt speed is solved with from the next cycle.
    assert_eq!(
        core.on_survey_calibration(&speed(site_m_s * 1.01, 0.2)),
        Ok(true)
    );
}

#[test]
fn before_any_schedule_or_input_a_calibration_waits_and_a_new_central_unit_starts_from_the_survey()
{
    let config = core_with("msu-raw").solver.config().clone();
    let mut fresh = MsuCore::new(config, build_by_name("msu-raw").unwrap());
    assert_eq!(
        fresh.on_survey_calibration(&calibration(1, 0.04)),
        Ok(false)
    );
    assert_eq!(fresh.survey_calibration(), None);
    // Nor before the robot's first input: a replay of a recording, which
    // starts there, could not tell whether the agent had heard it.
    let mut core = core_with("msu-raw");
    assert_eq!(core.on_survey_calibration(&calibration(2, 0.04)), Ok(false));
    let mut core = core_heard();
    assert_eq!(core.on_survey_calibration(&calibration(2, 0.04)), Ok(true));
    // The schedules of a central unit of a later epoch.
    let mut schedule = super::tests::schedule();
    schedule.epoch = 5;
    core.set_schedule(schedule).unwrap();
    assert_eq!(core.survey_calibration(), None);
    let fix = core
        .on_arrivals(&arrivals_from(&true_tx(), [2.2, 1.1, 0.5], &[]))
        .unwrap()
        .unwrap();
    assert_eq!(fix.survey_version, 0);
}

#[test]
fn a_calibrations_lateness_is_taken_from_the_transmitters_pseudo_ranges() {
    let mut core = core_heard();
    let at = [1.6, 2.7, 0.5];
    // Transmitters 2 and 3 (as if of a cell whose sync is off) arrive
    // 3 cm of path late.
    let late_arrivals = || arrivals_from(&TX, at, &[(2, 0.03), (3, 0.03)]);
    let before = core.on_arrivals(&late_arrivals()).unwrap().unwrap();
    assert!(worst_residual_m(&before) > 5e-3, "{before:?}");
    let mut c = calibration(5, 0.0);
    for o in &mut c.offsets {
        if o.tx_id == 2 || o.tx_id == 3 {
            o.late_m = 0.03;
        }
    }
    assert_eq!(core.on_survey_calibration(&c), Ok(true));
    let after = core.on_arrivals(&late_arrivals()).unwrap().unwrap();
    assert_eq!(after.survey_version, 5);
    assert!(worst_residual_m(&after) < 1e-5, "{after:?}");
    assert!((after.x_m - at[0]).abs() < 1e-4 && (after.y_m - at[1]).abs() < 1e-4);
    // A calibration that no longer says so: the arrivals are taken as
    // they come again.
    assert_eq!(core.on_survey_calibration(&calibration(6, 0.0)), Ok(true));
    let again = core.on_arrivals(&late_arrivals()).unwrap().unwrap();
    assert!(worst_residual_m(&again) > 5e-3, "{again:?}");
}
