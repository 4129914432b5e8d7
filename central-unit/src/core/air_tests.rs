//! The cell boards' air temperature sensors through the central unit:
//! from readings alone, the published speed of sound moves toward the
//! air's; bad readings change nothing and are reported.

use ickon_proto::msg::control::AirTemperature;
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};

use super::{CentralConfig, CentralCore, Event, Output};
use crate::air_temperature::speed_of_sound_at_c;

fn reading(cell: &str, t_c: f64, stamp: Time) -> Event {
    Event::AirTemperature(AirTemperature {
        cell_id: cell.into(),
        stamp,
        temperature_c: t_c,
    })
}

/// Runs the core for `seconds`, every cell reading `t_c(cell, k)` once a
/// second; the speeds it published, m/s.
fn run(seconds: u32, t_c: impl Fn(&str, u32) -> f64) -> (CentralCore, Vec<f64>) {
    let site = Site::default_site();
    let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    let mut c = CentralCore::new(site, String::new(), CentralConfig::default(), Time(0)).unwrap();
    let mut published = Vec::new();
    let mut now = Time(0);
    let end = Time::from_secs_f64(f64::from(seconds));
    let mut next_reading = Time(0);
    let mut k = 0;
    while now < end {
        now = c.next_wake().max(now);
        let mut out = c.handle(now, Event::Tick);
        if now >= next_reading {
            for cell in &cells {
                out.extend(c.handle(now, reading(cell, t_c(cell, k), now)));
            }
            k += 1;
            next_reading = next_reading + Duration::from_millis(1_000);
        }
        published.extend(out.iter().filter_map(|o| match o {
            Output::Survey(s) if s.speed_of_sound_m_s > 0.0 => Some(s.speed_of_sound_m_s),
            _ => None,
        }));
    }
    (c, published)
}

#[test]
fn from_sensors_alone_the_published_speed_moves_toward_the_air() {
    let site = Site::default_site();
    let site_m_s = site.speed_of_sound_m_s;
    // Seven degrees warmer than the site file says, a little spread.
    let warm_c = site.temperature_c.unwrap_or(20.0) + 7.0;
    let (c, published) = run(20, |cell, k| {
        let spread = if cell.ends_with('1') { 0.5 } else { -0.2 };
        warm_c + spread + if k % 2 == 0 { 0.02 } else { -0.02 }
    });
    let truth = speed_of_sound_at_c(warm_c);
    let last = *published.last().expect("speeds published");
    assert!(
        (last - truth).abs() < 0.5 * (site_m_s - truth).abs(),
        "published {last} m/s, the air's {truth}, the site's {site_m_s}"
    );
    let r = c.transmitters(Time::from_secs_f64(20.0));
    assert!(
        r.air_sensors
            .iter()
            .all(|b| b.state == "used" && b.accepted >= 19)
    );
    assert!((r.air_sensor_speed_m_s - truth).abs() < 0.3);
}

#[test]
fn sensors_that_fail_leave_the_site_speed_and_are_counted() {
    let site = Site::default_site();
    // c1 stuck, c2 not a number, c3 out of range, c4 jumping.
    let (c, published) = run(20, |cell, k| match cell {
        "c1" => 30.0,
        "c2" => f64::NAN,
        "c3" => 99.0,
        _ => {
            if k % 2 == 0 {
                20.0
            } else {
                45.0
            }
        }
    });
    let r = c.transmitters(Time::from_secs_f64(20.0));
    let b = |id: &str| r.air_sensors.iter().find(|b| b.cell_id == id).unwrap();
    assert!(b("c1").refused_stuck >= 9 && b("c1").state == "stuck");
    assert!(b("c2").refused_not_a_number >= 19);
    assert!(b("c3").refused_out_of_range >= 19);
    assert!(b("c4").refused_jump >= 9);
    // c4's accepted 20 C readings are the only evidence: the site's air.
    let last = *published.last().unwrap();
    let twenty = speed_of_sound_at_c(20.0);
    assert!(
        (last - twenty).abs() < 0.3,
        "published {last}, 20 C is {twenty} (the site's {})",
        site.speed_of_sound_m_s
    );
}
