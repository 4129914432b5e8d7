//! The site file parser fed random text and mutations of the built-in
//! sites: it never panics, and a site it accepts has the properties every
//! consumer relies on.

use proptest::prelude::*;

use super::config;
use super::mutate::{apply_text, text_mutations};
use crate::site::{BUILTIN_SITES, Site};

/// Text for the parser: random, or a built-in site mutated.
fn site_text() -> impl Strategy<Value = String> {
    let mutated = (0..BUILTIN_SITES.len(), text_mutations())
        .prop_map(|(i, m)| apply_text(BUILTIN_SITES[i].1, &m));
    prop_oneof![1 => "\\PC{0,200}", 1 => "[a-z_\\[\\]=\". 0-9\n]{0,300}", 8 => mutated]
}

fn check(site: &Site) -> Result<(), TestCaseError> {
    prop_assert!(site.speed_of_sound_m_s.is_finite() && site.speed_of_sound_m_s > 0.0);
    prop_assert!(!site.cells.is_empty());
    for t in &site.transmitters {
        prop_assert!(t.position_m.iter().all(|v| v.is_finite()), "{:?}", t);
        prop_assert!(site.cell(&t.cell).is_some(), "{:?}", t);
    }
    for c in &site.cells {
        prop_assert!(c.area_m2().is_finite(), "{:?}", c);
    }
    prop_assert!(site.area_m2().is_finite());
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn fuzz_site_file(text in site_text()) {
        if let Ok(site) = Site::from_toml(&text, "fuzz.toml") {
            check(&site)?;
        }
    }
}

#[test]
fn mutated_sites_are_often_still_valid_so_the_checks_run() {
    use proptest::strategy::ValueTree;
    let mut rng = proptest::test_runner::TestRunner::deterministic();
    let accepted = (0..300)
        .filter(|_| {
            let text = site_text().new_tree(&mut rng).unwrap().current();
            Site::from_toml(&text, "fuzz.toml").is_ok()
        })
        .count();
    assert!(accepted > 15, "{accepted} of 300 accepted");
}

/// Found by `fuzz_site_file`: a cell corner at -1e308 was accepted and the
/// cell's area was infinite.
#[test]
fn a_cell_corner_at_minus_1e308_is_refused() {
    let text = BUILTIN_SITES[0]
        .1
        .replace("[21.0, 4.0], [16.0, 4.0]]", "[21.0, 4.0], [-1e308, 4.0]]");
    assert_ne!(text, BUILTIN_SITES[0].1, "the lab's c3 polygon changed");
    let err = Site::from_toml(&text, "fuzz.toml").unwrap_err();
    assert!(err.to_string().contains("within"), "{err}");
}
