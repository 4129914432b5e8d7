//! `ickon site check`.

use std::path::Path;
use std::process::ExitCode;

/// Validates a site file and prints its summary.
pub fn check(_file: Option<&Path>) -> ExitCode {
    eprintln!("error: site check is not available in this build yet");
    ExitCode::from(crate::cli::EXIT_FAILURE)
}
