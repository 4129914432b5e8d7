//! The child processes of `ickon sim`: spawn, watch, stop, and never leave one behind.

use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

/// One spawned node.
struct Node {
    name: String,
    child: Child,
}

/// Owns every child of a run. Dropping it kills whatever is still running,
/// so an early return or a panic in the launcher leaves no process behind.
pub struct Supervisor {
    nodes: Vec<Node>,
}

/// A child that ended while it should have been running.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeadChild {
    /// Its name, e.g. `cell c2`.
    pub name: String,
    /// How it ended, in words.
    pub status: String,
}

impl Supervisor {
    /// An empty supervisor.
    pub fn new() -> Self {
        Supervisor { nodes: Vec::new() }
    }

    /// Starts `command` as the node `name`. Its stdout is discarded (nodes log
    /// to stderr, which is inherited so that their errors reach the user).
    pub fn spawn(&mut self, name: &str, mut command: Command) -> std::io::Result<()> {
        command.stdin(Stdio::null()).stdout(Stdio::null());
        let child = command.spawn()?;
        self.nodes.push(Node {
            name: name.to_string(),
            child,
        });
        Ok(())
    }

    /// CPU time and peak memory of every child still running, by name.
    pub fn usage(&self) -> Vec<(String, super::usage::ProcUsage)> {
        self.nodes
            .iter()
            .filter_map(|n| Some((n.name.clone(), super::usage::read(n.child.id())?)))
            .collect()
    }

    /// Number of children spawned.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// The first child that has exited, if any.
    pub fn first_dead(&mut self) -> Option<DeadChild> {
        for node in &mut self.nodes {
            if let Ok(Some(status)) = node.child.try_wait() {
                return Some(DeadChild {
                    name: node.name.clone(),
                    status: describe(status),
                });
            }
        }
        None
    }

    /// Asks every child to stop (SIGTERM), waits up to `grace` for all of them,
    /// then kills the rest. Returns the names of children that had to be killed.
    pub fn stop_all(&mut self, grace: Duration) -> Vec<String> {
        for node in &self.nodes {
            if let Ok(pid) = i32::try_from(node.child.id()) {
                // The child may already be gone; then there is nothing to signal.
                let _ = kill(Pid::from_raw(pid), Signal::SIGTERM);
            }
        }
        let deadline = Instant::now() + grace;
        let mut killed = Vec::new();
        for node in &mut self.nodes {
            loop {
                match node.child.try_wait() {
                    Ok(Some(_)) => break,
                    Ok(None) if Instant::now() < deadline => {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                    _ => {
                        let _ = node.child.kill();
                        let _ = node.child.wait();
                        killed.push(node.name.clone());
                        break;
                    }
                }
            }
        }
        self.nodes.clear();
        killed
    }
}

impl Default for Supervisor {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        for node in &mut self.nodes {
            let _ = node.child.kill();
            let _ = node.child.wait();
        }
    }
}

fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(code), _) => format!("exited with code {code}"),
        (None, Some(sig)) => format!("killed by signal {sig}"),
        _ => "ended".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sleeper(seconds: &str) -> Command {
        let mut c = Command::new("sleep");
        c.arg(seconds);
        c
    }

    #[test]
    fn reports_the_child_that_died() {
        let mut sup = Supervisor::new();
        sup.spawn("long", sleeper("30")).unwrap();
        sup.spawn("short", Command::new("false")).unwrap();
        let deadline = Instant::now() + Duration::from_secs(5);
        let dead = loop {
            if let Some(d) = sup.first_dead() {
                break d;
            }
            assert!(Instant::now() < deadline, "no child reported dead");
            std::thread::sleep(Duration::from_millis(10));
        };
        assert_eq!(dead.name, "short");
        assert_eq!(dead.status, "exited with code 1");
        assert!(sup.stop_all(Duration::from_secs(2)).is_empty());
    }

    #[test]
    fn stop_all_kills_children_that_ignore_sigterm() {
        let mut sup = Supervisor::new();
        let mut stubborn = Command::new("sh");
        stubborn.args(["-c", "trap '' TERM; exec sleep 30"]);
        sup.spawn("stubborn", stubborn).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        let started = Instant::now();
        let killed = sup.stop_all(Duration::from_millis(300));
        assert_eq!(killed, vec!["stubborn".to_string()]);
        assert!(started.elapsed() < Duration::from_secs(5));
    }

    #[test]
    fn dropping_the_supervisor_leaves_no_process() {
        let pid;
        {
            let mut sup = Supervisor::new();
            sup.spawn("orphan", sleeper("30")).unwrap();
            pid = sup.nodes[0].child.id() as i32;
        }
        // Signal 0 only checks existence; the child was reaped, so it is gone.
        assert!(kill(Pid::from_raw(pid), None).is_err());
    }
}
