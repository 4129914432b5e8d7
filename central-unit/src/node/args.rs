//! The central unit's command line: its flags, their ranges and the core
//! configuration they ask for.

use clap::Args;
use ickon_proto::site::Site;
use ickon_runtime::NodeArgs;

use crate::core::CentralConfig;

/// Arguments of `ickon-central` (and `ickon node central`).
#[derive(Debug, Clone, Args)]
pub struct CentralArgs {
    /// Connection and simulation flags.
    #[command(flatten)]
    pub node: NodeArgs,
    /// The web map's flags.
    #[command(flatten)]
    pub http: crate::http::HttpArgs,
    /// The Foxglove live server's flag.
    #[command(flatten)]
    pub foxglove: crate::foxglove::FoxgloveArgs,
    /// Start as a hot standby: follow the active central unit and take
    /// over when its liveliness token goes or its triggers stop for two
    /// cycles (see `ickon_central::core::standby`).
    #[arg(long)]
    pub standby: bool,
    /// Which transmitters fire each cycle: `needs` (a few in good geometry
    /// for each robot, spaced by the room's reverberation), `occupancy`
    /// (everything audible where robots may be) or `all` (the whole
    /// schedule every cycle). With `needs` and `occupancy` the whole
    /// schedule fires while no robot is known, and the MSU agents follow
    /// the cycle triggers' firing sets.
    #[arg(long, value_enum, default_value_t = Firing::Occupancy)]
    pub firing: Firing,
    /// Do not learn the transmitters' survey errors from the robots' fixes
    /// (nor publish them on `central/survey`).
    #[arg(long)]
    pub no_survey_calibration: bool,
    /// Do not publish the speed of sound learnt from the robots' fixes:
    /// the MSUs use the site file's throughout.
    #[arg(long)]
    pub no_speed_of_sound: bool,
    /// One-sigma timing noise of one arrival, microseconds: what the MSUs'
    /// data sheet states (their `timing_sigma_us`); weighs each fix in the
    /// survey calibration.
    #[arg(long, default_value_t = 50.0, value_parser = timing_sigma_us)]
    pub timing_sigma_us: f64,
    /// One-sigma error of a cell's sync, microseconds: how far the site's
    /// network may leave a cell's clock from the central unit's (half its
    /// paths' asymmetry, which no clock exchange sees). The prior of each
    /// cell's lateness in the survey calibration, which the MSUs take from
    /// that cell's pseudo-ranges; 0 keeps every cell on time.
    #[arg(long, default_value_t = 60.0, value_parser = cell_sync_sigma_us)]
    pub cell_sync_sigma_us: f64,
    /// How long the survey calibration remembers a cell's lateness,
    /// hours (its correlation time): a cell whose network path changes is
    /// followed within about this long; 0 remembers it for good.
    #[arg(long, default_value_t = 24.0, value_parser = cell_sync_memory_h)]
    pub cell_sync_memory_h: f64,
    /// Keep the survey calibration in this file (JSON), so that a restart
    /// goes on from what the fleet taught it: read at start when it
    /// exists (a file of another site or transmitter table is set aside
    /// with a warning; an unreadable or broken one stops the start, exit
    /// 2), written every minute and at shutdown.
    #[arg(long)]
    pub survey_file: Option<std::path::PathBuf>,
}

/// `--cell-sync-sigma-us`: microseconds from 0 up to a second.
fn cell_sync_sigma_us(text: &str) -> Result<f64, String> {
    micros_up_to_a_second(text, true)
}

/// `--cell-sync-memory-h`: hours from 0 up to a year (8760).
fn cell_sync_memory_h(text: &str) -> Result<f64, String> {
    let v = text.parse::<f64>().map_err(|e| format!("{text:?}: {e}"))?;
    if (0.0..=8760.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is not in [0, 8760] h"))
    }
}

/// `--timing-sigma-us`: a positive number of microseconds up to a second.
fn timing_sigma_us(text: &str) -> Result<f64, String> {
    micros_up_to_a_second(text, false)
}

/// A number of microseconds up to a second, above 0 (or from 0 when
/// `zero_allowed`); NaN is in no range.
fn micros_up_to_a_second(text: &str, zero_allowed: bool) -> Result<f64, String> {
    let v = text.parse::<f64>().map_err(|e| format!("{text:?}: {e}"))?;
    let above_floor = if zero_allowed { v >= 0.0 } else { v > 0.0 };
    if above_floor && v <= 1e6 {
        Ok(v)
    } else {
        let open = if zero_allowed { '[' } else { '(' };
        Err(format!("{v} is not in {open}0, 1000000] us"))
    }
}

/// The central unit's firing policy, as a flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Firing {
    /// Every emission of the schedule, every cycle.
    All,
    /// Only the transmitters audible from some robot's uncertainty region.
    Occupancy,
    /// A few transmitters in good geometry for each robot, spaced by the
    /// room's reverberation
    Needs,
}

impl CentralArgs {
    /// The core's configuration these flags ask for on `site`.
    pub fn core_config(&self, site: &Site) -> CentralConfig {
        let mut config = CentralConfig::default();
        config.firing.occupancy = self.firing != Firing::All;
        if self.firing == Firing::Needs {
            config.firing.needs = Some(crate::selection::NeedsConfig::default());
            config.firing.reverb = Some(crate::spacing::Reverb::default());
        }
        config.survey =
            (!self.no_survey_calibration).then(|| crate::survey_calibration::CalibrationConfig {
                range_sigma_m: self.timing_sigma_us * 1e-6 * site.speed_of_sound_m_s,
                cell_sync_sigma_m: self.cell_sync_sigma_us * 1e-6 * site.speed_of_sound_m_s,
                cell_sync_memory_s: self.cell_sync_memory_h * 3600.0,
                learn_speed_of_sound: !self.no_speed_of_sound,
                ..Default::default()
            });
        config
    }
}

/// The central unit's site name is its site file's `name`; a `--site-name`
/// given as well must say the same, for the other nodes take theirs from
/// the flag and a central unit serving another name would never meet them.
pub fn check_site_name(given: Option<&str>, in_file: &str, file: &str) -> Result<(), String> {
    match given {
        Some(given) if given != in_file => Err(format!(
            "--site-name {given:?} differs from the name {in_file:?} in the site file {file}: \
             the central unit takes the name from the file; give the same name to every node \
             or leave --site-name out here"
        )),
        _ => Ok(()),
    }
}
