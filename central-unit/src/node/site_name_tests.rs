//! `--site-name` against the site file's name.

use super::check_site_name;

#[test]
fn the_name_comes_from_the_file_and_a_given_name_must_match_it() {
    assert!(check_site_name(None, "acme", "/etc/ickon/site.toml").is_ok());
    assert!(check_site_name(Some("acme"), "acme", "/etc/ickon/site.toml").is_ok());
    let e = check_site_name(Some("lab"), "acme", "/etc/ickon/site.toml").expect_err("mismatch");
    assert!(e.contains("--site-name \"lab\""), "{e}");
    assert!(e.contains("\"acme\""), "{e}");
    assert!(e.contains("/etc/ickon/site.toml"), "{e}");
}
