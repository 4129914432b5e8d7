//! `scripts/figures.py`, the script that measures every figure of
//! `docs/estimators.md` and `docs/performance.md`, kept working: its quick
//! mode run on cheap sections against the `ickon` under test (the
//! commands, their JSON and the script's reading of it), a failing command
//! reported without a file written, and every section's region present
//! once in its page. It needs Python 3: `ICKON_FIGURES_PYTHON` names it
//! (`.ci/run` does), else `python3` on the PATH, else the tests are skipped
//! with a note. The real data's section runs where `ICKON_DATA` has the data.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use support::ICKON;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate is in the repository")
        .to_path_buf()
}

/// The variable naming the Python 3 that runs the script (`.ci/run` names
/// one); without it `python3` on the PATH, and the tests skip where there
/// is none.
const PYTHON_VARIABLE: &str = "ICKON_FIGURES_PYTHON";

/// `PYTHON scripts/figures.py ARGS`, its output; `None` (skipped, said in
/// one line) when no Python is named and `python3` is not on the PATH.
fn figures(args: &[&str]) -> Option<Output> {
    let named = std::env::var_os(PYTHON_VARIABLE).filter(|v| !v.is_empty());
    let python = named.clone().unwrap_or_else(|| "python3".into());
    match Command::new(&python)
        .arg(repo().join("scripts/figures.py"))
        .args(args)
        .output()
    {
        Ok(out) => Some(out),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound && named.is_none() => {
            eprintln!(
                "skipped: no python3 on the PATH for scripts/figures.py ({PYTHON_VARIABLE} names one)"
            );
            None
        }
        Err(e) => panic!(
            "{} does not run ({e}): the figures script needs Python 3",
            python.to_string_lossy()
        ),
    }
}

fn text(out: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A generated file: the machine's header and a table row of numbers.
fn assert_generated(file: &Path, row_start: &str) {
    let body = std::fs::read_to_string(file)
        .unwrap_or_else(|e| panic!("{} was written ({e})", file.display()));
    for fact in [
        "| git commit |",
        "| CPU |",
        "| cores |",
        "| load average at start |",
        "| rustc |",
        "| build profile |",
        "Smoke run",
    ] {
        assert!(
            body.contains(fact),
            "no `{fact}` in {}:\n{body}",
            file.display()
        );
    }
    let row = body
        .lines()
        .find(|l| l.starts_with(row_start))
        .unwrap_or_else(|| panic!("no row `{row_start}` in {}:\n{body}", file.display()));
    assert!(
        row.chars().any(|c| c.is_ascii_digit()) && !row.contains("| - |"),
        "row without figures: {row}"
    );
}

#[test]
fn quick_mode_measures_the_recorder_into_its_own_folder() {
    let out_dir = tempfile::tempdir().expect("temp dir");
    let ickon: &Path = ICKON.as_ref();
    let Some(out) = figures(&[
        "--quick",
        "--only",
        "record",
        "--ickon",
        ickon.to_str().expect("utf-8 path"),
        "--out",
        out_dir.path().to_str().expect("utf-8 path"),
    ]) else {
        return;
    };
    assert!(out.status.success(), "{}", text(&out));
    assert_generated(&out_dir.path().join("record.md"), "| 2 |");
    let progress = String::from_utf8_lossy(&out.stderr);
    assert!(progress.contains("figures [record] $ "), "{}", text(&out));
}

#[test]
fn quick_mode_replays_the_real_data() {
    let (Some(_), Some(_), Some(root)) = (
        ickon_testkit::data::real_data("util"),
        ickon_testkit::data::real_data("plaza"),
        ickon_testkit::data::data_root(),
    ) else {
        return;
    };
    let out_dir = tempfile::tempdir().expect("temp dir");
    let ickon: &Path = ICKON.as_ref();
    let Some(out) = figures(&[
        "--quick",
        "--only",
        "plaza,util",
        "--ickon",
        ickon.to_str().expect("utf-8 path"),
        "--data",
        root.to_str().expect("utf-8 path"),
        "--out",
        out_dir.path().to_str().expect("utf-8 path"),
    ]) else {
        return;
    };
    assert!(out.status.success(), "{}", text(&out));
    assert_generated(&out_dir.path().join("plaza.md"), "| Plaza1 | `tdoa-ekf` |");
    assert_generated(
        &out_dir.path().join("util.md"),
        "| const1-trial1-tdoa2 | `tdoa-ekf` |",
    );
}

#[test]
fn a_failing_command_is_named_and_nothing_is_written() {
    let dir = tempfile::tempdir().expect("temp dir");
    let failing = dir.path().join("ickon");
    std::fs::write(
        &failing,
        "#!/bin/sh\n[ \"$1\" = --version ] && exit 0\necho 'the mesh did not start' >&2\nexit 3\n",
    )
    .expect("write");
    let mut perms = std::fs::metadata(&failing).expect("meta").permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o755);
    std::fs::set_permissions(&failing, perms).expect("chmod");
    let out_dir = dir.path().join("out");
    let Some(out) = figures(&[
        "--quick",
        "--only",
        "live",
        "--ickon",
        failing.to_str().expect("utf-8 path"),
        "--out",
        out_dir.to_str().expect("utf-8 path"),
    ]) else {
        return;
    };
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("exited with status 3") && err.contains("the mesh did not start"),
        "{}",
        text(&out)
    );
    let written = std::fs::read_dir(&out_dir).map_or(0, |d| d.count());
    assert_eq!(written, 0, "files written after a failure");
}

#[test]
fn every_section_has_one_region_in_its_page() {
    let Some(out) = figures(&["--list"]) else {
        return;
    };
    assert!(out.status.success(), "{}", text(&out));
    let list = String::from_utf8_lossy(&out.stdout);
    let mut sections = 0;
    for line in list.lines() {
        let mut words = line.split_whitespace();
        let (Some(name), Some(page)) = (words.next(), words.next()) else {
            continue;
        };
        sections += 1;
        let body = std::fs::read_to_string(repo().join(page)).expect("the page exists");
        for marker in [
            format!("<!-- figures:{name} -->"),
            format!("<!-- /figures:{name} -->"),
        ] {
            assert_eq!(
                body.matches(&marker).count(),
                1,
                "{page} must hold `{marker}` once"
            );
        }
    }
    assert!(sections >= 20, "too few sections listed:\n{list}");
}
