//! The survey calibration file: what a restart reads, and what it refuses.

use super::survey_file::save_survey_file;
use super::*;
use crate::survey_calibration::{CalibrationConfig, SavedCalibration, SurveyCalibration};

fn dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("ickon-survey-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A calibration of the lab that has learnt something (a prior changed by
/// hand is enough to tell it from a fresh one).
fn learnt(site: &Site) -> SavedCalibration {
    let mut saved = SurveyCalibration::new(site, CalibrationConfig::default()).saved(site);
    let n = saved.weighted.len();
    saved.weighted[2] = 50.0;
    saved.information[0] *= 2.0;
    saved.fixes_taken = 1234;
    assert_eq!(saved.information.len(), n * n);
    saved
}

#[test]
fn a_kept_calibration_comes_back_as_it_was_saved() {
    let site = Site::default_site();
    let path = dir("round").join("survey.json");
    let saved = learnt(&site);
    save_survey_file(&path, &saved);
    let back = load_survey_file(&path, &site, CalibrationConfig::default())
        .unwrap()
        .unwrap();
    assert_eq!(back, saved);
    let restored = SurveyCalibration::restored(&site, CalibrationConfig::default(), &back).unwrap();
    assert_eq!(restored.fixes_taken(), 1234);
    assert!(restored.corrections()[0].offset_m[2] != 0.0);
    assert!(!path.with_extension("tmp").exists());
    // With the time it was saved, and from a release that did not keep it.
    let timed = SavedCalibration {
        saved_at_s: Some(1.8e9),
        ..saved.clone()
    };
    save_survey_file(&path, &timed);
    let back = load_survey_file(&path, &site, CalibrationConfig::default());
    assert_eq!(back, Ok(Some(timed)));
    let mut older = serde_json::to_value(&saved).unwrap();
    older.as_object_mut().unwrap().remove("saved_at_s").unwrap();
    std::fs::write(&path, older.to_string()).unwrap();
    let back = load_survey_file(&path, &site, CalibrationConfig::default());
    assert_eq!(back, Ok(Some(saved)));
}

#[test]
fn no_file_is_a_fresh_start_and_another_sites_file_is_set_aside() {
    let site = Site::default_site();
    let d = dir("other");
    assert_eq!(
        load_survey_file(&d.join("none.json"), &site, CalibrationConfig::default()),
        Ok(None)
    );
    let path = d.join("survey.json");
    let mut moved = learnt(&site);
    moved.transmitters[3].1[2] += 0.1;
    save_survey_file(&path, &moved);
    assert_eq!(
        load_survey_file(&path, &site, CalibrationConfig::default()),
        Ok(None)
    );
    let (warehouse, _) = Site::builtin("warehouse").unwrap();
    save_survey_file(&path, &learnt(&site));
    assert_eq!(
        load_survey_file(&path, &warehouse, CalibrationConfig::default()),
        Ok(None)
    );
}

#[test]
fn a_broken_file_stops_the_start_with_the_file_and_the_reason() {
    let site = Site::default_site();
    let d = dir("broken");
    let path = d.join("survey.json");
    let cases: Vec<(String, &str)> = vec![
        ("{ not json".into(), "not a survey calibration"),
        ("{}".into(), "not a survey calibration"),
        (
            serde_json::to_string(&SavedCalibration {
                information: vec![1.0; 3],
                ..learnt(&site)
            })
            .unwrap(),
            "sizes",
        ),
        (
            serde_json::to_string(&learnt(&site))
                .unwrap()
                .replacen("50.0", "1e999", 1),
            "not a survey calibration",
        ),
        (
            serde_json::to_string(&SavedCalibration {
                information: {
                    let mut m = learnt(&site).information;
                    m[0] = -5.0;
                    m
                },
                ..learnt(&site)
            })
            .unwrap(),
            "positive definite",
        ),
        (
            serde_json::to_string(&SavedCalibration {
                information: {
                    let mut m = learnt(&site).information;
                    m[1] = 7.0;
                    m
                },
                ..learnt(&site)
            })
            .unwrap(),
            "positive definite",
        ),
    ];
    for (text, reason) in cases {
        std::fs::write(&path, &text).unwrap();
        let e = load_survey_file(&path, &site, CalibrationConfig::default()).unwrap_err();
        assert!(e.contains("survey.json") && e.contains(reason), "{e}");
    }
    // A directory where the file should be.
    let e = load_survey_file(&d, &site, CalibrationConfig::default()).unwrap_err();
    assert!(e.contains(&d.display().to_string()), "{e}");
}

/// `ickon-central`'s flags, parsed as its command line would be.
fn parse(extra: &[&str]) -> Result<CentralArgs, clap::Error> {
    use clap::Parser;
    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        central: CentralArgs,
    }
    Cli::try_parse_from([&["ickon-central"][..], extra].concat()).map(|c| c.central)
}

#[test]
fn the_cells_sync_sigma_flag_sets_the_lateness_prior_and_refuses_nonsense() {
    let site = Site::default_site();
    let default = parse(&[]).unwrap().core_config(&site).survey.unwrap();
    assert!((default.cell_sync_sigma_m - 60e-6 * site.speed_of_sound_m_s).abs() < 1e-12);
    let set = parse(&["--cell-sync-sigma-us", "20"]).unwrap();
    let config = set.core_config(&site).survey.unwrap();
    assert!((config.cell_sync_sigma_m - 20e-6 * site.speed_of_sound_m_s).abs() < 1e-12);
    assert_eq!(
        parse(&["--cell-sync-sigma-us", "0"])
            .unwrap()
            .cell_sync_sigma_us,
        0.0
    );
    for bad in ["-1", "2e6", "NaN", "fast"] {
        assert!(parse(&["--cell-sync-sigma-us", bad]).is_err(), "{bad}");
    }
    // The timing sigma takes the same range but 0.
    assert!(parse(&["--timing-sigma-us", "0"]).is_err());
    for bad in ["-1", "2e6", "NaN", "fast"] {
        assert!(parse(&["--timing-sigma-us", bad]).is_err(), "{bad}");
    }
    assert_eq!(
        parse(&["--timing-sigma-us", "70"]).unwrap().timing_sigma_us,
        70.0
    );
}

#[test]
fn the_cells_sync_memory_flag_sets_the_correlation_time_and_refuses_nonsense() {
    let site = Site::default_site();
    let memory_s = |extra: &[&str]| {
        parse(extra)
            .unwrap()
            .core_config(&site)
            .survey
            .unwrap()
            .cell_sync_memory_s
    };
    assert_eq!(memory_s(&[]), 86_400.0);
    assert_eq!(memory_s(&["--cell-sync-memory-h", "2.5"]), 9_000.0);
    assert_eq!(memory_s(&["--cell-sync-memory-h", "0"]), 0.0);
    for bad in ["-1", "9000", "NaN", "inf", "a day"] {
        assert!(parse(&["--cell-sync-memory-h", bad]).is_err(), "{bad}");
    }
}

/// The `ickon-central` binary's command line (`src/main.rs`): a flag
/// defined twice panics only when parsed, so the definition is checked here.
#[test]
fn the_binarys_command_line_is_well_formed() {
    use clap::Args;
    let command = clap::Command::new("ickon-central").version("0");
    CentralArgs::augment_args(command).debug_assert();
}
