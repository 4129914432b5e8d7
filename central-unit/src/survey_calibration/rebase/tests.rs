use ickon_proto::site::Site;

use super::super::tests::{Noise, config, fix_at, places, true_offsets};
use super::super::{Applied, AppliedLate, SurveyCalibration};
use super::*;

/// A calibration of `lab` that learnt from 300 fixes of the transmitters
/// where they really hang.
fn learnt(site: &Site) -> SurveyCalibration {
    let mut c = SurveyCalibration::new(site, config());
    let truth = true_offsets(site, true);
    let mut noise = Noise(11);
    for at in places(300, &mut noise) {
        if let Some(fix) = fix_at(site, at, &truth, &Applied::new(), 0, &mut noise) {
            let _ = c.take_fix(&fix, &Applied::new(), &AppliedLate::new());
        }
    }
    assert!(c.fixes_taken() > 200);
    c
}

#[test]
fn surveying_one_again_leaves_every_other_parameter_where_it_was() {
    let site = Site::default_site();
    let mut c = learnt(&site);
    let before = c.corrections();
    let speed = c.speed_of_sound();
    let moved = site.transmitters[3].id;
    let surveyed = site.transmitters[3].position_m;
    let at = [surveyed[0] + 0.3, surveyed[1], surveyed[2]];
    c.rebase(moved, at, [0.01, 0.01, 0.02]).unwrap();
    let after = c.corrections();
    for (b, a) in before.iter().zip(&after) {
        if a.tx_id == moved {
            let expected = [0.3, 0.0, 0.0];
            assert!(
                (0..3).all(|k| (a.offset_m[k] - expected[k]).abs() < 1e-9),
                "{a:?}"
            );
            assert!((a.sigma_m[0] - 0.01).abs() < 1e-9 && (a.sigma_m[2] - 0.02).abs() < 1e-9);
            continue;
        }
        for k in 0..3 {
            assert!(
                (a.offset_m[k] - b.offset_m[k]).abs() < 1e-9,
                "{b:?} -> {a:?}"
            );
            assert!((a.sigma_m[k] - b.sigma_m[k]).abs() < 1e-9, "{b:?} -> {a:?}");
        }
        assert!((a.late_m - b.late_m).abs() < 1e-9, "{b:?} -> {a:?}");
    }
    assert!((c.speed_of_sound().speed_m_s - speed.speed_m_s).abs() < 1e-9);
    assert_eq!(c.base_of(moved), Some(at));
    assert_eq!(c.rebased(), vec![(moved, c.rebased_of(moved))]);
}

#[test]
fn it_learns_on_from_the_new_position_and_keeps_it_across_a_restart() {
    let site = Site::default_site();
    let mut c = learnt(&site);
    let moved = site.transmitters[3].id;
    let surveyed = site.transmitters[3].position_m;
    // Surveyed again 1 cm short of where it really is now.
    let mut truth = true_offsets(&site, true);
    truth.insert(moved, [0.3, 0.0, 0.0]);
    let at = [surveyed[0] + 0.29, surveyed[1], surveyed[2]];
    c.rebase(moved, at, [0.02; 3]).unwrap();
    let applied: Applied = c
        .corrections()
        .iter()
        .map(|k| (k.tx_id, k.offset_m))
        .collect();
    let mut noise = Noise(12);
    for p in places(400, &mut noise) {
        if let Some(fix) = fix_at(&site, p, &truth, &applied, 0, &mut noise) {
            let _ = c.take_fix(&fix, &applied, &AppliedLate::new());
        }
    }
    let got = c
        .corrections()
        .into_iter()
        .find(|k| k.tx_id == moved)
        .unwrap();
    assert!((got.offset_m[0] - 0.3).abs() < 0.008, "{got:?}");
    let saved = c.saved(&site);
    let again = SurveyCalibration::restored(&site, config(), &saved).unwrap();
    assert_eq!(again.base_of(moved), Some(at));
    assert_eq!(again.corrections(), c.corrections());
}

#[test]
fn a_position_out_of_bounds_or_unknown_transmitter_is_refused() {
    let site = Site::default_site();
    let mut c = SurveyCalibration::new(&site, config());
    let t = &site.transmitters[0];
    let far = [t.position_m[0] + 1.5, t.position_m[1], t.position_m[2]];
    assert_eq!(
        c.rebase(t.id, far, [0.01; 3]),
        Err(RebaseRefused::OutOfBounds)
    );
    assert_eq!(
        c.rebase(t.id, [f64::NAN, 0.0, 0.0], [0.01; 3]),
        Err(RebaseRefused::OutOfBounds)
    );
    assert_eq!(
        c.rebase(t.id, t.position_m, [0.0; 3]),
        Err(RebaseRefused::OutOfBounds)
    );
    assert_eq!(
        c.rebase(999_999, t.position_m, [0.01; 3]),
        Err(RebaseRefused::UnknownTransmitter)
    );
    assert!(c.rebased().is_empty());
}
