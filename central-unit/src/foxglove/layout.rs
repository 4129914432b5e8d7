//! The Foxglove layout of a site (`deploy/foxglove/<site>.json`): a 3D panel
//! on the site's scene and fleet, a plot of every robot's error and
//! position sigma, a plot of every cell's sync error and firing, a plot
//! of the speed of sound (in use, the site file's, the cell boards' air's)
//! and the log. The 3D panel shows each transmitter's health too. `Import layout` in the app with the file shows the site at once.
//!
//! The shipped files are made by this function and checked against it
//! (`ICKON_WRITE_FOXGLOVE_LAYOUTS=1 cargo test -p ickon-central layout`
//! writes them again), so that a renamed topic cannot leave them behind.

use ickon_proto::site::Site;
use serde_json::{Value, json};

use super::scene::MAP_FRAME;
use super::topics;

/// A plot line of `path`, labelled.
fn series(path: String, label: String) -> Value {
    json!({
        "value": path,
        "enabled": true,
        "timestampMethod": "receiveTime",
        "label": label,
    })
}

/// The layout of `site` (see the module doc).
pub fn layout(site: &Site) -> Value {
    let mut robot_series = Vec::new();
    for r in &site.robots {
        let state = topics::robot_topic(&r.id, "state");
        robot_series.push(series(
            format!("{state}.err_mm"),
            format!("{} error (mm)", r.id),
        ));
        robot_series.push(series(
            format!("{state}.sigma_major_mm"),
            format!("{} sigma (mm)", r.id),
        ));
    }
    let mut cell_series = Vec::new();
    for c in &site.cells {
        let sync = topics::cell_topic(&c.id);
        cell_series.push(series(
            format!("{sync}.sync_error_us"),
            format!("{} sync error (us)", c.id),
        ));
        cell_series.push(series(format!("{sync}.firing"), format!("{} firing", c.id)));
    }
    let visible = |t: &str| (t.to_string(), json!({ "visible": true }));
    let scene_topics: serde_json::Map<String, Value> = [
        topics::SITE_SCENE,
        topics::CELLS_SCENE,
        topics::ROBOTS_SCENE,
        topics::TRANSMITTERS_SCENE,
    ]
    .into_iter()
    .map(visible)
    .collect();
    json!({
        "configById": {
            "3D!ickon-site": {
                "followTf": MAP_FRAME,
                "followMode": "follow-none",
                "scene": { "transforms": { "showLabel": false } },
                "cameraState": {
                    "perspective": false,
                    "distance": 30,
                    "phi": 0,
                    "thetaOffset": 0,
                    "target": [0, 0, 0],
                    "targetOffset": site_centre(site),
                    "targetOrientation": [0, 0, 0, 1],
                    "fovy": 45,
                    "near": 0.5,
                    "far": 5000
                },
                "topics": scene_topics,
            },
            "Plot!ickon-robots": {
                "title": "Robots: error and position sigma (mm)",
                "paths": robot_series,
                "showLegend": true,
                "xAxisVal": "timestamp",
            },
            "Plot!ickon-cells": {
                "title": "Cells: sync error (us) and firing",
                "paths": cell_series,
                "showLegend": true,
                "xAxisVal": "timestamp",
            },
            "Plot!ickon-air": {
                "title": "Speed of sound (m/s)",
                "paths": speed_series(),
                "showLegend": true,
                "xAxisVal": "timestamp",
            },
            "RosOut!ickon-log": {
                "topicToRender": topics::LOG,
                "searchTerms": [],
                "minLogLevel": 2,
            },
        },
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": { "speed": 1 },
        "layout": {
            "first": "3D!ickon-site",
            "second": {
                "first": "Plot!ickon-robots",
                "second": {
                    "first": "Plot!ickon-cells",
                    "second": {
                        "first": "Plot!ickon-air",
                        "second": "RosOut!ickon-log",
                        "direction": "column",
                        "splitPercentage": 50,
                    },
                    "direction": "column",
                    "splitPercentage": 40,
                },
                "direction": "column",
                "splitPercentage": 40,
            },
            "direction": "row",
            "splitPercentage": 60,
        },
    })
}

/// The speed of sound's lines: in use, the site file's, the boards' air's.
fn speed_series() -> Vec<Value> {
    [
        ("speed_m_s", "in use"),
        ("site_m_s", "site file"),
        ("air_sensors_m_s", "cell boards' air"),
    ]
    .into_iter()
    .map(|(field, label)| {
        series(
            format!("{}.{field}", topics::SPEED_OF_SOUND),
            label.to_string(),
        )
    })
    .collect()
}

/// The middle of the site's cells, metres, where the camera looks.
fn site_centre(site: &Site) -> [f64; 3] {
    let points: Vec<&[f64; 2]> = site.cells.iter().flat_map(|c| c.polygon.iter()).collect();
    if points.is_empty() {
        return [0.0, 0.0, 0.0];
    }
    let fold =
        |f: fn(f64, f64) -> f64, k: usize, init: f64| points.iter().map(|p| p[k]).fold(init, f);
    let x = 0.5 * (fold(f64::min, 0, f64::INFINITY) + fold(f64::max, 0, f64::NEG_INFINITY));
    let y = 0.5 * (fold(f64::min, 1, f64::INFINITY) + fold(f64::max, 1, f64::NEG_INFINITY));
    [x, y, 0.0]
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    fn shipped(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../deploy/foxglove")
            .join(format!("{name}.json"))
    }

    #[test]
    fn the_shipped_layouts_are_those_of_the_built_in_sites() {
        for (name, _) in ickon_proto::site::BUILTIN_SITES {
            let (site, _) = Site::builtin(name).expect("built-in site");
            let text = serde_json::to_string_pretty(&layout(&site)).expect("JSON") + "\n";
            let path = shipped(name);
            if std::env::var_os("ICKON_WRITE_FOXGLOVE_LAYOUTS").is_some() {
                std::fs::write(&path, &text).expect("write layout");
            }
            let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                on_disk == text,
                "{} is not the layout of the {name} site; \
                 ICKON_WRITE_FOXGLOVE_LAYOUTS=1 cargo test -p ickon-central layout writes it",
                path.display()
            );
        }
    }

    #[test]
    fn every_robot_and_cell_is_plotted_and_the_log_shown() {
        let (site, _) = Site::builtin("lab").expect("lab");
        let l = layout(&site);
        let robots = l["configById"]["Plot!ickon-robots"]["paths"]
            .as_array()
            .expect("paths");
        assert_eq!(robots.len(), 2 * site.robots.len());
        assert_eq!(robots[0]["value"], "/robot/r1/state.err_mm");
        let cells = l["configById"]["Plot!ickon-cells"]["paths"]
            .as_array()
            .expect("paths");
        assert_eq!(cells.len(), 2 * site.cells.len());
        assert_eq!(l["configById"]["RosOut!ickon-log"]["topicToRender"], "/log");
        let air = l["configById"]["Plot!ickon-air"]["paths"]
            .as_array()
            .expect("paths");
        assert_eq!(air[0]["value"], "/site/speed_of_sound.speed_m_s");
        for t in [
            "/site/scene",
            "/site/cells",
            "/robots/scene",
            "/transmitters/scene",
        ] {
            assert_eq!(
                l["configById"]["3D!ickon-site"]["topics"][t]["visible"],
                true
            );
        }
    }
}
