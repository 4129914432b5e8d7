//! Site files for tests.

use std::path::{Path, PathBuf};

/// Writes the built-in `lab` site under the name `site` into `dir` and
/// returns its path: each test's own name keeps its keys apart from every
/// other test's on a shared loopback.
pub fn lab_site_file(dir: &Path, site: &str) -> PathBuf {
    let text = ickon_proto::site::DEFAULT_SITE_TOML.replacen(
        "name = \"lab\"",
        &format!("name = \"{site}\""),
        1,
    );
    let file = dir.join(format!("{site}.toml"));
    std::fs::write(&file, text).expect("site file");
    file
}
