//! Child processes that cannot outlive their test.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

/// A spawned process: stdout and stderr go to `<log dir>/<name>.log`, and
/// dropping the guard kills it (SIGKILL) and reaps it.
#[derive(Debug)]
pub struct ChildGuard {
    name: String,
    child: Child,
    log: PathBuf,
    exited: Option<ExitStatus>,
}

impl ChildGuard {
    /// Starts `command` as `name`, logging into `log_dir`.
    pub fn spawn(name: &str, mut command: Command, log_dir: &Path) -> std::io::Result<Self> {
        let log = log_dir.join(format!("{}.log", name.replace(['/', ' '], "_")));
        let out = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)?;
        let err = out.try_clone()?;
        let child = command
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()?;
        Ok(Self {
            name: name.to_string(),
            child,
            log,
            exited: None,
        })
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// How it ended, if it has.
    pub fn exit_status(&mut self) -> Option<ExitStatus> {
        if self.exited.is_none() {
            self.exited = self.child.try_wait().ok().flatten();
        }
        self.exited
    }

    /// Kills it at once (SIGKILL, no chance to clean up) and reaps it.
    pub fn kill(&mut self) -> std::io::Result<ExitStatus> {
        if let Some(status) = self.exit_status() {
            return Ok(status);
        }
        self.child.kill()?;
        let status = self.child.wait()?;
        self.exited = Some(status);
        Ok(status)
    }

    /// Asks it to stop (SIGTERM), kills it if it has not within `grace`.
    pub fn stop(&mut self, grace: Duration) -> std::io::Result<ExitStatus> {
        if let Some(status) = self.exit_status() {
            return Ok(status);
        }
        if let Ok(pid) = i32::try_from(self.child.id()) {
            let _ = kill(Pid::from_raw(pid), Signal::SIGTERM);
        }
        let end = Instant::now() + grace;
        while Instant::now() < end {
            if let Some(status) = self.exit_status() {
                return Ok(status);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        self.kill()
    }

    /// Everything it wrote so far (for failure messages).
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// The last `lines` lines it wrote.
    pub fn log_tail(&self, lines: usize) -> String {
        let log = self.log();
        let all: Vec<&str> = log.lines().collect();
        all[all.len().saturating_sub(lines)..].join("\n")
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if self.exited.is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_guard_leaves_no_process_and_logs_are_kept() {
        let dir = tempfile::tempdir().unwrap();
        let mut sh = Command::new("sh");
        sh.args(["-c", "echo hello; exec sleep 30"]);
        let guard = ChildGuard::spawn("sleeper", sh, dir.path()).unwrap();
        let pid = guard.pid() as i32;
        crate::poll_until(Duration::from_secs(5), "the greeting", || {
            guard.log().contains("hello").then_some(())
        })
        .unwrap();
        drop(guard);
        // Signal 0 checks existence; the child was reaped, so it is gone.
        assert!(kill(Pid::from_raw(pid), None).is_err());
    }

    #[test]
    fn stop_kills_a_process_that_ignores_sigterm() {
        let dir = tempfile::tempdir().unwrap();
        let mut sh = Command::new("sh");
        sh.args(["-c", "trap '' TERM; echo ready; exec sleep 30"]);
        let mut guard = ChildGuard::spawn("stubborn", sh, dir.path()).unwrap();
        crate::poll_until(Duration::from_secs(5), "ready", || {
            guard.log().contains("ready").then_some(())
        })
        .unwrap();
        let status = guard.stop(Duration::from_millis(200)).unwrap();
        assert!(!status.success());
        assert!(guard.exit_status().is_some());
    }
}
