//! The MSU configuration file (`ickon-msu --config FILE`, TOML): one block
//! per input (`[fix]`, `[range_differences]`, `[odometry]`, `[gyro]`,
//! `[receiver_heading]`) with its noise and its gate in data-sheet units,
//! the filter-wide tuning apart (`[filter]`, with the estimator's own
//! remaining parameters in `[filter.params]`), and the drive geometry
//! (`[robot]`), a Marvelmind kit's settings (`[marvelmind]`), and the ROS 2 side (`[ros2]`, the fields of the `--ros2-*`
//! flags; a flag given with another value than its default wins). Every key is optional except `[filter] estimator`; what is
//! left out keeps the estimator's defaults. Validated like the site file:
//! every problem at once, each with its line and column. A commented example
//! is `deploy/msu.toml`.

mod apply;
mod raw;
mod validate;

// The tests use the `[ros2]` block, which needs the Zenoh node.
#[cfg(all(test, feature = "zenoh"))]
mod tests;

use std::path::Path;

use ickon_fusion::estimator::{EstimatorConfig, UnknownEstimator, WheelGeometry};
use ickon_proto::site::Site;
use thiserror::Error;

use crate::config::MsuConfig;
use crate::config::apply_site;
use crate::hedgehog::MarvelmindSettings;

/// Distance per encoder tick of a Pioneer 3-DX, metres (its 19.5 cm wheel,
/// 500-line encoder and 38.3:1 gear): the drive the ICKON paper used.
pub const PIONEER_M_PER_TICK: f64 = 2.0 * std::f64::consts::PI * 0.0975 / (500.0 * 38.3);
/// Wheel base of a Pioneer 3-DX, metres.
pub const PIONEER_WHEEL_BASE_M: f64 = 0.33;
/// One-sigma timing noise of one arrival when the file gives none, seconds
/// (the ICKON paper's receivers: 50 us).
pub const DEFAULT_TIMING_SIGMA_S: f64 = 50e-6;

/// One problem in an MSU configuration file.
pub type ConfigIssue = ickon_proto::file_issue::FileIssue;

/// An MSU configuration file that could not be read or is not valid.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MsuConfigError {
    /// The file could not be read.
    #[error("cannot read MSU configuration {file}: {reason}")]
    Io {
        /// The file.
        file: String,
        /// The operating system's reason.
        reason: String,
    },
    /// The file was read but has problems: every one is listed.
    #[error("{}", render(file, issues))]
    Invalid {
        /// The file.
        file: String,
        /// Every problem found, in file order.
        issues: Vec<ConfigIssue>,
    },
}

fn render(file: &str, issues: &[ConfigIssue]) -> String {
    ickon_proto::file_issue::render_issues("MSU configuration", file, issues)
}

/// How the fix solver judges one cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverTuning {
    /// One-sigma timing noise of one arrival, seconds.
    pub timing_sigma_s: f64,
    /// Largest range residual a used signal may keep, metres; `None`: four
    /// sigma of the range noise, and never below 5 cm.
    pub residual_gate_m: Option<f64>,
    /// Largest one-sigma position uncertainty of a fix, metres.
    pub max_fix_sigma_m: f64,
}

impl Default for SolverTuning {
    fn default() -> Self {
        Self {
            timing_sigma_s: DEFAULT_TIMING_SIGMA_S,
            residual_gate_m: None,
            max_fix_sigma_m: crate::config::DEFAULT_MAX_FIX_SIGMA_M,
        }
    }
}

/// A robot the site file does not list, without `filter.start` in its
/// MSU file: nothing says where it starts.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "robot {robot:?} is not in site {site:?} and its MSU file gives no start pose: \
     set filter.start = [x_m, y_m, heading_deg] (where the robot is switched on)"
)]
pub struct MissingStart {
    /// The robot's id.
    pub robot: String,
    /// The site's name.
    pub site: String,
}

/// Everything an MSU agent is tuned with: what the file says, or the
/// defaults of one estimator. The site supplies the rest (start pose,
/// receiver height, floor) through [`MsuTuning::estimator_for`] and
/// [`MsuTuning::msu_config`].
#[derive(Debug, Clone, PartialEq)]
pub struct MsuTuning {
    /// The estimator with the file's tuning, before the site's values.
    pub estimator: EstimatorConfig,
    /// A start pose the file gives (`x_m, y_m, theta_rad`), over the site's.
    pub start: Option<[f64; 3]>,
    /// The fix solver's noise and gates.
    pub solver: SolverTuning,
    /// The robot's nominal drive geometry.
    pub wheels: WheelGeometry,
    /// How a Marvelmind kit's stream is read (`--receivers marvelmind:...`).
    pub marvelmind: MarvelmindSettings,
    /// Values the chosen estimator has no use for (ignored), with where they are.
    pub warnings: Vec<ConfigIssue>,
    /// The file's `[ros2]` block, when it has one (a build without the
    /// Zenoh node has no ROS 2 link, and refuses the block as unknown).
    #[cfg(feature = "zenoh")]
    pub ros2: Option<crate::ros2::Ros2Options>,
}

impl MsuTuning {
    /// The defaults of estimator `name` on a Pioneer 3-DX drive.
    pub fn defaults(name: &str) -> Result<Self, UnknownEstimator> {
        Ok(Self {
            estimator: EstimatorConfig::default_for(name)?,
            start: None,
            solver: SolverTuning::default(),
            wheels: pioneer_wheels(),
            marvelmind: MarvelmindSettings::default(),
            warnings: Vec::new(),
            #[cfg(feature = "zenoh")]
            ros2: None,
        })
    }

    /// Parses and validates the text of a configuration file; `file` names
    /// it in messages.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, MsuConfigError> {
        validate::parse_and_validate(text, file)
    }

    /// Reads, parses and validates a configuration file.
    pub fn load(path: &Path) -> Result<Self, MsuConfigError> {
        let file = path.display().to_string();
        // A configuration file is a page of text: refuse to read a huge one
        // (a wrong path to a log or a device) into memory.
        const MAX_BYTES: u64 = 1 << 20;
        let text = ickon_proto::text_file::read_bounded(path, MAX_BYTES).map_err(|reason| {
            MsuConfigError::Io {
                file: file.clone(),
                reason,
            }
        })?;
        Self::from_toml(&text, &file)
    }

    /// The estimator name.
    pub fn estimator_name(&self) -> &'static str {
        self.estimator.name()
    }

    /// The estimator configuration for a robot of `site` whose site-file
    /// start is `site_start`: the file's tuning, then the start pose (the
    /// file's if it gives one) and the site's receiver height and floor.
    pub fn estimator_for(&self, site: &Site, site_start: [f64; 3]) -> EstimatorConfig {
        let mut c = self.estimator.clone();
        apply_site(&mut c, site, self.start.unwrap_or(site_start));
        c
    }

    /// The estimator configuration for robot `robot` of `site`: its start
    /// pose is the file's `filter.start` if given, else the robot's start
    /// in the site file. A real site need not list its robots (their
    /// credentials come from `ickon site secure --robots`), so a robot the
    /// site file does not list needs `filter.start`; without either, the
    /// error says so.
    pub fn estimator_for_robot(
        &self,
        site: &Site,
        robot: &str,
    ) -> Result<EstimatorConfig, MissingStart> {
        let listed = site.robots.iter().find(|r| r.id == robot);
        match (self.start, listed) {
            (Some(start), _) => Ok(self.estimator_for(site, start)),
            (None, Some(spec)) => Ok(self.estimator_for(site, spec.start)),
            (None, None) => Err(MissingStart {
                robot: robot.to_string(),
                site: site.name.clone(),
            }),
        }
    }

    /// The fix solver's configuration on `site`.
    pub fn msu_config(&self, site: &Site) -> MsuConfig {
        let mut c = MsuConfig::for_site(site, self.solver.timing_sigma_s, self.wheels);
        if let Some(gate) = self.solver.residual_gate_m {
            c.residual_gate_m = gate;
        }
        c.max_fix_sigma_m = self.solver.max_fix_sigma_m;
        c
    }
}

/// The drive of the ICKON paper's robot (a Pioneer 3-DX).
pub fn pioneer_wheels() -> WheelGeometry {
    WheelGeometry {
        wheel_base_m: PIONEER_WHEEL_BASE_M,
        left_m_per_tick: PIONEER_M_PER_TICK,
        right_m_per_tick: PIONEER_M_PER_TICK,
    }
}
