//! The speed of sound the central unit learns and publishes: what the
//! fleet's fixes say of it (`survey_calibration`), and the same fused with
//! the cell boards' air temperatures (`air_temperature`).

/// The speed of sound learnt from the fleet's fixes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearntSpeed {
    /// The speed of sound, m/s.
    pub speed_m_s: f64,
    /// Its one-sigma uncertainty, m/s.
    pub sigma_m_s: f64,
    /// Its relative change from the site's speed.
    pub scale: f64,
}
