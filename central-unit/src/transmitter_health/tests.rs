use ickon_proto::msg::robot::{Fix, FixQuality};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};

use super::*;

/// A fix at `p` that heard every transmitter within `near_m` in sight,
/// but for `missing`; `rejected` are heard but not used; `residual` gives
/// each used one's residual.
fn fix_at(
    site: &Site,
    p: [f64; 2],
    missing: &[u32],
    rejected: &[u32],
    residual: impl Fn(u32) -> f64,
) -> Fix {
    let at = [p[0], p[1], site.msu.height_m];
    let mut used = Vec::new();
    let mut rejected_ids = Vec::new();
    for t in &site.transmitters {
        let d = (0..3)
            .map(|k| (t.position_m[k] - at[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        if d > 8.0 || !site.line_of_sight(t.position_m, at) || missing.contains(&t.id) {
            continue;
        }
        if rejected.contains(&t.id) {
            rejected_ids.push(t.id);
        } else {
            used.push(t.id);
        }
    }
    Fix {
        stamp: Time::ZERO,
        arrivals_seq: 0,
        x_m: at[0],
        y_m: at[1],
        z_m: at[2],
        covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-4],
        heading_rad: 0.0,
        heading_valid: false,
        residuals_m: used.iter().map(|&id| residual(id)).collect(),
        used,
        rejected: rejected_ids,
        quality: FixQuality::Good,
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
    }
}

/// A place on `lab` near transmitter `id`, and a cell-mate of it in range.
fn near(site: &Site, id: u32) -> [f64; 2] {
    let t = site.transmitter(id).unwrap();
    [t.position_m[0] + 0.3, t.position_m[1] + 0.2]
}

fn condition(h: &TransmitterHealth, id: u32) -> Condition {
    h.report(Time::ZERO)
        .iter()
        .find(|r| r.tx_id == id)
        .unwrap()
        .condition
}

/// Feeds `n` fixes, ten a second, from `at(k)` built by `fix(k, p)`.
fn feed(h: &mut TransmitterHealth, start: Time, n: u32, mut fix: impl FnMut(u32) -> Fix) -> Time {
    let mut now = start;
    for k in 0..n {
        h.observe(&fix(k), now);
        now = now + Duration::from_millis(100);
    }
    now
}

#[test]
fn a_dead_transmitter_is_flagged_within_a_few_seconds_and_its_neighbours_are_not() {
    let site = Site::default_site();
    let mut h = TransmitterHealth::new(&site, HealthConfig::default());
    let dead = site.transmitters[5].id;
    let p = near(&site, dead);
    // Heard at first: its counts remember it, its misses in a row do not.
    let now = feed(&mut h, Time::ZERO, 100, |_| {
        fix_at(&site, p, &[], &[], |_| 0.002)
    });
    assert_eq!(condition(&h, dead), Condition::Healthy);
    feed(&mut h, now, 20, |_| {
        fix_at(&site, p, &[dead], &[], |_| 0.002)
    });
    assert_eq!(condition(&h, dead), Condition::Dead);
    assert!(h.left_out().contains(&dead));
    assert_eq!(h.left_out().len(), 1, "{:?}", h.left_out());
    let r = h
        .report(Time::ZERO)
        .into_iter()
        .find(|r| r.tx_id == dead)
        .unwrap();
    assert!(
        TransmitterHealth::evidence(&r).contains("its cell's others"),
        "{r:?}"
    );
}

#[test]
fn a_weak_transmitter_heard_a_quarter_of_the_time_is_flagged_and_recovers() {
    let site = Site::default_site();
    let mut h = TransmitterHealth::new(&site, HealthConfig::default());
    let weak = site.transmitters[9].id;
    let p = near(&site, weak);
    let now = feed(&mut h, Time::ZERO, 200, |k| {
        let missing: &[u32] = if k % 4 == 0 { &[] } else { &[weak] };
        fix_at(&site, p, missing, &[], |_| 0.0)
    });
    assert_eq!(condition(&h, weak), Condition::Weak);
    // Repaired: heard every time again; while left out the MSUs list its
    // arrivals as rejected, once taken back they use them.
    let mut now = now;
    for _ in 0..300 {
        let rejected: &[u32] = if h.left_out().contains(&weak) {
            &[weak]
        } else {
            &[]
        };
        h.observe(&fix_at(&site, p, &[], rejected, |_| 0.0), now);
        now = now + Duration::from_millis(100);
    }
    assert_eq!(condition(&h, weak), Condition::Healthy);
    assert!(h.left_out().is_empty());
}

#[test]
fn a_moved_transmitter_whose_arrivals_fail_the_gates_is_flagged_and_stays_so() {
    let site = Site::default_site();
    let mut h = TransmitterHealth::new(&site, HealthConfig::default());
    let moved = site.transmitters[2].id;
    let p = near(&site, moved);
    let now = feed(&mut h, Time::ZERO, 100, |k| {
        let rejected: &[u32] = if k % 5 == 0 { &[] } else { &[moved] };
        fix_at(&site, p, &[], rejected, |id| {
            if id == moved { 0.08 } else { 0.0 }
        })
    });
    assert_eq!(condition(&h, moved), Condition::Moved);
    feed(&mut h, now, 100, |_| {
        fix_at(&site, p, &[], &[moved], |_| 0.0)
    });
    assert_eq!(condition(&h, moved), Condition::Moved);
}

#[test]
fn a_fleet_that_hears_everything_flags_nothing_and_garbage_fixes_change_nothing() {
    let site = Site::default_site();
    let mut h = TransmitterHealth::new(&site, HealthConfig::default());
    let (lo, hi) = site.bounds();
    let mut now = Time::ZERO;
    for k in 0..2000u32 {
        let f = f64::from(k) / 2000.0;
        let p = [
            lo[0] + f * (hi[0] - lo[0]),
            lo[1] + (0.3 + 0.4 * f) * (hi[1] - lo[1]),
        ];
        // One arrival in twenty lost anywhere, as the air and the gates do.
        let lost: Vec<u32> = site
            .transmitters
            .iter()
            .filter(|t| (t.id + k) % 20 == 0)
            .map(|t| t.id)
            .collect();
        h.observe(&fix_at(&site, p, &lost, &[], |_| 0.003), now);
        now = now + Duration::from_millis(100);
    }
    assert!(h.left_out().is_empty(), "{:?}", h.left_out());
    let mut garbage = fix_at(
        &site,
        near(&site, site.transmitters[0].id),
        &[],
        &[],
        |_| 0.0,
    );
    garbage.x_m = f64::NAN;
    // Time passes with every fix, garbage or not; nothing else changes.
    h.observe(&garbage, now);
    let before = h.report(now);
    h.observe(&garbage, now);
    let mut short = garbage.clone();
    short.x_m = 1.0;
    short.residuals_m.pop();
    h.observe(&short, now);
    assert_eq!(h.report(now), before);
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// A transmitter of the default site that is 0.3 m east of its surveyed
/// place, and the spot beside it the fixes that flag it are taken at.
struct MovedScene {
    site: Site,
    id: u32,
    surveyed: [f64; 3],
    truth: [f64; 3],
    p: [f64; 2],
}

impl MovedScene {
    fn new() -> Self {
        let site = Site::default_site();
        let id = site.transmitters[2].id;
        let surveyed = site.transmitter(id).unwrap().position_m;
        let p = near(&site, id);
        Self {
            id,
            surveyed,
            truth: [surveyed[0] + 0.3, surveyed[1], surveyed[2]],
            p,
            site,
        }
    }

    /// 100 fixes at `p` that mostly reject it, 8 cm late: it is flagged
    /// moved. The time after them.
    fn flag(&self, h: &mut TransmitterHealth) -> Time {
        let moved = self.id;
        let now = feed(h, Time::ZERO, 100, |k| {
            let rejected: &[u32] = if k % 5 == 0 { &[] } else { &[moved] };
            fix_at(&self.site, self.p, &[], rejected, |id| {
                if id == moved { 0.08 } else { 0.0 }
            })
        });
        assert_eq!(condition(h, moved), Condition::Moved);
        now
    }

    /// `n` fixes around it that list it as left out, with its residual
    /// against `solved_at`, the place each was solved with. The time after
    /// them.
    fn drive(&self, h: &mut TransmitterHealth, now: Time, solved_at: [f64; 3], n: u32) -> Time {
        let offset: [f64; 3] = std::array::from_fn(|a| solved_at[a] - self.surveyed[a]);
        let solved_with = BTreeMap::from([(self.id, offset)]);
        let mut now = now;
        for k in 0..n {
            let a = f64::from(k) * 0.37;
            // An ellipse on the room's side of the transmitter.
            let at = [self.p[0] + 1.0 * a.cos(), self.p[1] - 0.75 + 0.75 * a.sin()];
            let mut fix = fix_at(&self.site, at, &[], &[self.id], |_| 0.0);
            let receiver = [fix.x_m, fix.y_m, fix.z_m];
            fix.unused = vec![self.id];
            fix.unused_residuals_m = vec![dist(self.truth, receiver) - dist(solved_at, receiver)];
            h.observe(&fix, now);
            h.observe_unused("r1", &fix, &solved_with, now);
            now = now + Duration::from_millis(100);
        }
        now
    }
}

#[test]
fn a_moved_transmitter_is_surveyed_again_from_its_unused_arrivals_and_taken_back() {
    let scene = MovedScene::new();
    let (site, moved, truth, p) = (&scene.site, scene.id, scene.truth, scene.p);
    let mut h = TransmitterHealth::new(site, HealthConfig::default());
    let mut now = scene.flag(&mut h);
    now = scene.drive(&mut h, now, scene.surveyed, 30);
    assert!(h.resurveyed(moved).is_none(), "30 fixes are too few");
    now = scene.drive(&mut h, now, scene.surveyed, 20);
    let placed = h.resurveyed(moved).expect("placed");
    assert!(dist(placed.position_m, truth) < 0.005, "{placed:?}");
    assert_eq!(condition(&h, moved), Condition::Moved);
    // Published there: the fixes solved with it there agree, and it is
    // taken back; none of its neighbours was ever flagged.
    h.mark_resurveyed(moved, placed.position_m);
    now = scene.drive(&mut h, now, placed.position_m, 19);
    assert_eq!(
        condition(&h, moved),
        Condition::Moved,
        "19 fixes are too few"
    );
    // The operator sees where the fleet placed it while it is checked.
    let report = |h: &TransmitterHealth, now: Time| {
        h.report(now)
            .into_iter()
            .find(|r| r.tx_id == moved)
            .expect("reported")
    };
    let r = report(&h, now);
    assert_eq!(r.resurveyed_m, Some(placed.position_m));
    let [x, y, z] = placed.position_m;
    let evidence = TransmitterHealth::evidence(&r);
    assert!(
        evidence.contains(&format!(
            "surveyed again by the fleet at ({x:.3}, {y:.3}, {z:.3}) m"
        )),
        "{evidence}"
    );
    now = scene.drive(&mut h, now, placed.position_m, 1);
    assert_eq!(condition(&h, moved), Condition::Healthy);
    assert_eq!(report(&h, now).resurveyed_m, None, "taken back");
    assert!(h.left_out().is_empty(), "{:?}", h.left_out());
    assert!(h.moved().is_empty());
    // Until the MSUs have the calibration that takes it back, their fixes
    // still leave it out and list its arrivals as rejected: that is no
    // evidence of a move. Counted as rejections, they would flag it again.
    let in_flight = |_| fix_at(site, p, &[], &[moved], |_| 0.0);
    let mut counted = h.clone();
    feed(&mut counted, now, 20, in_flight);
    assert_eq!(condition(&counted, moved), Condition::Moved);
    let left_out = BTreeSet::from([moved]);
    for k in 0..20 {
        h.observe_solved(&in_flight(k), &left_out, now);
        now = now + Duration::from_millis(100);
    }
    assert_eq!(condition(&h, moved), Condition::Healthy);
    // Used again, with its residuals centred: it stays healthy.
    feed(&mut h, now, 100, |_| fix_at(site, p, &[], &[], |_| 0.0));
    assert_eq!(condition(&h, moved), Condition::Healthy);
}

#[test]
fn unused_residuals_of_a_healthy_transmitter_or_a_bad_fix_survey_nothing() {
    let site = Site::default_site();
    let mut h = TransmitterHealth::new(&site, HealthConfig::default());
    let id = site.transmitters[2].id;
    let p = near(&site, id);
    for k in 0..80 {
        let mut fix = fix_at(
            &site,
            [p[0] + 0.02 * f64::from(k), p[1]],
            &[],
            &[id],
            |_| 0.0,
        );
        fix.unused = vec![id];
        fix.unused_residuals_m = vec![0.3];
        h.observe_unused("r1", &fix, &BTreeMap::new(), Time::ZERO);
        // Unpaired lists: ignored whatever the transmitter's condition.
        fix.unused_residuals_m.clear();
        h.observe_unused("r1", &fix, &BTreeMap::new(), Time::ZERO);
    }
    assert!(h.resurveyed(id).is_none());
    assert!(h.resurveys.is_empty());
}

#[test]
fn a_transmitter_published_where_the_fleet_no_longer_places_it_is_not_taken_back() {
    let scene = MovedScene::new();
    let (site, moved, truth) = (&scene.site, scene.id, scene.truth);
    let mut h = TransmitterHealth::new(site, HealthConfig::default());
    let mut now = scene.flag(&mut h);
    now = scene.drive(&mut h, now, scene.surveyed, 60);
    assert!(h.resurveyed(moved).is_some());
    // Published 5 cm along the room from where it is: seen from below and
    // from both sides, its ranges barely change (the residuals' mean is
    // millimetres), but the fleet's fixes place it elsewhere.
    let off = [truth[0] + 0.05, truth[1], truth[2]];
    h.mark_resurveyed(moved, off);
    now = scene.drive(&mut h, now, off, 20);
    assert_eq!(condition(&h, moved), Condition::Moved);
    assert_eq!(h.resurveyed_at(moved), None, "to be surveyed again");
    // Published where it is: taken back.
    let placed = h.resurveyed(moved).expect("placed");
    assert!(dist(placed.position_m, truth) < 0.005, "{placed:?}");
    h.mark_resurveyed(moved, placed.position_m);
    scene.drive(&mut h, now, placed.position_m, 20);
    assert_eq!(condition(&h, moved), Condition::Healthy);
}
