//! What the MSU knows about its site and its robot ([`MsuConfig`]), built
//! from the site model, shared by the MSU agent
//! process and the virtual-time engine so that both solve alike.

use ickon_fusion::estimator::tdoa_ekf::Floor;
use ickon_fusion::estimator::{EstimatorConfig, UnknownEstimator, WheelGeometry};
use ickon_proto::msg::control::TransmitterEntry;
use ickon_proto::site::Site;

use ickon_proto::site::{Column, Wall};

/// What the MSU knows about its site and its robot.
#[derive(Debug, Clone, PartialEq)]
pub struct MsuConfig {
    /// Speed of sound the MSU assumes, m/s.
    pub speed_of_sound_m_s: f64,
    /// Height of the receivers above the floor, metres.
    pub height_m: f64,
    /// Pointing angle of each receiver from the heading, counter-clockwise, radians.
    pub receiver_angles_rad: Vec<f64>,
    /// The transmitter lookup table.
    pub transmitters: Vec<TransmitterEntry>,
    /// The robot's nominal drive geometry (turns encoder ticks into metres).
    pub wheels: WheelGeometry,
    /// One-sigma timing noise of an arrival, seconds (weights the fix covariance).
    pub timing_sigma_s: f64,
    /// Largest range residual a used signal may keep, metres (reflection gate).
    pub residual_gate_m: f64,
    /// Floor area a fix must lie in (`[min_x, min_y]`, `[max_x, max_y]`, metres):
    /// a solution outside cannot be the robot (a reflection or a wrong root).
    pub floor_bounds_m: Option<[[f64; 2]; 2]>,
    /// Largest acceptable one-sigma position uncertainty of a fix, metres
    /// (larger: degenerate geometry, reported as no fix).
    pub max_fix_sigma_m: f64,
    /// The site's walls and columns: a transmitter they hide from where the
    /// robot is can only be heard by a reflection (empty: nothing blocks).
    pub walls: Vec<Wall>,
    /// See `walls`.
    pub columns: Vec<Column>,
}

/// Largest one-sigma position uncertainty a fix may have before it counts as
/// degenerate geometry, metres.
pub const DEFAULT_MAX_FIX_SIGMA_M: f64 = 0.5;

/// The configuration of estimator `name` for a robot on `site` starting at
/// `start` (`x, y, theta`): the registry's defaults, the start pose, and for
/// `tdoa-ekf` the receivers' height and the floor it must stay on. The MSU
/// agent and the virtual-time engine both start from it.
pub fn estimator_for_site(
    name: &str,
    site: &Site,
    start: [f64; 3],
) -> Result<EstimatorConfig, UnknownEstimator> {
    let mut c = EstimatorConfig::default_for(name)?;
    apply_site(&mut c, site, start);
    Ok(c)
}

/// Gives `c` what only the site knows: the start pose, and for `tdoa-ekf`
/// the receivers' height and the floor it must stay on.
pub(crate) fn apply_site(c: &mut EstimatorConfig, site: &Site, start: [f64; 3]) {
    c.set_initial_pose(start);
    if let EstimatorConfig::TdoaEkf(p) = c {
        p.receiver_height_m = site.msu.height_m;
        let (min_m, max_m) = site.bounds();
        p.floor = Some(Floor { min_m, max_m });
    }
}

impl MsuConfig {
    /// The MSU configuration for `site`: its speed of sound, MSU geometry,
    /// transmitter table and floor bounds; `timing_sigma_s` is the one-sigma
    /// timing noise of one arrival (the MSU's data sheet), `wheels` the robot's
    /// nominal drive geometry.
    pub fn for_site(site: &Site, timing_sigma_s: f64, wheels: WheelGeometry) -> MsuConfig {
        MsuConfig {
            speed_of_sound_m_s: site.speed_of_sound_m_s,
            height_m: site.msu.height_m,
            receiver_angles_rad: site.msu.receiver_angles_rad.clone(),
            transmitters: site
                .transmitters
                .iter()
                .map(|t| TransmitterEntry {
                    tx_id: t.id,
                    cell_id: t.cell.clone(),
                    x_m: t.position_m[0],
                    y_m: t.position_m[1],
                    z_m: t.position_m[2],
                })
                .collect(),
            wheels,
            timing_sigma_s,
            // Four sigma of range noise, and never below 5 cm: residuals smaller
            // than that are not reflections worth losing a signal over.
            residual_gate_m: (4.0 * timing_sigma_s * site.speed_of_sound_m_s).max(0.05),
            floor_bounds_m: {
                let (lo, hi) = site.bounds();
                Some([lo, hi])
            },
            max_fix_sigma_m: DEFAULT_MAX_FIX_SIGMA_M,
            walls: site.walls.clone(),
            columns: site.columns.clone(),
        }
    }
}
