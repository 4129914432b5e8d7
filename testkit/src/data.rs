//! Where the real measurement data of the tests is, and whether a test
//! that needs it may skip: the data is opt-in.
//!
//! - `ICKON_DATA` names the folder that holds `util/`, `util-imu/` and
//!   `plaza/`. Unset (or a data set missing under it), a test that needs
//!   the data says so in one line and passes, so that a clean clone's
//!   test command passes anywhere, hosted CI included.
//! - `ICKON_REQUIRE_DATA=1` turns that skip into a failure: the project's
//!   own CI (`.ci/run`) sets it together with `ICKON_DATA`, so that a
//!   missing or misplaced data set cannot pass unnoticed there.

use std::path::{Path, PathBuf};

/// The environment variable naming the folder that holds `util/`,
/// `util-imu/` and `plaza/`.
pub const DATA_VARIABLE: &str = "ICKON_DATA";

/// The environment variable that, set to `1`, makes absent data a failure
/// instead of a skip.
pub const REQUIRE_VARIABLE: &str = "ICKON_REQUIRE_DATA";

/// The folder named by `$ICKON_DATA`, or `None` when it is unset or empty.
pub fn data_root() -> Option<PathBuf> {
    std::env::var_os(DATA_VARIABLE)
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
}

/// Whether `$ICKON_REQUIRE_DATA` asks for the data (`1`).
pub fn data_required() -> bool {
    std::env::var(REQUIRE_VARIABLE).is_ok_and(|v| v.trim() == "1")
}

/// The data set `name` (`util`, `util-imu`, `plaza`), or `None` (the
/// caller returns: the test is skipped) when it is absent, after one line
/// on stderr naming what is missing.
///
/// # Panics
/// When the data set is absent and `ICKON_REQUIRE_DATA=1`.
pub fn real_data(name: &str) -> Option<PathBuf> {
    match locate(data_root().as_deref(), name) {
        Ok(dir) => Some(dir),
        Err(why) => {
            assert!(!data_required(), "{why} ({REQUIRE_VARIABLE}=1)");
            eprintln!("skipped: {why}");
            None
        }
    }
}

/// The data set `name` under `root`, or why it cannot be used.
fn locate(root: Option<&Path>, name: &str) -> Result<PathBuf, String> {
    let Some(root) = root else {
        return Err(format!(
            "real data `{name}` not used: {DATA_VARIABLE} is unset (set it to the folder that holds util/, util-imu/ and plaza/)"
        ));
    };
    let dir = root.join(name);
    if dir.is_dir() {
        Ok(dir)
    } else {
        Err(format!(
            "real data `{name}` not found at {} ({DATA_VARIABLE}={})",
            dir.display(),
            root.display()
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unset_variable_is_named_in_the_reason() {
        let why = locate(None, "plaza").unwrap_err();
        assert!(
            why.contains(DATA_VARIABLE) && why.contains("plaza"),
            "{why}"
        );
    }

    #[test]
    fn a_missing_data_set_is_named_with_its_path() {
        let root = std::env::temp_dir().join(format!("ickon-no-data-{}", std::process::id()));
        let why = locate(Some(&root), "util").unwrap_err();
        assert!(
            why.contains(&root.join("util").display().to_string()),
            "{why}"
        );
    }

    #[test]
    fn a_present_data_set_is_found() {
        let root = std::env::temp_dir().join(format!("ickon-data-{}", std::process::id()));
        std::fs::create_dir_all(root.join("util")).unwrap();
        let found = locate(Some(&root), "util");
        std::fs::remove_dir_all(&root).unwrap();
        assert_eq!(found, Ok(root.join("util")));
    }
}
