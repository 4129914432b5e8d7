//! Where the real measurement data of the tests is: one setting, the
//! environment variable `ICKON_DATA`, with `../shared/data` beside the
//! repository as its default.

use std::path::PathBuf;

/// The environment variable naming the folder that holds `util/`,
/// `util-imu/` and `plaza/`.
pub const DATA_VARIABLE: &str = "ICKON_DATA";

/// The folder of the real data: `$ICKON_DATA`, else `../shared/data`
/// beside the repository.
pub fn data_root() -> PathBuf {
    std::env::var_os(DATA_VARIABLE)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")))
}

/// The data set `name` (`util`, `util-imu`, `plaza`), or `None` when it is
/// absent: the test says so in one line naming the variable and passes,
/// except under `CI=true`, where absent data fails it.
pub fn real_data(name: &str) -> Option<PathBuf> {
    let dir = data_root().join(name);
    if dir.is_dir() {
        return Some(dir);
    }
    let message = format!(
        "real data {} not found: set {DATA_VARIABLE} to the folder that holds util/, util-imu/ and plaza/",
        dir.display()
    );
    assert!(std::env::var("CI").as_deref() != Ok("true"), "{message}");
    eprintln!("skipped: {message}");
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_absent_data_set_is_skipped_outside_ci_and_named() {
        if std::env::var("CI").as_deref() == Ok("true") {
            // Under CI absent data fails: shown by the assertion above.
            return;
        }
        assert_eq!(real_data("no-such-data-set"), None);
    }

    #[test]
    fn the_default_is_beside_the_repository() {
        if std::env::var_os(DATA_VARIABLE).is_none() {
            assert!(data_root().ends_with("shared/data"));
        }
    }
}
