//! The MSU configuration file `ickon sim` gives its agents: the estimator
//! exactly as `ickon eval` configures it for the noise profile, so that the
//! live mesh and the virtual-time engine run the same filter, and the agents
//! are set up the way a deployed one is (`--config FILE`).

use ickon_fusion::estimator::{EstimatorConfig, WheelGeometry};

use crate::error::LaunchError;

/// The file's text: `[filter]` with every parameter of `config` (the site
/// re-applies the start pose, receiver height and floor), the drive, and
/// the arrivals' timing noise.
pub(crate) fn render(
    config: &EstimatorConfig,
    timing_sigma_s: f64,
    wheels: WheelGeometry,
    ros2: bool,
) -> Result<String, LaunchError> {
    let mut params =
        toml::Table::try_from(config).map_err(|e| LaunchError::MsuFile(e.to_string()))?;
    params.remove("name");
    let mut filter = toml::Table::new();
    filter.insert("estimator".into(), config.name().into());
    filter.insert("params".into(), params.into());
    let mut robot = toml::Table::new();
    robot.insert("wheel_base_m".into(), wheels.wheel_base_m.into());
    robot.insert("m_per_tick".into(), wheels.left_m_per_tick.into());
    let mut fix = toml::Table::new();
    fix.insert("timing_sigma_us".into(), (timing_sigma_s * 1e6).into());
    let mut root = toml::Table::new();
    root.insert("filter".into(), filter.into());
    root.insert("robot".into(), robot.into());
    root.insert("fix".into(), fix.into());
    if ros2 {
        // `ickon sim --ros2`: the agents speak ROS 2 by their file, as a
        // deployed one configured once would.
        let mut block = toml::Table::new();
        block.insert("enabled".into(), true.into());
        root.insert("ros2".into(), block.into());
    }
    Ok(format!(
        "# Written by `ickon sim` for its MSU agents: `{}` as `ickon eval` configures it.\n{}",
        config.name(),
        toml::to_string(&root).map_err(|e| LaunchError::MsuFile(e.to_string()))?
    ))
}

/// Writes `text` to a new temporary file, removed when the handle drops.
pub(crate) fn write_temp(text: &str) -> std::io::Result<tempfile::NamedTempFile> {
    let mut file = tempfile::Builder::new()
        .prefix("ickon-sim-msu-")
        .suffix(".toml")
        .tempfile()?;
    std::io::Write::write_all(&mut file, text.as_bytes())?;
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ickon sim --learn-cell-sync` reaches the agents through their file.
    #[test]
    fn the_cell_sync_option_reaches_the_agents_file() {
        let site = ickon_proto::site::Site::default_site();
        let profile = ickon_sim::profile::NoiseProfile::by_name("paper").unwrap();
        let start = site.robots[0].start;
        let wheels = ickon_msu::config_file::pioneer_wheels();
        let options = ickon_sim::engine::FilterOptions {
            learn_cell_sync: true,
            ..Default::default()
        };
        let config =
            ickon_sim::engine::estimator_config("tdoa-ekf", start, &site, &profile, options)
                .unwrap();
        let ickon_fusion::estimator::EstimatorConfig::TdoaEkf(p) = &config else {
            panic!("{config:?}");
        };
        assert!(p.learn_cell_sync);
        let text = render(&config, 42e-6, wheels, false).unwrap();
        assert!(text.contains("learn_cell_sync = true"), "{text}");
        let tuning = ickon_msu::MsuTuning::from_toml(&text, "sim").unwrap();
        assert_eq!(tuning.estimator_for(&site, start), config);
        // Off by default, as the filter's own default.
        let plain = ickon_sim::engine::estimator_config(
            "tdoa-ekf",
            start,
            &site,
            &profile,
            Default::default(),
        )
        .unwrap();
        let ickon_fusion::estimator::EstimatorConfig::TdoaEkf(p) = &plain else {
            panic!("{plain:?}");
        };
        assert!(!p.learn_cell_sync);
    }

    /// `ickon sim --local-wind` reaches the agents through their file: the
    /// local wind state's spread, read back as written.
    #[test]
    fn the_local_wind_option_reaches_the_agents_file() {
        let site = ickon_proto::site::Site::default_site();
        let profile = ickon_sim::profile::NoiseProfile::by_name("paper").unwrap();
        let start = site.robots[0].start;
        let wheels = ickon_msu::config_file::pioneer_wheels();
        let spread = |options| {
            let config =
                ickon_sim::engine::estimator_config("tdoa-ekf", start, &site, &profile, options)
                    .unwrap();
            let text = render(&config, 42e-6, wheels, false).unwrap();
            let tuning = ickon_msu::MsuTuning::from_toml(&text, "sim").unwrap();
            let read = tuning.estimator_for(&site, start);
            assert_eq!(read, config);
            let ickon_fusion::estimator::EstimatorConfig::TdoaEkf(p) = &read else {
                panic!("{read:?}");
            };
            p.sensors.local_wind_sigma_m_s
        };
        let on = ickon_sim::engine::FilterOptions {
            local_wind: true,
            ..Default::default()
        };
        assert_eq!(spread(on), ickon_sim::engine::LOCAL_WIND_SIGMA_M_S);
        assert_eq!(spread(Default::default()), 0.0);
    }

    /// What the sim writes is what the agent reads back: the same estimator
    /// configuration, bit for bit, for every estimator.
    #[test]
    fn the_agents_read_back_exactly_the_configuration_the_sim_wrote() {
        let site = ickon_proto::site::Site::default_site();
        let profile = ickon_sim::profile::NoiseProfile::by_name("paper").unwrap();
        let start = site.robots[0].start;
        let wheels = ickon_msu::config_file::pioneer_wheels();
        for name in ickon_fusion::estimator::names() {
            let config = ickon_sim::engine::estimator_config(
                name,
                start,
                &site,
                &profile,
                ickon_sim::engine::FilterOptions::default(),
            )
            .unwrap();
            let text = render(&config, 42e-6, wheels, *name == "tdoa-ekf").unwrap();
            let tuning = ickon_msu::MsuTuning::from_toml(&text, "sim").unwrap();
            assert!(tuning.warnings.is_empty(), "{name}: {:?}", tuning.warnings);
            assert_eq!(tuning.estimator_for(&site, start), config, "{name}\n{text}");
            assert_eq!(tuning.wheels, wheels);
            assert!((tuning.solver.timing_sigma_s - 42e-6).abs() < 1e-15);
            // `--ros2` is written as the file's `[ros2]` block.
            let ros2 = tuning.ros2.as_ref().is_some_and(|r| r.enabled);
            assert_eq!(ros2, *name == "tdoa-ekf", "{name}\n{text}");
        }
    }
}
