//! Where the `ickon` binary under test is.
//!
//! Cargo tells an integration test where its own package's binaries are
//! (`CARGO_BIN_EXE_<name>`), never another package's. So this package
//! builds the program itself, as its example `ickon` (the `ickon` library's
//! `main`): every build of the tests builds it too, from the same sources
//! with the same features, into `target/<profile>/examples/ickon`, beside
//! the test binaries' `target/<profile>/deps/`. `ICKON_BIN` names another
//! binary to test instead (an installed one, a release build).
//!
//! A build that names single test binaries (`cargo test --test mesh`)
//! builds no example; so a binary older than one of the sources Cargo
//! built it from is refused, with the command that builds it, rather than
//! tested in the place of the current code.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::SystemTime;

/// The variable that names the binary to test instead of the one built here.
pub const BIN_VARIABLE: &str = "ICKON_BIN";

/// The `ickon` binary under test, as a program to start:
/// `Command::new(ICKON)`. Found (and checked) at its first use.
pub const ICKON: Ickon = Ickon;

/// The `ickon` binary under test (see [`ICKON`]).
#[derive(Debug, Clone, Copy)]
pub struct Ickon;

impl AsRef<OsStr> for Ickon {
    fn as_ref(&self) -> &OsStr {
        path().as_os_str()
    }
}

impl AsRef<Path> for Ickon {
    fn as_ref(&self) -> &Path {
        path()
    }
}

/// The binary's path; panics, saying what to do, when it is missing or
/// older than the sources it is built from.
pub fn path() -> &'static Path {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        if let Some(named) = std::env::var_os(BIN_VARIABLE).filter(|v| !v.is_empty()) {
            let named = PathBuf::from(named);
            assert!(
                named.is_file(),
                "{BIN_VARIABLE} names {}, which is not a file",
                named.display()
            );
            return named;
        }
        let built = built_here();
        let built_at = std::fs::metadata(&built)
            .and_then(|m| m.modified())
            .unwrap_or_else(|e| {
                panic!(
                    "no ickon binary at {} ({e}): build it with \
                     `cargo build -p ickon-tests --example ickon` \
                     (the README's test command does)",
                    built.display()
                )
            });
        if let Some(newer) = newer_source(&built, built_at) {
            panic!(
                "the ickon binary at {} is older than {}: build it with \
                 `cargo build -p ickon-tests --example ickon` \
                 (the README's test command does)",
                built.display(),
                newer.display()
            );
        }
        built
    })
}

/// `target/<profile>/examples/ickon`, from this test binary's place in
/// `target/<profile>/deps/`.
fn built_here() -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary knows its path");
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("a test binary sits in target/<profile>/deps/");
    profile_dir
        .join("examples")
        .join(format!("ickon{}", std::env::consts::EXE_SUFFIX))
}

/// A source the binary at `built` is built from, as Cargo lists them in
/// the dep-info file beside it (every file of the workspace's crates that
/// the compiler read: Rust sources and the files they embed), that was
/// modified after `than` or is gone; `None` when every one is older.
fn newer_source(built: &Path, than: SystemTime) -> Option<PathBuf> {
    let dep_info = std::fs::read_to_string(built.with_extension("d")).ok()?;
    let (_, sources) = dep_info.lines().next()?.split_once(": ")?;
    sources_of(sources).into_iter().find(|source| {
        std::fs::metadata(source)
            .and_then(|m| m.modified())
            .map_or(true, |modified| modified > than)
    })
}

/// The paths of a dep-info line, separated by spaces (a space inside a
/// path is escaped with a backslash).
fn sources_of(line: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut current = String::new();
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '\\' => current.extend(chars.next()),
            ' ' => {
                if !current.is_empty() {
                    out.push(PathBuf::from(std::mem::take(&mut current)));
                }
            }
            c => current.push(c),
        }
    }
    if !current.is_empty() {
        out.push(PathBuf::from(current));
    }
    out
}
