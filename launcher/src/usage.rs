//! CPU time and peak memory of the processes of a run, read from `/proc`
//! (Linux) just before they are stopped, and summed per kind of process.

use std::collections::BTreeMap;

use serde::Serialize;

/// What one process used so far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProcUsage {
    /// User plus system CPU time, seconds.
    pub cpu_s: f64,
    /// Peak resident memory, bytes.
    pub peak_rss_bytes: u64,
}

/// The CPU time and peak memory of one kind of process (`router`, `cell`, ...).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct KindUsage {
    /// The kind: the first word of the node's name (`cell c2` -> `cell`), or
    /// `launcher` for `ickon sim` itself (its observer session).
    pub kind: String,
    /// Processes of this kind that were measured.
    pub processes: usize,
    /// CPU seconds of all of them together.
    pub cpu_s: f64,
    /// CPU seconds of the busiest one.
    pub cpu_max_s: f64,
    /// Largest peak resident memory of one of them, MiB.
    pub peak_rss_max_mib: f64,
}

/// Kernel clock ticks per second of `/proc/<pid>/stat`: 100 on every Linux
/// configuration in use (USER_HZ is fixed by the kernel ABI).
const TICKS_PER_S: f64 = 100.0;

/// Reads what process `pid` used; `None` when it is gone or `/proc` is not there.
pub fn read(pid: u32) -> Option<ProcUsage> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    Some(ProcUsage {
        cpu_s: cpu_s_from_stat(&stat)?,
        peak_rss_bytes: peak_rss_from_status(&status)?,
    })
}

/// User plus system time from a `/proc/<pid>/stat` line, seconds. The
/// command name (field 2) is in parentheses and may hold spaces, so fields
/// are counted after its closing parenthesis: utime and stime are fields 14
/// and 15.
fn cpu_s_from_stat(stat: &str) -> Option<f64> {
    let after = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    // `after` starts at field 3 (the state).
    let utime: u64 = fields.get(14 - 3)?.parse().ok()?;
    let stime: u64 = fields.get(15 - 3)?.parse().ok()?;
    Some((utime + stime) as f64 / TICKS_PER_S)
}

/// `VmHWM` (peak resident set) from `/proc/<pid>/status`, bytes.
fn peak_rss_from_status(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The kind of a process: the first word of its name (`cell c2` -> `cell`).
pub fn kind_of(name: &str) -> &str {
    name.split_whitespace().next().unwrap_or(name)
}

/// Sums `(name, usage)` per kind of process, kinds in name order.
pub fn by_kind(named: &[(String, ProcUsage)]) -> Vec<KindUsage> {
    let mut kinds: BTreeMap<String, KindUsage> = BTreeMap::new();
    for (name, u) in named {
        let kind = kind_of(name).to_string();
        let k = kinds.entry(kind.clone()).or_insert(KindUsage {
            kind,
            processes: 0,
            cpu_s: 0.0,
            cpu_max_s: 0.0,
            peak_rss_max_mib: 0.0,
        });
        k.processes += 1;
        k.cpu_s += u.cpu_s;
        k.cpu_max_s = k.cpu_max_s.max(u.cpu_s);
        k.peak_rss_max_mib = k
            .peak_rss_max_mib
            .max(u.peak_rss_bytes as f64 / (1024.0 * 1024.0));
    }
    kinds.into_values().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_cpu_time_after_a_command_name_with_spaces() {
        let stat = "4242 (ickon node (x) y) S 1 2 3 4 5 6 7 8 9 10 250 50 0 0 20 0 3 0";
        assert_eq!(cpu_s_from_stat(stat), Some(3.0));
        assert_eq!(cpu_s_from_stat("4242 (truncated) S 1 2"), None);
        assert_eq!(cpu_s_from_stat("garbage"), None);
    }

    #[test]
    fn reads_the_peak_resident_set() {
        let status = "Name:\tickon\nVmPeak:\t  900 kB\nVmHWM:\t   2048 kB\nVmRSS:\t 1024 kB\n";
        assert_eq!(peak_rss_from_status(status), Some(2 * 1024 * 1024));
        assert_eq!(peak_rss_from_status("Name:\tx\n"), None);
    }

    #[test]
    fn this_process_can_be_measured() {
        let me = read(std::process::id()).expect("/proc of this process");
        assert!(me.peak_rss_bytes > 0);
    }

    #[test]
    fn sums_per_kind() {
        let u = |cpu_s, mib: u64| ProcUsage {
            cpu_s,
            peak_rss_bytes: mib * 1024 * 1024,
        };
        let kinds = by_kind(&[
            ("cell c1".into(), u(1.0, 10)),
            ("router".into(), u(4.0, 30)),
            ("cell c2".into(), u(2.0, 12)),
        ]);
        assert_eq!(kinds.len(), 2);
        assert_eq!(kinds[0].kind, "cell");
        assert_eq!(kinds[0].processes, 2);
        assert!((kinds[0].cpu_s - 3.0).abs() < 1e-12);
        assert!((kinds[0].cpu_max_s - 2.0).abs() < 1e-12);
        assert!((kinds[0].peak_rss_max_mib - 12.0).abs() < 1e-12);
        assert_eq!(kinds[1].kind, "router");
    }
}
