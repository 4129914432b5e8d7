//! The speed of sound and the transmitters' health as Foxglove sends them,
//! from forged reports.

use ickon_proto::msg::admin::{
    BoardAirStatus, StatusReport, TransmitterStatus, TransmittersReport,
};
use ickon_proto::site::Site;
use ickon_proto::time::Time;

use super::*;

fn site() -> Site {
    Site::load_or_default(None).expect("built-in site").0
}

fn status(speed: f64, sigma: f64) -> StatusReport {
    StatusReport {
        site: "lab".into(),
        cycle: 1,
        stamp: Time(0),
        paused: false,
        schedule_version: 1,
        update_rate_hz: 10.0,
        cells: Vec::new(),
        robots: Vec::new(),
        epoch: 1,
        foreign_control: 0,
        active: true,
        survey_publications: 0,
        survey_publish_mean_us: 0.0,
        survey_publish_max_us: 0.0,
        speed_of_sound_m_s: speed,
        speed_of_sound_sigma_m_s: sigma,
        site_speed_of_sound_m_s: 343.2,
        transmitters_left_out: Vec::new(),
        robot_counts: Default::default(),
        robots_posed: 0,
    }
}

fn transmitter(tx_id: u32, condition: &str, left_out: bool) -> TransmitterStatus {
    TransmitterStatus {
        tx_id,
        cell_id: "c1".into(),
        condition: condition.into(),
        left_out,
        evidence: String::new(),
        due: 10.0,
        heard_pct: if condition == "unknown" { -1.0 } else { 80.0 },
        expected_pct: 90.0,
        rejected_pct: 1.0,
        residuals_known: condition != "unknown",
        residual_mean_m: 0.0123,
        residual_std_m: 0.004,
        last_heard_s_ago: if condition == "dead" { 30.0 } else { 0.1 },
        offset_m: [0.0; 3],
    }
}

fn transmitters(site: &Site) -> TransmittersReport {
    let conditions = ["healthy", "dead", "weak", "moved", "unknown"];
    TransmittersReport {
        site: site.name.clone(),
        stamp: Time(0),
        learning: true,
        fixes_taken: 100,
        speed_of_sound_m_s: 344.0,
        speed_of_sound_sigma_m_s: 0.3,
        site_speed_of_sound_m_s: 343.2,
        transmitters: site
            .transmitters
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let c = conditions[i % conditions.len()];
                transmitter(t.id, c, c == "dead" || c == "moved")
            })
            .collect(),
        air_sensors: vec![BoardAirStatus {
            cell_id: "c1".into(),
            state: "used".into(),
            temperature_c: 22.0,
            accepted_s_ago: 0.5,
            accepted: 10,
            refused_not_a_number: 0,
            refused_out_of_range: 0,
            refused_stuck: 0,
            refused_jump: 0,
        }],
        air_sensor_speed_m_s: 344.5,
    }
}

#[test]
fn the_speed_of_sound_plotted_is_the_one_in_use_with_its_sigma() {
    let learnt = serde_json::to_value(SpeedOfSound::new(&status(344.1, 0.25), None)).unwrap();
    assert_eq!(learnt["speed_m_s"], 344.1);
    assert_eq!(learnt["sigma_m_s"], 0.25);
    assert_eq!(learnt["learnt"], true);
    assert_eq!(learnt["site_m_s"], 343.2);
    assert!(
        learnt.get("air_sensors_m_s").is_none(),
        "none known: left out"
    );
    // Not learnt: the site file's speed, no sigma.
    let site_speed = serde_json::to_value(SpeedOfSound::new(&status(0.0, 0.0), None)).unwrap();
    assert_eq!(site_speed["speed_m_s"], 343.2);
    assert_eq!(site_speed["learnt"], false);
    assert!(site_speed.get("sigma_m_s").is_none());
    let t = transmitters(&site());
    let with_boards =
        serde_json::to_value(SpeedOfSound::new(&status(344.1, 0.25), Some(&t))).unwrap();
    assert_eq!(with_boards["air_sensors_m_s"], 344.5);
}

#[test]
fn every_transmitter_is_a_sphere_coloured_by_its_health_under_it() {
    let site = site();
    let report = transmitters(&site);
    let scene = transmitters_scene(&site, &report, Timestamp::new(1, 0));
    assert_eq!(scene.entities.len(), site.transmitters.len());
    for (e, (t, r)) in scene
        .entities
        .iter()
        .zip(site.transmitters.iter().zip(&report.transmitters))
    {
        assert_eq!(e.id, format!("tx/{}", t.id));
        let sphere = &e.spheres[0];
        let p = sphere.pose.as_ref().unwrap().position.as_ref().unwrap();
        assert_eq!((p.x, p.y), (t.position_m[0], t.position_m[1]));
        assert!(p.z < t.position_m[2], "under its transmitter");
        assert_eq!(sphere.color.as_ref().unwrap(), &health_color(&r.condition));
        let labelled = !e.texts.is_empty();
        assert_eq!(
            labelled,
            r.condition != "healthy" && r.condition != "unknown",
            "{}",
            r.condition
        );
        if r.left_out {
            assert!(e.texts[0].text.contains("left out"));
        }
    }
    // Every condition its own colour.
    let colors: Vec<Color> = ["healthy", "dead", "weak", "moved", "unknown"]
        .into_iter()
        .map(health_color)
        .collect();
    for (i, a) in colors.iter().enumerate() {
        assert!(colors[i + 1..].iter().all(|b| b != a));
    }
    // A transmitter the site does not place is not drawn.
    let mut stranger = report.clone();
    stranger.transmitters.push(transmitter(9_999, "dead", true));
    assert_eq!(
        transmitters_scene(&site, &stranger, Timestamp::new(1, 0))
            .entities
            .len(),
        site.transmitters.len()
    );
}

#[test]
fn the_health_status_carries_each_transmitters_figures_in_mm_and_leaves_unknowns_out() {
    let site = site();
    let report = transmitters(&site);
    let doc = serde_json::to_value(TransmittersHealth::from(&report)).unwrap();
    let list = doc["transmitters"].as_array().unwrap();
    assert_eq!(list.len(), site.transmitters.len());
    assert_eq!(
        doc["left_out"],
        report.transmitters.iter().filter(|t| t.left_out).count()
    );
    let healthy = &list[0];
    assert_eq!(healthy["condition"], "healthy");
    assert_eq!(healthy["residual_mean_mm"], 12.3);
    assert_eq!(healthy["residual_std_mm"], 4.0);
    assert_eq!(healthy["heard_pct"], 80.0);
    assert_eq!(healthy["left_out"], 0);
    assert_eq!(list[1]["left_out"], 1);
    assert_eq!(list[1]["last_heard_s_ago"], 30.0);
    let unknown = &list[4];
    assert_eq!(unknown["condition"], "unknown");
    assert!(unknown.get("heard_pct").is_none());
    assert!(unknown.get("residual_mean_mm").is_none());
}
