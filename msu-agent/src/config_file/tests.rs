use ickon_fusion::estimator::EstimatorConfig;

use super::*;

fn parse(text: &str) -> Result<MsuTuning, Vec<ConfigIssue>> {
    MsuTuning::from_toml(text, "test.toml").map_err(|e| match e {
        MsuConfigError::Invalid { issues, .. } => issues,
        other => panic!("not a validation error: {other}"),
    })
}

fn tdoa(t: &MsuTuning) -> &ickon_fusion::estimator::tdoa_ekf::TdoaEkfParams {
    match &t.estimator {
        EstimatorConfig::TdoaEkf(p) => p,
        other => panic!("not tdoa-ekf: {other:?}"),
    }
}

const EXAMPLE: &str = include_str!("../../../deploy/msu.toml");

#[test]
fn a_file_naming_only_the_estimator_gives_its_defaults() {
    for name in ickon_fusion::estimator::names() {
        let t = parse(&format!("[filter]\nestimator = \"{name}\"\n")).unwrap();
        assert_eq!(t, MsuTuning::defaults(name).unwrap(), "{name}");
    }
}

#[test]
fn the_example_file_is_valid_and_its_commented_values_are_the_defaults() {
    let t = parse(EXAMPLE).unwrap();
    let ros2 = Some(crate::ros2::Ros2Options::default());
    assert_eq!(
        t,
        MsuTuning {
            ros2: ros2.clone(),
            ..MsuTuning::defaults("tdoa-ekf").unwrap()
        }
    );
    // Uncomment every `#key = value` line: the same tuning (to the digits
    // the example shows), with one warning for the key tdoa-ekf does not use.
    let uncommented: String = EXAMPLE
        .lines()
        .map(|l| {
            let rest = l.strip_prefix('#').unwrap_or(l);
            let is_value = l.starts_with('#')
                && rest.split_once(" = ").is_some_and(|(k, _)| {
                    !k.is_empty() && k.chars().all(|c| c.is_ascii_lowercase() || c == '_')
                });
            if is_value { rest } else { l }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let all = parse(&uncommented).unwrap();
    let fields: Vec<&str> = all.warnings.iter().map(|w| w.field.as_str()).collect();
    assert_eq!(fields, ["fix.sigma_floor_mm"]);
    let (a, d) = (tdoa(&all), MsuTuning::defaults("tdoa-ekf").unwrap());
    let d = tdoa(&d);
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-4 * y.abs().max(1e-9);
    assert!(close(
        a.sensors.wheel_slip_fraction,
        d.sensors.wheel_slip_fraction
    ));
    assert!(close(
        a.sensors.wheel_heading_rad_per_m,
        d.sensors.wheel_heading_rad_per_m
    ));
    assert_eq!(a.sensors.gyro_white_deg_s, d.sensors.gyro_white_deg_s);
    assert_eq!(a.gate_sigma, d.gate_sigma);
    assert_eq!(a.heading_sigma_deg, d.heading_sigma_deg);
    assert_eq!(a.model_nis, d.model_nis);
    assert_eq!(all.start, Some([1.0, 1.0, 0.0]));
    assert_eq!(all.solver.residual_gate_m, Some(0.07));
    assert!((all.wheels.left_m_per_tick - 3.2e-5).abs() < 1e-12);
    assert_eq!(all.ros2, ros2);
}

#[test]
fn the_ros2_block_sets_the_ros2_side_and_a_flag_away_from_its_default_wins() {
    use crate::ros2::{Ros2Mode, Ros2Options};
    let t = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[ros2]\nenabled = true\nmode = \"bridge\"\n\
         domain = 7\npose_topic = \"loc/pose\"\nunconfirmed_poses = true\n",
    )
    .unwrap();
    let file = t.ros2.expect("the block");
    assert!(file.enabled && file.unconfirmed_poses);
    assert_eq!((file.mode, file.domain), (Ros2Mode::Bridge, Some(7)));
    assert_eq!(file.pose_topic, "loc/pose");
    assert_eq!(file.odom_topic, Ros2Options::default().odom_topic);
    let flags = Ros2Options {
        pose_topic: "other/pose".into(),
        ..Ros2Options::default()
    };
    let both = Ros2Options::under_flags(&file, &flags);
    assert!(both.enabled, "the file turns it on");
    assert_eq!(both.pose_topic, "other/pose");
    assert_eq!((both.mode, both.domain), (Ros2Mode::Bridge, Some(7)));
    // A misspelt key or a wrong value is named with its line.
    let issues =
        parse("[filter]\nestimator = \"tdoa-ekf\"\n[ros2]\npose_topik = \"x\"\n").unwrap_err();
    assert_eq!(issues[0].line, 4, "{issues:?}");
    let issues = parse("[filter]\nestimator = \"tdoa-ekf\"\n[ros2]\nmode = \"dds\"\n").unwrap_err();
    assert_eq!(issues[0].line, 4, "{issues:?}");
}

#[test]
fn every_problem_is_reported_at_once_with_its_line_and_column() {
    let text = "[filter]\nestimator = \"tdoa-ekf\"\nhistory_s = -1.0\n\n[fix]\ntiming_sigma_us = nan\n\n[gyro]\nrate_hz = 0.0\nmax_gap_s = 1e9\n";
    let issues = parse(text).unwrap_err();
    let at: Vec<(usize, usize, &str)> = issues
        .iter()
        .map(|i| (i.line, i.column, i.field.as_str()))
        .collect();
    assert_eq!(
        at,
        [
            (3, 13, "filter.history_s"),
            (6, 19, "fix.timing_sigma_us"),
            (9, 11, "gyro.rate_hz"),
            (10, 13, "gyro.max_gap_s"),
        ]
    );
    assert!(issues[1].message.contains("finite"), "{:?}", issues[1]);
    assert!(
        issues[2].message.contains("out of range"),
        "{:?}",
        issues[2]
    );
    let text_of_error = MsuTuning::from_toml(text, "msu.toml")
        .unwrap_err()
        .to_string();
    assert!(
        text_of_error.contains("msu.toml:9:11: gyro.rate_hz"),
        "{text_of_error}"
    );
    assert!(text_of_error.starts_with("MSU configuration msu.toml has 4 problems"));
}

#[test]
fn unknown_estimators_keys_and_parameters_are_named() {
    let issues = parse("[filter]\nestimator = \"kalman\"\n").unwrap_err();
    assert_eq!(
        (issues[0].line, issues[0].field.as_str()),
        (2, "filter.estimator")
    );
    assert!(issues[0].message.contains("tdoa-ekf"), "{:?}", issues[0]);

    let issues = parse("[filter]\nestimator = \"tdoa-ekf\"\n[gyro]\nnoise = 1.0\n").unwrap_err();
    assert_eq!(issues[0].line, 4, "{issues:?}");
    assert!(issues[0].message.contains("noise"), "{issues:?}");

    let issues = parse("[filter]\nestimator = \"tdoa-ekf\"\n[filter.params]\nmodel_nsi = 3.0\n")
        .unwrap_err();
    assert_eq!(issues[0].field, "filter.params");
    assert!(issues[0].message.contains("model_nsi"), "{issues:?}");

    let issues = parse("[filter]\nestimator = \"ickon-akf\"\n[filter.params]\nhistory_s = -2.0\n")
        .unwrap_err();
    assert!(issues[0].message.contains("history_s"), "{issues:?}");

    let issues = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[filter.params]\nsensors = { survey_sigma_m = 1e300 }\n",
    )
    .unwrap_err();
    assert!(
        issues[0].message.contains("sensors.survey_sigma_m")
            && issues[0].message.contains("at most 1 m"),
        "{issues:?}"
    );

    let issues = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[filter.params]\nsensors = { cell_sync_sigma_us = -1.0 }\n",
    )
    .unwrap_err();
    assert!(
        issues[0].message.contains("sensors.cell_sync_sigma_us"),
        "{issues:?}"
    );

    let issues = parse("[fix]\ntiming_sigma_us = 20.0\n").unwrap_err();
    assert!(issues[0].message.contains("filter"), "{issues:?}");

    let issues = parse("[filter\nestimator = 1").unwrap_err();
    assert_eq!((issues[0].line, issues[0].field.as_str()), (1, "(syntax)"));
}

#[test]
fn a_value_set_in_an_input_block_and_in_the_params_is_refused() {
    let text = "[filter]\nestimator = \"tdoa-ekf\"\n[filter.params.sensors]\ngyro_white_deg_s = 0.2\n[gyro]\nwhite_noise_deg_s = 0.3\n";
    let issues = parse(text).unwrap_err();
    assert_eq!(issues.len(), 1, "{issues:?}");
    assert_eq!(
        (issues[0].line, issues[0].field.as_str()),
        (6, "gyro.white_noise_deg_s")
    );
    assert!(
        issues[0].message.contains("sensors.gyro_white_deg_s"),
        "{issues:?}"
    );
    // In the params alone it is taken.
    let t = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[filter.params.sensors]\ngyro_white_deg_s = 0.2\n",
    )
    .unwrap();
    assert_eq!(tdoa(&t).sensors.gyro_white_deg_s, 0.2);
}

#[test]
fn values_an_estimator_does_not_use_are_warnings_not_errors() {
    let t = parse("[filter]\nestimator = \"ickon-akf\"\n[gyro]\nscale_error = 0.01\n[range_differences]\ngate_sigma = 3.0\n")
        .unwrap();
    let w: Vec<(usize, &str)> = t
        .warnings
        .iter()
        .map(|w| (w.line, w.field.as_str()))
        .collect();
    assert_eq!(
        w,
        [(4, "gyro.scale_error"), (6, "range_differences.gate_sigma")]
    );
    assert!(t.warnings[0].message.contains("ickon-akf"));
    assert_eq!(
        t.estimator,
        EstimatorConfig::default_for("ickon-akf").unwrap()
    );
}

#[test]
fn input_blocks_land_in_each_estimators_own_parameters() {
    let gyro = "[gyro]\nwhite_noise_deg_s = 0.2\nrate_hz = 400.0\nbias_sigma_deg_s = 0.3\nmax_gap_s = 0.25\n[receiver_heading]\nsigma_deg = 20.0\n[fix]\nsigma_floor_mm = 5.0\ntiming_sigma_us = 20.0\nmax_sigma_m = 0.3\n";
    let t = parse(&format!("[filter]\nestimator = \"gyro-ckf\"\n{gyro}")).unwrap();
    let EstimatorConfig::GyroCkf(p) = &t.estimator else {
        panic!("{t:?}")
    };
    assert!((p.gyro_noise_deg_sqrt_s - 0.01).abs() < 1e-12);
    assert_eq!(p.initial_bias_sigma_deg_s, 0.3);
    assert_eq!(p.max_gyro_gap_s, 0.25);
    assert_eq!(p.heading_sigma_deg, 20.0);
    assert_eq!(p.position.r_floor_mm, 5.0);
    assert!((t.solver.timing_sigma_s - 20e-6).abs() < 1e-15);
    assert_eq!(t.solver.max_fix_sigma_m, 0.3);

    let t = parse(&format!("[filter]\nestimator = \"tdoa-ekf\"\n{gyro}")).unwrap();
    let p = tdoa(&t);
    assert_eq!(
        (p.sensors.gyro_white_deg_s, p.sensors.gyro_rate_hz),
        (0.2, 400.0)
    );
    assert_eq!(p.heading_sigma_deg, 20.0);
    assert_eq!(t.warnings.len(), 1, "{:?}", t.warnings);

    let t = parse("[filter]\nestimator = \"odometry\"\n[odometry]\ndistance_sigma_fraction = 0.05\nheading_sigma_deg_per_m = 2.0\n")
        .unwrap();
    let EstimatorConfig::Odometry(p) = &t.estimator else {
        panic!("{t:?}")
    };
    assert_eq!(p.noise.distance_fraction, 0.05);
    assert!((p.noise.heading_rad_per_m - 2.0_f64.to_radians()).abs() < 1e-15);
}

#[test]
fn the_site_gives_the_start_unless_the_file_does() {
    let site = ickon_proto::site::Site::default_site();
    let start = site.robots[0].start;
    let t = MsuTuning::defaults("ickon-akf").unwrap();
    let EstimatorConfig::IckonAkf(p) = t.estimator_for(&site, start) else {
        panic!()
    };
    let pose = p.initial_pose.unwrap();
    assert_eq!([pose.x_m, pose.y_m, pose.theta_rad], start);

    let t = parse("[filter]\nestimator = \"tdoa-ekf\"\nstart = [2.0, 3.0, 90.0]\n").unwrap();
    let EstimatorConfig::TdoaEkf(p) = t.estimator_for(&site, start) else {
        panic!()
    };
    let pose = p.initial_pose.unwrap();
    assert_eq!([pose.x_m, pose.y_m], [2.0, 3.0]);
    assert!((pose.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert_eq!(p.receiver_height_m, site.msu.height_m);
    assert!(p.floor.is_some());
}

#[test]
fn files_that_are_not_configurations_are_refused_clearly() {
    let dir = std::env::temp_dir().join(format!("ickon-msu-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let big = dir.join("big.toml");
    std::fs::write(&big, vec![b'#'; 2 << 20]).unwrap();
    let e = MsuTuning::load(&big).unwrap_err().to_string();
    assert!(e.contains("larger than"), "{e}");
    let binary = dir.join("binary.toml");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x80]).unwrap();
    let e = MsuTuning::load(&binary).unwrap_err().to_string();
    assert!(e.contains("cannot read"), "{e}");
    let e = MsuTuning::load(&dir.join("missing.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.toml"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_marvelmind_block_sets_the_kits_settings_and_refuses_absurd_ones() {
    let t = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[marvelmind]\nspeed_of_sound_m_s = 340.5\nrange_sigma_m = 0.03\nuse_kit_positions = true\nkit_position_sigma_m = 0.05\ngyro_rad_s_per_count = 0.00122\n",
    )
    .unwrap();
    assert_eq!(
        t.marvelmind,
        crate::hedgehog::MarvelmindSettings {
            speed_of_sound_m_s: 340.5,
            range_sigma_m: 0.03,
            use_kit_positions: true,
            kit_position_sigma_m: 0.05,
            gyro_rad_s_per_count: Some(0.00122),
        }
    );
    let issues = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[marvelmind]\nspeed_of_sound_m_s = 34.3\nrange_sigma_m = -1.0\nbaud = 9600\n",
    )
    .unwrap_err();
    assert_eq!(
        issues.len(),
        1,
        "unknown key: the file does not parse {issues:?}"
    );
    let issues = parse(
        "[filter]\nestimator = \"tdoa-ekf\"\n[marvelmind]\nspeed_of_sound_m_s = 34.3\nrange_sigma_m = -1.0\ngyro_rad_s_per_count = 0.5\n",
    )
    .unwrap_err();
    let fields: Vec<&str> = issues.iter().map(|i| i.field.as_str()).collect();
    // 0.5 rad/s per count: degrees mistaken for radians, or a gyro in
    // whole degrees; refused.
    assert_eq!(
        fields,
        [
            "marvelmind.speed_of_sound_m_s",
            "marvelmind.range_sigma_m",
            "marvelmind.gyro_rad_s_per_count"
        ]
    );
}

#[test]
fn a_robot_the_site_does_not_list_starts_from_the_file_or_is_refused() {
    let site = ickon_proto::site::Site::default_site();
    let listed = &site.robots[0];
    let t = MsuTuning::defaults("tdoa-ekf").unwrap();
    let EstimatorConfig::TdoaEkf(p) = t.estimator_for_robot(&site, &listed.id).unwrap() else {
        panic!()
    };
    let pose = p.initial_pose.unwrap();
    assert_eq!([pose.x_m, pose.y_m, pose.theta_rad], listed.start);

    let err = t.estimator_for_robot(&site, "amr-7").unwrap_err();
    assert_eq!(err.robot, "amr-7");
    assert!(err.to_string().contains("filter.start"), "{err}");

    let t = parse("[filter]\nestimator = \"tdoa-ekf\"\nstart = [2.0, 3.0, 90.0]\n").unwrap();
    let EstimatorConfig::TdoaEkf(p) = t.estimator_for_robot(&site, "amr-7").unwrap() else {
        panic!()
    };
    let pose = p.initial_pose.unwrap();
    assert_eq!([pose.x_m, pose.y_m], [2.0, 3.0]);
    assert!((pose.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
}
