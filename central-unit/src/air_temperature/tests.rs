use super::*;

fn at(s: f64) -> Time {
    Time::from_secs_f64(s)
}

fn sensors() -> AirTemperatures {
    AirTemperatures::new(["c1", "c2", "c3"])
}

/// Readings that a working sensor gives: a little noise on the last digit.
fn feed_good(a: &mut AirTemperatures, cell: &str, from_s: f64, n: u32, t_c: f64) {
    for k in 0..n {
        let wobble = if k % 2 == 0 { 0.01 } else { -0.01 };
        a.observe(cell, t_c + wobble, at(from_s + f64::from(k)))
            .expect("a working sensor's reading is accepted");
    }
}

fn board<'a>(r: &'a [BoardAirStatus], cell: &str) -> &'a BoardAirStatus {
    r.iter().find(|b| b.cell_id == cell).expect("reported")
}

#[test]
fn plausible_readings_are_evidence_of_the_speed_at_their_median() {
    let mut a = sensors();
    feed_good(&mut a, "c1", 0.0, 3, 20.0);
    feed_good(&mut a, "c2", 0.0, 3, 26.0);
    feed_good(&mut a, "c3", 0.0, 3, 24.0);
    let site = speed_of_sound_at_c(20.0);
    let e = a.evidence(at(3.0), site).expect("fresh readings");
    let want = speed_of_sound_at_c(24.01) / site - 1.0;
    assert!((e.scale - want).abs() < 1e-4, "{} vs {want}", e.scale);
    // Honest-wide: at least the shared placement's two degrees.
    let sigma_c = e.variance.sqrt() * site / 0.6;
    assert!(sigma_c > PLACEMENT_SIGMA_C * 0.95, "sigma {sigma_c} C");
    // Stale readings are no evidence.
    assert!(a.evidence(at(3.0 + FRESH_S + 1.0), site).is_none());
}

#[test]
fn bad_readings_are_refused_counted_and_never_used() {
    let mut a = sensors();
    let site = speed_of_sound_at_c(20.0);
    assert_eq!(
        a.observe("c1", f64::NAN, at(0.0)),
        Err(AirRefused::NotANumber)
    );
    assert_eq!(a.observe("c1", -40.5, at(1.0)), Err(AirRefused::OutOfRange));
    assert_eq!(a.observe("c1", 85.5, at(2.0)), Err(AirRefused::OutOfRange));
    assert_eq!(
        a.observe("c1", f64::INFINITY, at(2.5)),
        Err(AirRefused::OutOfRange)
    );
    assert!(a.evidence(at(3.0), site).is_none(), "nothing accepted yet");
    // A jump of more than 20 degrees within a second of an accepted one.
    a.observe("c1", 21.0, at(3.0)).unwrap();
    assert_eq!(a.observe("c1", 42.0, at(3.9)), Err(AirRefused::Jump));
    assert_eq!(a.observe("c1", -0.5, at(3.95)), Err(AirRefused::Jump));
    // What was refused did not move the evidence.
    let e = a.evidence(at(5.0), site).unwrap();
    assert!((e.scale - (speed_of_sound_at_c(21.0) / site - 1.0)).abs() < 1e-12);
    // Unknown cells are counted apart, never kept.
    assert_eq!(a.observe("c9", 20.0, at(5.0)), Err(AirRefused::UnknownCell));
    assert_eq!(a.unknown_cell(), 1);
    let cells: Vec<String> = ["c1", "c2", "c3"].map(String::from).to_vec();
    let r = a.report(at(5.0), &cells);
    let c1 = board(&r, "c1");
    assert_eq!(
        (
            c1.refused_not_a_number,
            c1.refused_out_of_range,
            c1.refused_jump,
            c1.refused_stuck,
            c1.accepted
        ),
        (1, 3, 2, 0, 1)
    );
    assert_eq!(c1.state, "used");
    assert_eq!(board(&r, "c2").state, "no sensor");
}

#[test]
fn a_stuck_sensor_is_refused_and_its_board_not_used_until_it_moves() {
    let mut a = sensors();
    let site = speed_of_sound_at_c(20.0);
    for k in 0..STUCK_READINGS {
        a.observe("c2", 22.5, at(f64::from(k))).unwrap();
    }
    let n = f64::from(STUCK_READINGS);
    assert_eq!(a.observe("c2", 22.5, at(n)), Err(AirRefused::Stuck));
    assert_eq!(a.observe("c2", 22.5, at(n + 1.0)), Err(AirRefused::Stuck));
    assert!(
        a.evidence(at(n + 1.0), site).is_none(),
        "a stuck board is no evidence, though its last readings were accepted"
    );
    let cells = vec!["c2".to_string()];
    let r = a.report(at(n + 1.0), &cells);
    assert_eq!((r[0].state.as_str(), r[0].refused_stuck), ("stuck", 2));
    // It converts again.
    a.observe("c2", 22.6, at(n + 2.0)).unwrap();
    assert!(a.evidence(at(n + 2.0), site).is_some());
}

#[test]
fn a_jump_that_stays_is_taken_once_the_time_covers_it() {
    let mut a = sensors();
    a.observe("c3", 10.0, at(0.0)).unwrap();
    assert_eq!(a.observe("c3", 35.0, at(1.0)), Err(AirRefused::Jump));
    // 25 degrees over 2 s is within 20 a second.
    a.observe("c3", 35.0, at(2.0)).unwrap();
}

#[test]
fn fusion_moves_the_fleets_speed_toward_the_sensors_by_their_weights() {
    let site = 343.0;
    let fleet = LearntSpeed {
        speed_m_s: site,
        sigma_m_s: site * 0.009,
        scale: 0.0,
    };
    let sensors = SpeedEvidence {
        scale: 0.01,
        variance: 0.0036f64.powi(2),
    };
    let f = sensors.fused(fleet, site);
    let w = 0.009f64.powi(2) / (0.009f64.powi(2) + 0.0036f64.powi(2));
    assert!((f.scale - 0.01 * w).abs() < 1e-9, "{}", f.scale);
    assert!(f.sigma_m_s < site * 0.0036 && f.sigma_m_s > 0.0);
    assert!((f.speed_m_s - site * (1.0 + f.scale)).abs() < 1e-9);
    // A confident fleet hardly moves.
    let sure = LearntSpeed {
        sigma_m_s: site * 0.0003,
        ..fleet
    };
    assert!(sensors.fused(sure, site).scale < 0.0001);
    // Nonsense evidence changes nothing.
    let nan = SpeedEvidence {
        scale: f64::NAN,
        variance: 1.0,
    };
    assert_eq!(nan.fused(fleet, site), fleet);
}

#[test]
fn a_reload_follows_the_sites_cells() {
    let mut a = sensors();
    a.observe("c1", 20.0, at(0.0)).unwrap();
    a.follow_cells(["c1", "c4"]);
    a.observe("c4", 20.0, at(0.0)).unwrap();
    assert_eq!(a.observe("c2", 20.0, at(0.0)), Err(AirRefused::UnknownCell));
    let cells: Vec<String> = ["c1", "c4"].map(String::from).to_vec();
    assert_eq!(a.report(at(0.5), &cells)[0].accepted, 1);
}
