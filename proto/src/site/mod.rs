//! The site model: floor plan, cells, transmitters, MSU geometry, routes and
//! robots, read from TOML and validated into typed values.
//!
//! [`Site::from_toml`] reports every problem of a file at once, each with its
//! line, column and field ([`SiteError`]); it never panics. The built-in default
//! site ([`DEFAULT_SITE_TOML`], `deploy/sites/lab.toml`) is compiled in so that
//! every command works with no file given. See that file for the commented
//! format.

pub mod geometry;
mod model;
mod raw;
mod validate;

pub use model::*;

use std::path::Path;

use thiserror::Error;

/// The default site, `deploy/sites/lab.toml`, compiled into every binary.
pub const DEFAULT_SITE_TOML: &str = include_str!("../../../deploy/sites/lab.toml");

/// The name shown for the built-in site in messages.
pub const DEFAULT_SITE_FILE_NAME: &str = "<built-in lab.toml>";

/// One problem found in a site file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiteIssue {
    /// 1-based line of the offending value (0 when the problem concerns the whole file).
    pub line: usize,
    /// 1-based column of the offending value.
    pub column: usize,
    /// Dotted path of the field, e.g. `transmitters[3].position`.
    pub field: String,
    /// What is wrong, in plain words.
    pub message: String,
}

/// A site file that could not be read or is not valid.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SiteError {
    /// The file could not be read.
    #[error("cannot read site file {file}: {reason}")]
    Io {
        /// The file.
        file: String,
        /// The operating system's reason.
        reason: String,
    },
    /// The file was read but has problems: every one of them is listed.
    #[error("{}", render_issues(file, issues))]
    Invalid {
        /// The file.
        file: String,
        /// Every problem found, in file order.
        issues: Vec<SiteIssue>,
    },
}

fn render_issues(file: &str, issues: &[SiteIssue]) -> String {
    let mut out = format!(
        "site file {file} has {} problem{}:",
        issues.len(),
        if issues.len() == 1 { "" } else { "s" }
    );
    for i in issues {
        out.push_str(&format!(
            "\n  {file}:{}:{}: {}: {}",
            i.line, i.column, i.field, i.message
        ));
    }
    out
}

impl Site {
    /// Parses and validates a site from TOML text; `file` names it in messages.
    pub fn from_toml(text: &str, file: &str) -> Result<Site, SiteError> {
        validate::parse_and_validate(text, file)
    }

    /// Reads, parses and validates a site file.
    pub fn from_file(path: &Path) -> Result<Site, SiteError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SiteError::Io {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        Site::from_toml(&text, &file)
    }

    /// The built-in default site.
    pub fn default_site() -> Site {
        // The built-in file is checked by a unit test, so this cannot fail in a
        // released build; keep a clear message should it ever be broken.
        Site::from_toml(DEFAULT_SITE_TOML, DEFAULT_SITE_FILE_NAME)
            .unwrap_or_else(|e| panic!("the built-in site is invalid: {e}"))
    }

    /// Loads `path` if given, else the built-in site; also returns the TOML text
    /// (to serve to other processes) and the name to show for it.
    pub fn load_or_default(path: Option<&Path>) -> Result<(Site, String, String), SiteError> {
        match path {
            Some(p) => {
                let file = p.display().to_string();
                let text = std::fs::read_to_string(p).map_err(|e| SiteError::Io {
                    file: file.clone(),
                    reason: e.to_string(),
                })?;
                let site = Site::from_toml(&text, &file)?;
                Ok((site, text, file))
            }
            None => Ok((
                Site::default_site(),
                DEFAULT_SITE_TOML.to_string(),
                DEFAULT_SITE_FILE_NAME.to_string(),
            )),
        }
    }
}

#[cfg(test)]
mod tests;
