//! The run file: how `ickon admin` finds an `ickon sim` running on the same
//! machine without being told where to connect.
//!
//! `ickon sim` writes `<run dir>/<site>.json` with the central unit's
//! endpoints once the mesh is up and removes it when it stops. The run dir is
//! `$XDG_RUNTIME_DIR/ickon` (per user, cleared at log-out), or
//! `/tmp/ickon-<uid>` where that variable is not set; it is created with mode
//! 0700 so that no other user can point an admin tool elsewhere.

use std::ffi::OsString;
use std::io::Write;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

use ickon_proto::keys::validate_id;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// What a run file says about a running site.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunFile {
    /// Site name (the `<site>` of every key).
    pub site: String,
    /// Endpoints of the central unit, e.g. `tcp/127.0.0.1:40123`.
    pub central: Vec<String>,
    /// Process id of the launcher that wrote the file.
    pub pid: u32,
    /// When the launcher started, seconds since the Unix epoch.
    pub started_unix_s: u64,
}

/// Why a run file could not be used.
#[derive(Debug, Error)]
pub enum RunFileError {
    /// The site name cannot name a file (it is not a valid id).
    #[error("invalid site name: {0}")]
    BadSite(#[from] ickon_proto::keys::KeyError),
    /// No run file for the site: nothing is running, or it runs elsewhere.
    #[error("no run file {}: no `ickon sim` for this site is running on this machine", path.display())]
    NotFound {
        /// Where it was looked for.
        path: PathBuf,
    },
    /// The run file was left by a launcher that is gone.
    #[error("stale run file {} (process {pid} is gone): no `ickon sim` for this site is running", path.display())]
    Stale {
        /// The file.
        path: PathBuf,
        /// The launcher's process id.
        pid: u32,
    },
    /// The run file exists but is not what `ickon sim` writes.
    #[error("run file {} is malformed: {reason}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Reading or writing failed.
    #[error("run file {}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// The directory holding the run files of one user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    /// The standard location: `$XDG_RUNTIME_DIR/ickon`, else `/tmp/ickon-<uid>`.
    pub fn standard() -> Self {
        Self::from_env(
            std::env::var_os("XDG_RUNTIME_DIR"),
            nix::unistd::getuid().as_raw(),
        )
    }

    /// The location for a given `XDG_RUNTIME_DIR` value and user id (only an
    /// absolute path counts, as the XDG specification says).
    pub fn from_env(xdg_runtime_dir: Option<OsString>, uid: u32) -> Self {
        let path = match xdg_runtime_dir.map(PathBuf::from) {
            Some(dir) if dir.is_absolute() => dir.join("ickon"),
            _ => std::env::temp_dir().join(format!("ickon-{uid}")),
        };
        Self { path }
    }

    /// A run dir at `path` (tests).
    pub fn at(path: impl Into<PathBuf>) -> Self {
        Self { path: path.into() }
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The run file of `site`.
    pub fn file_for(&self, site: &str) -> Result<PathBuf, RunFileError> {
        validate_id(site)?;
        Ok(self.path.join(format!("{site}.json")))
    }

    /// Writes `run` (atomically: a reader never sees half a file).
    pub fn write(&self, run: &RunFile) -> Result<PathBuf, RunFileError> {
        let path = self.file_for(&run.site)?;
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| RunFileError::Io { path, source }
        };
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(&self.path)
            .map_err(io(&self.path))?;
        let tmp = self
            .path
            .join(format!(".{}.{}.tmp", run.site, std::process::id()));
        let text = serde_json::to_string_pretty(run).map_err(|e| RunFileError::Malformed {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .mode(0o600)
            .open(&tmp)
            .map_err(io(&tmp))?;
        file.write_all(text.as_bytes()).map_err(io(&tmp))?;
        std::fs::rename(&tmp, &path).map_err(io(&path))?;
        Ok(path)
    }

    /// Reads the run file of `site`; a file whose launcher is gone is [`RunFileError::Stale`].
    pub fn read(&self, site: &str) -> Result<RunFile, RunFileError> {
        let path = self.file_for(site)?;
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(RunFileError::NotFound { path });
            }
            Err(source) => return Err(RunFileError::Io { path, source }),
        };
        let run: RunFile = serde_json::from_str(&text).map_err(|e| RunFileError::Malformed {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        if run.site != site || run.central.is_empty() {
            return Err(RunFileError::Malformed {
                path,
                reason: format!(
                    "it names site {:?} with {} central endpoints",
                    run.site,
                    run.central.len()
                ),
            });
        }
        if !process_alive(run.pid) {
            return Err(RunFileError::Stale { path, pid: run.pid });
        }
        Ok(run)
    }

    /// Removes the run file of `site` if process `pid` wrote it (a second
    /// launcher of the same site may have replaced it); `true` if removed.
    pub fn remove(&self, site: &str, pid: u32) -> Result<bool, RunFileError> {
        let path = self.file_for(site)?;
        let ours = std::fs::read_to_string(&path)
            .ok()
            .and_then(|t| serde_json::from_str::<RunFile>(&t).ok())
            .is_some_and(|r| r.pid == pid);
        if !ours {
            return Ok(false);
        }
        std::fs::remove_file(&path).map_err(|source| RunFileError::Io { path, source })?;
        Ok(true)
    }

    /// Sites with a run file here (live or not), sorted.
    pub fn sites(&self) -> Vec<String> {
        let mut sites: Vec<String> = std::fs::read_dir(&self.path)
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| {
                let name = e.file_name().into_string().ok()?;
                let site = name.strip_suffix(".json")?;
                validate_id(site).ok()?;
                Some(site.to_string())
            })
            .collect();
        sites.sort();
        sites
    }
}

/// Whether a process with this id exists (signal 0 checks without sending;
/// `EPERM` means it exists but belongs to someone else).
fn process_alive(pid: u32) -> bool {
    let Ok(raw) = i32::try_from(pid) else {
        return false;
    };
    if raw <= 0 {
        return false;
    }
    match nix::sys::signal::kill(nix::unistd::Pid::from_raw(raw), None) {
        Ok(()) => true,
        Err(e) => e == nix::errno::Errno::EPERM,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(site: &str, pid: u32) -> RunFile {
        RunFile {
            site: site.into(),
            central: vec!["tcp/127.0.0.1:40123".into()],
            pid,
            started_unix_s: 1_700_000_000,
        }
    }

    #[test]
    fn xdg_runtime_dir_is_used_when_absolute() {
        let d = RunDir::from_env(Some("/run/user/1000".into()), 1000);
        assert_eq!(d.path(), Path::new("/run/user/1000/ickon"));
        let fallback = std::env::temp_dir().join("ickon-1000");
        assert_eq!(RunDir::from_env(None, 1000).path(), fallback);
        assert_eq!(
            RunDir::from_env(Some("relative/dir".into()), 1000).path(),
            fallback
        );
    }

    #[test]
    fn a_written_run_file_reads_back_and_is_removed_only_by_its_writer() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = RunDir::at(tmp.path().join("ickon"));
        let me = std::process::id();
        let path = dir.write(&run("lab", me)).unwrap();
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(dir.path()).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o700);
        assert_eq!(dir.read("lab").unwrap(), run("lab", me));
        assert_eq!(dir.sites(), vec!["lab".to_string()]);
        assert!(!dir.remove("lab", me + 1).unwrap(), "not its writer");
        assert!(dir.remove("lab", me).unwrap());
        assert!(!path.exists());
        assert!(matches!(
            dir.read("lab"),
            Err(RunFileError::NotFound { .. })
        ));
    }

    #[test]
    fn stale_malformed_and_foreign_files_are_refused_clearly() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = RunDir::at(tmp.path());
        // A process id that cannot exist (above the kernel's pid_max limit).
        dir.write(&run("gone", 0x3FFF_FFFF)).unwrap();
        let err = dir.read("gone").unwrap_err();
        assert!(matches!(err, RunFileError::Stale { .. }), "{err}");
        assert!(err.to_string().contains("is gone"), "{err}");
        std::fs::write(tmp.path().join("junk.json"), "{ not json").unwrap();
        assert!(matches!(
            dir.read("junk"),
            Err(RunFileError::Malformed { .. })
        ));
        dir.write(&run("other", std::process::id())).unwrap();
        std::fs::rename(tmp.path().join("other.json"), tmp.path().join("lab.json")).unwrap();
        assert!(matches!(
            dir.read("lab"),
            Err(RunFileError::Malformed { .. })
        ));
        assert!(matches!(
            dir.file_for("../etc"),
            Err(RunFileError::BadSite(_))
        ));
    }
}
