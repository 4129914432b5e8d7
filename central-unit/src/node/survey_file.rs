//! The survey calibration kept in a file (`--survey-file`): read at start,
//! written every minute and at shutdown, so that a restart goes on from
//! what the fleet taught it.

use ickon_proto::site::Site;

use crate::core::CentralCore;
use crate::survey_calibration::SavedCalibration;

/// Largest survey calibration file read, bytes (a site of 1000
/// transmitters keeps about 9 million numbers; this is far above any site
/// this unit can serve, and below what would exhaust memory).
const MAX_SURVEY_FILE_BYTES: u64 = 256 << 20;

/// How often the survey calibration file is written.
pub(super) const SURVEY_SAVE_PERIOD: std::time::Duration = std::time::Duration::from_secs(60);

/// Reads the survey calibration kept in `path` for `site`: `Ok(None)` when
/// there is no file or it is of another site or table (said in a
/// warning); `Err` with the file and the reason when it cannot be read or
/// its numbers are broken.
pub fn load_survey_file(
    path: &std::path::Path,
    site: &Site,
    config: crate::survey_calibration::CalibrationConfig,
) -> Result<Option<SavedCalibration>, String> {
    use crate::survey_calibration::{SavedMismatch, SurveyCalibration};
    let shown = path.display();
    let size = match std::fs::metadata(path) {
        Ok(m) => m.len(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{shown}: {e}")),
    };
    if size > MAX_SURVEY_FILE_BYTES {
        return Err(format!(
            "{shown}: {size} bytes, more than a survey calibration ({MAX_SURVEY_FILE_BYTES} at most)"
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("{shown}: {e}"))?;
    let saved: SavedCalibration = serde_json::from_str(&text)
        .map_err(|e| format!("{shown}: not a survey calibration: {e}"))?;
    match SurveyCalibration::restored(site, config, &saved) {
        Ok(_) => Ok(Some(saved)),
        Err(SavedMismatch::OtherSite) => {
            tracing::warn!(
                "{shown}: the calibration is of another site or transmitter table: starting from the survey (the file is overwritten)"
            );
            Ok(None)
        }
        Err(e @ SavedMismatch::Broken(_)) => Err(format!("{shown}: {e}")),
    }
}

/// Writes `saved` to `path` through a temporary file beside it, so that a
/// crash mid-write leaves the previous file whole.
pub(super) fn save_survey_file(path: &std::path::Path, saved: &SavedCalibration) {
    let tmp = path.with_extension("tmp");
    let written = serde_json::to_vec(saved)
        .map_err(std::io::Error::other)
        .and_then(|bytes| std::fs::write(&tmp, bytes))
        .and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = written {
        tracing::warn!("survey calibration not saved to {}: {e}", path.display());
    }
}

/// Goes on with the survey calibration kept in the file, if any.
pub(super) fn restore_survey(core: &mut CentralCore, survey_file: &SurveyFile) {
    if let Some(saved) = &survey_file.saved {
        // Checked against this site when the file was read.
        if core.restore_survey(saved).is_ok() {
            tracing::info!(
                "survey calibration goes on from {} fixes kept in the file",
                saved.fixes_taken
            );
        }
    }
}

/// Where the survey calibration is kept, and what was read from it.
#[derive(Debug, Clone, Default)]
pub struct SurveyFile {
    /// The file (`--survey-file`); `None`: not kept.
    pub path: Option<std::path::PathBuf>,
    /// What it held for this site, checked.
    pub saved: Option<SavedCalibration>,
}

impl SurveyFile {
    pub(super) fn save(&self, core: &CentralCore) {
        if let (Some(path), Some(saved)) = (&self.path, core.survey_saved()) {
            save_survey_file(path, &saved);
        }
    }
}
