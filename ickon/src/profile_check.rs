//! Every crate of the workspace is named in the root `Cargo.toml`'s
//! `[profile.dev.package]`: the dev profile optimises every crate (what the
//! dependencies need) and sets the workspace's own back, one by one, so a
//! crate missing there would be built optimised and without line tables.

use std::collections::BTreeSet;

use crate::import_check::{crate_dirs, root};

/// The `[package] name` of the crate at `dir`.
fn package_name(dir: &std::path::Path) -> String {
    let text = std::fs::read_to_string(dir.join("Cargo.toml")).expect("Cargo.toml is readable");
    let doc: toml::Table = text.parse().expect("Cargo.toml is TOML");
    doc["package"]["name"]
        .as_str()
        .expect("a package name")
        .to_string()
}

#[test]
fn every_workspace_crate_has_its_own_dev_profile() {
    let text = std::fs::read_to_string(root().join("Cargo.toml")).expect("Cargo.toml is readable");
    let doc: toml::Table = text.parse().expect("Cargo.toml is TOML");
    let named: BTreeSet<&str> = doc["profile"]["dev"]["package"]
        .as_table()
        .expect("[profile.dev.package]")
        .keys()
        .map(String::as_str)
        .collect();
    let crates: BTreeSet<String> = crate_dirs().iter().map(|d| package_name(d)).collect();
    assert!(crates.len() > 10, "{crates:?}");
    let missing: Vec<&String> = crates
        .iter()
        .filter(|c| !named.contains(c.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "not in [profile.dev.package] of Cargo.toml: {missing:?}"
    );
    assert!(
        !named.contains("*"),
        "a glob overrides the build scripts' profile too"
    );
}
