//! `ickon site check` as a user runs it: exit codes and messages.

use std::process::Command;
use support::ICKON;

fn ickon() -> Command {
    Command::new(ICKON)
}

fn lab_toml() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../deploy/sites/lab.toml"
    ))
    .unwrap()
}

fn temp_file(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("ickon-site-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn default_site_checks_clean_and_prints_a_summary() {
    let out = ickon()
        .args([
            "site",
            "check",
            concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/sites/lab.toml"),
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("4 cells, 16 transmitters"), "{text}");
    assert!(text.contains("route-1"), "{text}");
    // With no file the built-in copy is checked: the same summary.
    let builtin = ickon().args(["site", "check"]).output().unwrap();
    assert!(builtin.status.success());
}

#[test]
fn broken_site_exits_2_naming_line_and_field() {
    let text = lab_toml().replacen(
        "position = [6.8, 0.6, 2.65]",
        "position = [9.9, 0.6, 2.65]",
        1,
    );
    let path = temp_file("outside.toml", &text);
    let out = ickon().args(["site", "check"]).arg(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    let line = text[..text.find("[9.9, 0.6").unwrap()]
        .matches('\n')
        .count()
        + 1;
    assert!(err.contains(&format!("outside.toml:{line}:")), "{err}");
    assert!(err.contains("transmitters[1].position"), "{err}");
    assert!(out.stdout.is_empty());
}

#[test]
fn unreadable_and_garbage_files_exit_2() {
    let out = ickon()
        .args(["site", "check", "/nonexistent/lab.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
    let path = temp_file("garbage.toml", "\u{0}\u{1}not toml at all [[[");
    let out = ickon().args(["site", "check"]).arg(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}
