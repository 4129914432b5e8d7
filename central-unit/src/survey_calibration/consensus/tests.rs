use super::super::tests::{Noise, config, fix_at, places, true_offsets};
use super::super::{Applied, SurveyPublisher, TransmitterCorrection};
use super::*;
use ickon_proto::msg::robot::Fix;
use ickon_proto::site::Site;
use ickon_proto::time::Duration;
use nalgebra::{DMatrix, DVector, Vector3};

/// What a forger's fix says: the honest `fix`'s residuals plus what
/// transmitters displaced by `forged` would add to them, with the fix's
/// own position and offset taken out as an MSU's solver takes them out
/// (residuals of a least-squares fix are orthogonal to its unknowns).
fn forged(site: &Site, fix: &Fix, forged: &Applied) -> Fix {
    let receiver = Vector3::new(fix.x_m, fix.y_m, fix.z_m);
    let toward: Vec<Vector3<f64>> = fix
        .used
        .iter()
        .map(|id| {
            let t = site.transmitter(*id).expect("a site transmitter");
            (Vector3::from(t.position_m) - receiver).normalize()
        })
        .collect();
    let n = toward.len();
    let a = DMatrix::from_fn(n, 3, |i, k| [-toward[i].x, -toward[i].y, 1.0][k]);
    let ata_inv = (a.transpose() * &a)
        .try_inverse()
        .expect("a fix's geometry");
    let projector = DMatrix::identity(n, n) - &a * ata_inv * a.transpose();
    let added = DVector::from_fn(n, |i, _| {
        toward[i].dot(&Vector3::from(forged[&fix.used[i]]))
    });
    let extra = projector * added;
    Fix {
        residuals_m: fix
            .residuals_m
            .iter()
            .zip(extra.iter())
            .map(|(e, x)| e + x)
            .collect(),
        ..fix.clone()
    }
}

/// Every transmitter 20 cm off its place: up for one, down for the next.
fn twenty_cm_off(site: &Site) -> Applied {
    site.transmitters
        .iter()
        .enumerate()
        .map(|(i, t)| (t.id, [0.0, 0.0, if i % 2 == 0 { 0.2 } else { -0.2 }]))
        .collect()
}

/// A fleet driving over the lab, ten fixes a second each, the central
/// unit publishing its calibration every second and every fix solved with
/// the last one.
struct Fleet {
    site: Site,
    truth: Applied,
    publisher: SurveyPublisher,
    noise: Noise,
    /// The forgers' own draws, apart: a fleet with and without them gets
    /// the same honest fixes.
    forger_noise: Noise,
    applied: Applied,
    version: u32,
    step: u64,
    /// Fixes the publisher read (of every robot).
    read: u64,
    /// The forgers' fixes are taken without the check (what the
    /// calibration would learn without it).
    unchecked_forgers: bool,
}

impl Fleet {
    fn new(seed: u64) -> Self {
        let site = Site::default_site();
        let truth = true_offsets(&site, true);
        let publisher = SurveyPublisher::new(&site, config());
        Self {
            site,
            truth,
            publisher,
            noise: Noise(seed),
            forger_noise: Noise(seed ^ 0x5eed),
            applied: Applied::new(),
            version: 0,
            step: 0,
            read: 0,
            unchecked_forgers: false,
        }
    }

    fn now(&self) -> Time {
        Time::ZERO + Duration::from_millis(100 * self.step as i64)
    }

    /// One tenth of a second: a fix of each of `honest` robots (`r1`,
    /// `r2`, ...) and of each robot in `forgers` (forging `offsets`).
    fn step(&mut self, honest: usize, forgers: &[(&str, &Applied)]) {
        let now = self.now();
        if self.step.is_multiple_of(10)
            && let Some(published) = self.publisher.due(now, 1)
        {
            self.version = published.version;
            self.applied = published
                .offsets
                .iter()
                .map(|o| (o.tx_id, o.offset_m))
                .collect();
        }
        for k in 0..honest {
            if let Some(fix) = self.fix(false) {
                let offered = self.publisher.offer_fix(&format!("r{}", k + 1), &fix, now);
                self.read += u64::from(offered.is_ok());
            }
        }
        for (robot, offsets) in forgers {
            if let Some(fix) = self.fix(true) {
                let fix = forged(&self.site, &fix, offsets);
                let offered = if self.unchecked_forgers {
                    self.publisher.take_fix(&fix)
                } else {
                    self.publisher.offer_fix(robot, &fix, now)
                };
                self.read += u64::from(offered.is_ok());
            }
        }
        self.step += 1;
    }

    fn fix(&mut self, forger: bool) -> Option<Fix> {
        let noise = if forger {
            &mut self.forger_noise
        } else {
            &mut self.noise
        };
        let at = places(1, noise)[0];
        fix_at(
            &self.site,
            at,
            &self.truth,
            &self.applied,
            self.version,
            noise,
        )
    }

    /// Fixes read and neither taken nor held: kept out by the check.
    fn kept_out(&self) -> u64 {
        let calibration = self.publisher.calibration();
        self.read - calibration.fixes_taken() - self.publisher.fixes_held() as u64
    }

    /// How far the learnt heights moved toward `forgery`, metres: the mean
    /// over the transmitters of each one's height correction along the
    /// forged direction of its height.
    fn toward(&self, forgery: &Applied) -> f64 {
        let learnt = self.corrections();
        let along: Vec<f64> = learnt
            .iter()
            .map(|c| c.offset_m[2] * forgery[&c.tx_id][2].signum())
            .collect();
        along.iter().sum::<f64>() / along.len() as f64
    }

    fn check(&self, robot: &str) -> RobotCheck {
        self.publisher.robot_check(robot)
    }

    fn corrections(&self) -> Vec<TransmitterCorrection> {
        self.publisher.calibration().corrections()
    }
}

#[test]
fn a_robot_placing_every_transmitter_20_cm_off_is_quarantined_before_it_teaches_anything() {
    let mut clean = Fleet::new(11);
    let mut attacked = Fleet::new(11);
    let off = twenty_cm_off(&attacked.site);
    let mut quarantined_at = None;
    for step in 0..300 {
        clean.step(3, &[]);
        attacked.step(3, &[("r4", &off)]);
        if quarantined_at.is_none() && attacked.check("r4").check == Check::Quarantined {
            quarantined_at = Some(step);
        }
    }
    // Judged on its first window: within about two seconds.
    let at = quarantined_at.expect("the forger is quarantined");
    assert!(at < 2 * WINDOW_FIXES, "quarantined at step {at}");
    let r4 = attacked.check("r4");
    assert_eq!(r4.check, Check::Quarantined);
    let (misfit, bound) = (r4.misfit_m.unwrap(), r4.bound_m.unwrap());
    assert!(misfit > 0.05 && bound < 0.05, "{r4:?}");
    for robot in ["r1", "r2", "r3"] {
        assert_eq!(attacked.check(robot).check, Check::Agrees, "{robot}");
        assert_eq!(attacked.check(robot).fixes_quarantined, 0);
    }
    // Not one forged fix was learnt from: the calibration is the one the
    // honest fleet learns alone, to the last bit.
    assert_eq!(
        attacked.publisher.calibration().fixes_taken(),
        clean.publisher.calibration().fixes_taken()
    );
    assert_eq!(attacked.corrections(), clean.corrections());
    // Without the check the same forger moves the heights toward what it
    // forged, several millimetres on average (its fixes down-weighted as
    // outliers, against three honest robots'), where the honest fleet's
    // calibration stays within a few millimetres of nothing: what the
    // live test's bound of 5 mm tells apart.
    let mut unchecked = Fleet::new(11);
    unchecked.unchecked_forgers = true;
    for _ in 0..300 {
        unchecked.step(3, &[("r4", &off)]);
    }
    let (honest, bent) = (clean.toward(&off), unchecked.toward(&off));
    eprintln!(
        "heights toward the forgery: {:.1} mm with the check, {:.1} mm without",
        1e3 * honest,
        1e3 * bent
    );
    assert!(honest.abs() < 0.003 && bent > 0.006, "{honest} {bent}");
    // Every fix kept out is counted, and all of them are the forger's.
    assert_eq!(attacked.kept_out(), r4.fixes_quarantined);
    assert_eq!(clean.kept_out(), 0);
    assert!(r4.fixes_quarantined > 100, "{r4:?}");
}

#[test]
fn an_honest_fleet_is_never_quarantined_and_learns_from_every_fix() {
    let mut fleet = Fleet::new(5);
    for _ in 0..600 {
        fleet.step(4, &[]);
        for robot in ["r1", "r2", "r3", "r4"] {
            assert_ne!(fleet.check(robot).check, Check::Quarantined, "{robot}");
        }
    }
    assert_eq!(fleet.kept_out(), 0);
    for robot in ["r1", "r2", "r3", "r4"] {
        let c = fleet.check(robot);
        assert_eq!(c.check, Check::Agrees);
        assert_eq!(c.fixes_quarantined, 0);
        // The bound sits a few centimetres above an honest misfit.
        assert!(c.misfit_m.unwrap() < c.bound_m.unwrap(), "{c:?}");
    }
}

#[test]
fn a_fleet_of_one_is_unchecked_and_still_calibrates() {
    let mut fleet = Fleet::new(7);
    for _ in 0..WINDOW_FIXES - 1 {
        fleet.step(1, &[]);
    }
    assert_eq!(fleet.check("r1").check, Check::Checking);
    assert_eq!(fleet.publisher.calibration().fixes_taken(), 0);
    for _ in 0..300 {
        fleet.step(1, &[]);
    }
    let c = fleet.check("r1");
    assert_eq!(c.check, Check::Unchecked);
    assert_eq!(c.check.label(), "unchecked: no other robot to compare");
    assert_eq!(c.bound_m, None);
    // Every fix but the window held is learnt from.
    assert_eq!(fleet.kept_out(), 0);
    assert_eq!(fleet.publisher.fixes_held(), WINDOW_FIXES);
    assert!(fleet.publisher.calibration().fixes_taken() > 200);
}

#[test]
fn a_lone_forger_is_unchecked_too_and_a_robot_that_stopped_is_no_reference() {
    let mut fleet = Fleet::new(9);
    let off = twenty_cm_off(&fleet.site);
    // Another robot gave fixes, then stopped for longer than a reference
    // is kept.
    for _ in 0..50 {
        fleet.step(1, &[]);
    }
    fleet.step += (REFERENCE_AGE_S * 10.0) as u64 + 10;
    for _ in 0..50 {
        fleet.step(0, &[("r2", &off)]);
    }
    assert_eq!(fleet.check("r2").check, Check::Unchecked);
    // When r1 comes back, r2 is compared with it and quarantined.
    for _ in 0..50 {
        fleet.step(1, &[("r2", &off)]);
    }
    assert_eq!(fleet.check("r2").check, Check::Quarantined);
}

/// A fix to hold (what it says does not matter to the check itself).
fn any_read() -> ReadFix {
    let mut fleet = Fleet::new(3);
    loop {
        if let Some(fix) = fleet.fix(false) {
            let calibration = fleet.publisher.calibration();
            if let Ok(read) = calibration.read_fix(&fix, &Applied::new(), &Default::default()) {
                return read;
            }
        }
    }
}

#[test]
fn a_quarantined_robot_is_released_only_well_within_the_bound() {
    let read = any_read();
    let mut check = Consensus::new(0.01);
    let at = |k: usize| Time::ZERO + Duration::from_millis(100 * k as i64);
    // Two robots whose misfits are all 10 mm: the spread is the noise's
    // floor, 7.07 mm; quarantine beyond 31.2 mm, release within 24.1 mm.
    let mut k = 0;
    let mut offer = |check: &mut Consensus, misfit_r3: f64| {
        for robot in ["r1", "r2"] {
            let _ = check.offer(robot, read.clone(), 0.010, at(k));
        }
        let taken = check.offer("r3", read.clone(), misfit_r3, at(k));
        k += 1;
        taken
    };
    for _ in 0..WINDOW_FIXES {
        offer(&mut check, 0.012);
    }
    assert_eq!(check.robot("r3").check, Check::Agrees);
    let bound = check.robot("r3").bound_m.unwrap();
    assert!((bound - (0.010 + 3.0 * 0.01 / 2f64.sqrt())).abs() < 1e-12);
    // Just below the bound: still agrees, and its fixes are learnt.
    let mut taken = 0;
    for _ in 0..WINDOW_FIXES {
        taken += usize::from(offer(&mut check, bound - 1e-4).is_some());
    }
    assert_eq!(check.robot("r3").check, Check::Agrees);
    assert_eq!(taken, WINDOW_FIXES);
    // Beyond it: quarantined once half its window is, its held fixes
    // counted out.
    let mut steps = 0;
    while check.robot("r3").check != Check::Quarantined {
        assert!(offer(&mut check, 0.05).is_some() || steps >= WINDOW_FIXES / 2);
        steps += 1;
        assert!(steps <= WINDOW_FIXES, "never quarantined");
    }
    // The window it was judged on: the full one and the fix just in.
    assert_eq!(check.robot("r3").fixes_quarantined, WINDOW_FIXES as u64 + 1);
    // Between the release and the quarantine bounds: stays out.
    let release = 0.010 + 2.0 * 0.01 / 2f64.sqrt();
    for _ in 0..3 * WINDOW_FIXES {
        assert!(offer(&mut check, release + 1e-3).is_none());
    }
    assert_eq!(check.robot("r3").check, Check::Quarantined);
    assert_eq!(check.robot("r3").bound_m, Some(release));
    // Within the release bound for over half a window: let in again,
    // its window (judged agreeing) learnt from as new fixes come.
    for _ in 0..WINDOW_FIXES / 2 {
        assert!(offer(&mut check, 0.011).is_none());
        assert_eq!(check.robot("r3").check, Check::Quarantined);
    }
    assert!(offer(&mut check, 0.011).is_some());
    assert_eq!(check.robot("r3").check, Check::Agrees);
    // Kept out: the window it was quarantined on, then every fix that left
    // a full window while it was out.
    assert_eq!(
        check.robot("r3").fixes_quarantined,
        (WINDOW_FIXES + 1 + 2 * WINDOW_FIXES + WINDOW_FIXES / 2) as u64
    );
}

#[test]
fn the_reference_spread_is_the_fleets_when_it_is_wider_than_the_noise() {
    let read = any_read();
    let mut check = Consensus::new(0.001);
    // The others' misfits spread over 10 to 30 mm (their MAD is 5 mm).
    for i in 0..2 * WINDOW_FIXES {
        let misfit = 0.010 + 0.020 * (i % 5) as f64 / 4.0;
        let _ = check.offer(
            if i % 2 == 0 { "r1" } else { "r2" },
            read.clone(),
            misfit,
            Time::ZERO,
        );
    }
    for _ in 0..WINDOW_FIXES {
        let _ = check.offer("r3", read.clone(), 0.040, Time::ZERO);
    }
    let r3 = check.robot("r3");
    assert_eq!(r3.check, Check::Agrees, "{r3:?}");
    assert!(
        (r3.bound_m.unwrap() - (0.020 + 3.0 * 1.4826 * 0.005)).abs() < 1e-9,
        "{r3:?}"
    );
}

/// The selection's median is the sorted list's middle (the mean of the
/// two middle values for an even count), for lengths odd and even.
#[test]
fn median_is_the_sorted_middle() {
    let mut state = 12_345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    assert_eq!(super::median(&mut []), 0.0);
    for n in 1..60 {
        let values: Vec<f64> = (0..n).map(|_| next() - 0.3).collect();
        let mut sorted = values.clone();
        sorted.sort_by(f64::total_cmp);
        let expected = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
        };
        assert_eq!(super::median(&mut values.clone()), expected, "n = {n}");
    }
}

#[test]
fn a_robot_that_leaves_is_forgotten_unless_it_was_quarantined() {
    let read = any_read();
    let mut check = Consensus::new(0.01);
    let at = |k: usize| Time::ZERO + Duration::from_millis(100 * k as i64);
    for k in 0..WINDOW_FIXES {
        for robot in ["r1", "r2"] {
            let _ = check.offer(robot, read.clone(), 0.010, at(k));
        }
        let _ = check.offer("r3", read.clone(), 0.5, at(k));
    }
    assert_eq!(check.robot("r3").check, Check::Quarantined);
    assert_ne!(check.robot("r1").check, Check::Quarantined);
    assert_eq!(check.held(), 2 * WINDOW_FIXES);
    // The window it held is handed back to be learnt, and it is forgotten.
    assert_eq!(check.forget("r1").len(), WINDOW_FIXES);
    assert_eq!(check.robot("r1").check, Check::Checking);
    // A quarantined robot's standing stays; nothing of it is learnt.
    assert!(check.forget("r3").is_empty());
    assert_eq!(check.robot("r3").check, Check::Quarantined);
    assert_eq!(check.robot("r3").fixes_quarantined, WINDOW_FIXES as u64);
    assert_eq!(check.len(), 2);
    assert_eq!(check.held(), WINDOW_FIXES);
    assert!(check.forget("nobody").is_empty());
}
