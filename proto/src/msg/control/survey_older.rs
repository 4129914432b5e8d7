//! What the older layouts of `central/survey` share: the calibration's
//! head as it has always been, followed by offsets of the layout's own
//! kind (each read as a [`TransmitterOffset`]). Read with the site's
//! speed of sound, which is what an MSU of those times solved with.

use serde::{Deserialize, Serialize};

use super::{SurveyCalibration, TransmitterOffset};

/// A calibration of an older layout whose offsets are `O` (the fields
/// mean what [`SurveyCalibration`]'s of the same name do).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OlderCalibration<O> {
    /// The epoch of the central unit that made it.
    pub epoch: u64,
    /// Its version in that epoch.
    pub version: u32,
    /// Fixes of the fleet behind it.
    pub fixes_taken: u64,
    /// One per transmitter of the site.
    pub offsets: Vec<O>,
}

impl<O: Into<TransmitterOffset>> From<OlderCalibration<O>> for SurveyCalibration {
    fn from(old: OlderCalibration<O>) -> Self {
        SurveyCalibration {
            epoch: old.epoch,
            version: old.version,
            fixes_taken: old.fixes_taken,
            offsets: old.offsets.into_iter().map(Into::into).collect(),
            speed_of_sound_m_s: 0.0,
            speed_of_sound_sigma_m_s: 0.0,
        }
    }
}
