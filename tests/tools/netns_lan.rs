//! Hosts on one LAN for the deployment test: each host a Linux network
//! namespace with an address on a bridge (itself in a namespace of its own,
//! so that the machine's own network is never touched), and a mount view
//! of its own: `/etc/ickon`, `/etc/systemd`, `/etc/hosts` and
//! `/usr/local/bin` are bound, per command, to the host's directories.
//! Needs root. Everything is removed when the [`Lan`] drops: the
//! processes in its namespaces killed, the namespaces deleted, the mount
//! points it had to create in `/etc` removed.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Where each host's directories are bound in its mount view.
const BOUND: [(&str, &str); 4] = [
    ("etc-ickon", "/etc/ickon"),
    ("etc-systemd", "/etc/systemd"),
    ("bin", "/usr/local/bin"),
    ("hosts", "/etc/hosts"),
];

/// One host: its name, its namespace, its directory, its addresses.
#[derive(Debug, Clone)]
pub struct Host {
    /// The name the docs use (`server`, `cells`, ...).
    pub name: String,
    /// Its network namespace.
    pub netns: String,
    /// Its files: `etc-ickon/`, `etc-systemd/`, `hosts`, `logs/`.
    pub dir: PathBuf,
}

/// The hosts of one test, on one bridge.
pub struct Lan {
    hosts: Vec<Host>,
    bridge_ns: String,
    created_mount_points: Vec<PathBuf>,
}

fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().expect("run ip");
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

impl Lan {
    /// Makes each `(name, addresses)` a host under `root`, its first
    /// address its own; `bin` is the hosts' shared `/usr/local/bin` and
    /// `hosts_file` their `/etc/hosts`.
    pub fn new(root: &Path, bin: &Path, hosts_file: &str, specs: &[(&str, &[&str])]) -> Self {
        let tag = format!("ick{}", std::process::id());
        let bridge_ns = format!("{tag}-lan");
        let mut lan = Lan {
            hosts: Vec::new(),
            bridge_ns: bridge_ns.clone(),
            created_mount_points: Vec::new(),
        };
        ip(&["netns", "add", &bridge_ns]);
        ip(&["-n", &bridge_ns, "link", "add", "br0", "type", "bridge"]);
        ip(&["-n", &bridge_ns, "link", "set", "br0", "up"]);
        for (i, (name, addrs)) in specs.iter().enumerate() {
            let netns = format!("{tag}-{name}");
            ip(&["netns", "add", &netns]);
            let port = format!("v{i}");
            // The veth's peer is the host's eth0.
            ip(&[
                "-n", &bridge_ns, "link", "add", &port, "type", "veth", "peer", "name", "eth0",
                "netns", &netns,
            ]);
            ip(&[
                "-n", &bridge_ns, "link", "set", &port, "master", "br0", "up",
            ]);
            for a in addrs.iter() {
                ip(&[
                    "-n",
                    &netns,
                    "addr",
                    "add",
                    &format!("{a}/24"),
                    "dev",
                    "eth0",
                ]);
            }
            ip(&["-n", &netns, "link", "set", "eth0", "up"]);
            ip(&["-n", &netns, "link", "set", "lo", "up"]);
            let dir = root.join(name);
            for sub in ["etc-ickon", "etc-systemd/system", "logs"] {
                std::fs::create_dir_all(dir.join(sub)).expect("host directory");
            }
            std::fs::write(dir.join("hosts"), hosts_file).expect("hosts file");
            std::os::unix::fs::symlink(bin, dir.join("bin")).expect("bin link");
            lan.hosts.push(Host {
                name: name.to_string(),
                netns,
                dir,
            });
        }
        for (_, target) in BOUND {
            let target = Path::new(target);
            if !target.exists() {
                std::fs::create_dir_all(target).expect("mount point");
                lan.created_mount_points.push(target.to_path_buf());
            }
        }
        lan
    }

    /// The host of that name.
    pub fn host(&self, name: &str) -> &Host {
        self.hosts
            .iter()
            .find(|h| h.name == name)
            .unwrap_or_else(|| panic!("no host {name}"))
    }

    /// A command run on `host`: in its namespace and mount view, with
    /// `env` set and `program args` as the command.
    pub fn command(&self, host: &str, env: &[(&str, String)], program: &[&str]) -> Command {
        let h = self.host(host);
        let mut binds = String::new();
        for (from, to) in BOUND {
            let from = h.dir.join(from);
            let from = std::fs::canonicalize(&from).unwrap_or(from);
            binds.push_str(&format!("mount --bind '{}' '{to}' && ", from.display()));
        }
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &h.netns, "unshare", "-m", "sh", "-c"])
            .arg(format!("{binds}exec \"$@\""))
            .arg("sh")
            .args(program)
            .envs(env.iter().map(|(k, v)| (*k, v.as_str())))
            .stdin(Stdio::null());
        cmd
    }

    /// Runs a command on `host` for at most `timeout`; `None` if it did not
    /// finish in time (it is killed).
    pub fn run(
        &self,
        host: &str,
        env: &[(&str, String)],
        program: &[&str],
        timeout: Duration,
    ) -> Option<Output> {
        let out_file = self.host(host).dir.join("logs/last-command.out");
        let out = std::fs::File::create(&out_file).expect("output file");
        let mut child = self
            .command(host, env, program)
            .stdout(out.try_clone().expect("dup"))
            .stderr(out)
            .spawn()
            .expect("start a command in a namespace");
        let start = Instant::now();
        loop {
            if let Some(status) = child.try_wait().expect("wait") {
                let text = std::fs::read(&out_file).unwrap_or_default();
                return Some(Output {
                    status,
                    stdout: text,
                    stderr: Vec::new(),
                });
            }
            if start.elapsed() > timeout {
                let _ = child.kill();
                let _ = child.wait();
                return None;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Lan {
    fn drop(&mut self) {
        for h in &self.hosts {
            // Every process of the host: the nodes the units started too.
            if let Ok(out) = Command::new("ip")
                .args(["netns", "pids", &h.netns])
                .output()
            {
                for pid in String::from_utf8_lossy(&out.stdout).split_whitespace() {
                    let _ = Command::new("kill").args(["-9", pid]).status();
                }
            }
        }
        std::thread::sleep(Duration::from_millis(200));
        for h in &self.hosts {
            let _ = Command::new("ip").args(["netns", "del", &h.netns]).status();
        }
        let _ = Command::new("ip")
            .args(["netns", "del", &self.bridge_ns])
            .status();
        for p in &self.created_mount_points {
            let _ = std::fs::remove_dir(p);
        }
    }
}
