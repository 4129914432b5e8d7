//! The child processes of `ickon sim`: spawn, watch, stop, and never leave one behind.

use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

/// One spawned node, and how to start it again.
struct Node {
    name: String,
    child: Child,
    recipe: Recipe,
}

/// What a command was made of (`Command` cannot be cloned).
#[derive(Debug, Clone)]
struct Recipe {
    program: std::ffi::OsString,
    args: Vec<std::ffi::OsString>,
    envs: Vec<(std::ffi::OsString, Option<std::ffi::OsString>)>,
    dir: Option<std::path::PathBuf>,
}

impl Recipe {
    fn of(command: &Command) -> Self {
        Recipe {
            program: command.get_program().to_owned(),
            args: command.get_args().map(ToOwned::to_owned).collect(),
            envs: command
                .get_envs()
                .map(|(k, v)| (k.to_owned(), v.map(ToOwned::to_owned)))
                .collect(),
            dir: command.get_current_dir().map(ToOwned::to_owned),
        }
    }

    fn command(&self) -> Command {
        let mut c = Command::new(&self.program);
        c.args(&self.args);
        for (k, v) in &self.envs {
            match v {
                Some(v) => c.env(k, v),
                None => c.env_remove(k),
            };
        }
        if let Some(d) = &self.dir {
            c.current_dir(d);
        }
        c
    }
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
        let recipe = Recipe::of(&command);
        command.stdin(Stdio::null()).stdout(Stdio::null());
        let child = command.spawn()?;
        self.nodes.push(Node {
            name: name.to_string(),
            child,
            recipe,
        });
        Ok(())
    }

    /// Starts again, with the same command, every child that has exited
    /// (as systemd's `Restart=always` would); their names, with how they ended.
    pub fn restart_dead(&mut self) -> Vec<DeadChild> {
        let mut restarted = Vec::new();
        for node in &mut self.nodes {
            if let Ok(Some(status)) = node.child.try_wait() {
                let mut command = node.recipe.command();
                command.stdin(Stdio::null()).stdout(Stdio::null());
                match command.spawn() {
                    Ok(child) => {
                        node.child = child;
                        restarted.push(DeadChild {
                            name: node.name.clone(),
                            status: describe(status),
                        });
                    }
                    Err(e) => tracing::warn!("{} not restarted: {e}", node.name),
                }
            }
        }
        restarted
    }

    /// Sends `signal` to the child `name`; `false` if there is none running.
    pub fn signal(&mut self, name: &str, signal: Signal) -> bool {
        let Some(node) = self.nodes.iter_mut().find(|n| n.name == name) else {
            return false;
        };
        if !matches!(node.child.try_wait(), Ok(None)) {
            return false;
        }
        i32::try_from(node.child.id()).is_ok_and(|pid| kill(Pid::from_raw(pid), signal).is_ok())
    }

    /// Kills the child `name` on purpose and, unless it is to be restarted,
    /// forgets it (its death is no failure of the run); `false` if there is
    /// none running.
    pub fn kill_planned(&mut self, name: &str, restart: bool) -> bool {
        let Some(i) = self.nodes.iter().position(|n| n.name == name) else {
            return false;
        };
        let _ = self.nodes[i].child.kill();
        let _ = self.nodes[i].child.wait();
        if !restart {
            self.nodes.remove(i);
        }
        true
    }

    /// CPU time and peak memory of every child still running, by name.
    pub fn usage(&self) -> Vec<(String, crate::usage::ProcUsage)> {
        self.nodes
            .iter()
            .filter_map(|n| Some((n.name.clone(), crate::usage::read(n.child.id())?)))
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

    /// Stops every child in the reverse order of their kinds' start (the
    /// first word of a name: MSUs and the world, then the cells, the
    /// central unit, the router last), so that no node sees the one it
    /// depends on go and nothing is still sending into a closing session.
    /// Each kind is asked at once (SIGTERM) and given up to `grace`; the
    /// rest are killed. Returns the names of children that had to be killed.
    pub fn stop_all(&mut self, grace: Duration) -> Vec<String> {
        let mut killed = Vec::new();
        while let Some(last) = self.nodes.last() {
            let kind = kind_of(&last.name).to_string();
            let mut group = Vec::new();
            let mut i = self.nodes.len();
            while i > 0 {
                i -= 1;
                if kind_of(&self.nodes[i].name) == kind {
                    group.push(self.nodes.remove(i));
                }
            }
            killed.extend(stop_group(&mut group, grace));
        }
        killed
    }
}

/// The name and kind of a standby central unit.
const STANDBY: &str = "central standby";

/// The kind of a node named `name` (`cell c2` -> `cell`). A standby central
/// unit is a kind of its own: started after the active one, it stops before
/// it, instead of seeing the active one's token go and taking over for its
/// last milliseconds (a restart keeps a node's place).
fn kind_of(name: &str) -> &str {
    if name == STANDBY {
        return STANDBY;
    }
    name.split_whitespace().next().unwrap_or(name)
}

/// SIGTERM to every node of `group`, up to `grace` for them to end, then
/// SIGKILL; the names of those killed.
fn stop_group(group: &mut [Node], grace: Duration) -> Vec<String> {
    for node in group.iter() {
        if let Ok(pid) = i32::try_from(node.child.id()) {
            // The child may already be gone; then there is nothing to signal.
            let _ = kill(Pid::from_raw(pid), Signal::SIGTERM);
        }
    }
    let deadline = Instant::now() + grace;
    let mut killed = Vec::new();
    for node in group.iter_mut() {
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
    killed
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
    fn a_dead_child_is_restarted_with_the_same_command() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("runs");
        let mut sup = Supervisor::new();
        let mut c = Command::new("sh");
        c.args(["-c", &format!("echo run >> {}; sleep 30", log.display())]);
        sup.spawn("cell c1", c).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        assert!(sup.kill_planned("cell c1", true));
        let restarted = sup.restart_dead();
        assert_eq!(restarted.len(), 1);
        assert_eq!(restarted[0].status, "killed by signal 9");
        std::thread::sleep(Duration::from_millis(300));
        assert_eq!(std::fs::read_to_string(&log).unwrap().lines().count(), 2);
        assert!(sup.first_dead().is_none());
        assert!(sup.signal("cell c1", Signal::SIGSTOP));
        assert!(sup.signal("cell c1", Signal::SIGCONT));
        assert!(!sup.signal("cell c9", Signal::SIGSTOP));
        assert!(sup.kill_planned("cell c1", false));
        assert_eq!(sup.len(), 0);
    }

    #[test]
    fn kinds_stop_in_the_reverse_order_of_their_start() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("order");
        let mut sup = Supervisor::new();
        for name in [
            "router",
            "central",
            "central standby",
            "cell c1",
            "cell c2",
            "msu r1",
        ] {
            let mut c = Command::new("sh");
            // Each notes its kind when asked to stop, then ends.
            c.args([
                "-c",
                &format!(
                    "trap 'echo {} >> {}; exit 0' TERM; while :; do sleep 0.05; done",
                    kind_of(name),
                    log.display()
                ),
            ]);
            sup.spawn(name, c).unwrap();
        }
        std::thread::sleep(Duration::from_millis(300));
        assert!(sup.stop_all(Duration::from_secs(5)).is_empty());
        let order = std::fs::read_to_string(&log).unwrap();
        let order: Vec<&str> = order.lines().collect();
        assert_eq!(
            order,
            [
                "msu",
                "cell",
                "cell",
                "central standby",
                "central",
                "router"
            ]
        );
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
