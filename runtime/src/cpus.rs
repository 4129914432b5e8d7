//! Which CPUs a process runs on: a CPU list (`0`, `1-3`, `0,2-3`) parsed
//! and checked, the CPUs this process may use, and pinning the process to
//! a set before it starts any thread, so that every thread it creates
//! afterwards (tokio's, Zenoh's) inherits the set.
//!
//! `ickon sim --split-cores` gives the site's servers one set and the
//! simulated fleet the rest (through [`CPUS_ENV`]), so that the servers are
//! measured as if the robots had computers of their own.

use std::collections::BTreeSet;
use std::fmt;

use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
use nix::unistd::Pid;

/// The environment variable that pins an `ickon` process at start: a CPU
/// list, e.g. `ICKON_CPUS=0` or `ICKON_CPUS=1-3`.
pub const CPUS_ENV: &str = "ICKON_CPUS";

/// Why a CPU list cannot be used.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum CpusError {
    /// The text is not a CPU list.
    #[error("{text:?} is not a CPU list (e.g. 0, 1-3 or 0,2-3): {why}")]
    Malformed {
        /// The text given.
        text: String,
        /// What is wrong with it.
        why: String,
    },
    /// The kernel refused or could not report the set.
    #[error("CPU affinity: {0}")]
    Kernel(String),
    /// A CPU of the list is not one this process may use.
    #[error("CPU {cpu} is not available to this process (it may use {available})")]
    Unavailable {
        /// The CPU asked for.
        cpu: usize,
        /// The CPUs this process may use, as a list.
        available: Cpus,
    },
}

/// A set of CPU numbers.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Cpus(BTreeSet<usize>);

impl Cpus {
    /// The CPUs, lowest first.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().copied()
    }

    /// How many CPUs.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Parses a CPU list as the kernel writes them (`0`, `1-3`, `0,2-3`).
    pub fn parse(text: &str) -> Result<Self, CpusError> {
        let bad = |why: &str| CpusError::Malformed {
            text: text.to_string(),
            why: why.to_string(),
        };
        let mut set = BTreeSet::new();
        for part in text.split(',').map(str::trim) {
            let (low, high) = match part.split_once('-') {
                Some((a, b)) => (a.trim(), b.trim()),
                None => (part, part),
            };
            let number = |s: &str| {
                s.parse::<usize>()
                    .ok()
                    .filter(|&n| n < CpuSet::count())
                    .ok_or_else(|| {
                        bad(&format!(
                            "{s:?} is not a CPU number below {}",
                            CpuSet::count()
                        ))
                    })
            };
            let (low, high) = (number(low)?, number(high)?);
            if low > high {
                return Err(bad(&format!("the range {part:?} runs backwards")));
            }
            set.extend(low..=high);
        }
        Ok(Self(set))
    }

    /// The CPUs this process may run on (its affinity, which `taskset`, a
    /// container or systemd's `CPUAffinity=` may have narrowed).
    pub fn available() -> Result<Self, CpusError> {
        let set =
            sched_getaffinity(Pid::from_raw(0)).map_err(|e| CpusError::Kernel(e.to_string()))?;
        Ok(Self(
            (0..CpuSet::count())
                .filter(|&cpu| set.is_set(cpu).unwrap_or(false))
                .collect(),
        ))
    }

    /// Splits the CPUs in two: the lower half (at least one) and the rest;
    /// `None` with fewer than two.
    pub fn split_in_two(&self) -> Option<(Cpus, Cpus)> {
        self.split_after(self.len() / 2)
    }

    /// The lowest `first` CPUs and the rest; `None` unless both sides get
    /// at least one.
    pub fn split_after(&self, first: usize) -> Option<(Cpus, Cpus)> {
        if first == 0 || first >= self.len() {
            return None;
        }
        let low = self.0.iter().copied().take(first).collect();
        let high = self.0.iter().copied().skip(first).collect();
        Some((Self(low), Self(high)))
    }

    /// Pins the calling thread (and every thread it creates afterwards) to
    /// these CPUs, each of which the machine must let this process use. A
    /// process may widen the set it inherited (a child of a pinned
    /// launcher goes to the other side), so the kernel is the judge: the
    /// set is asked for, then read back.
    pub fn pin_current_thread(&self) -> Result<(), CpusError> {
        if self.is_empty() {
            return Err(CpusError::Malformed {
                text: String::new(),
                why: "no CPU".into(),
            });
        }
        let mut set = CpuSet::new();
        for cpu in self.iter() {
            set.set(cpu).map_err(|e| CpusError::Kernel(e.to_string()))?;
        }
        match sched_setaffinity(Pid::from_raw(0), &set) {
            Ok(()) => {}
            // No CPU of the set may be used.
            Err(nix::errno::Errno::EINVAL) => {
                return Err(CpusError::Unavailable {
                    cpu: self.iter().next().unwrap_or_default(),
                    available: Self::available()?,
                });
            }
            Err(e) => return Err(CpusError::Kernel(e.to_string())),
        }
        let got = Self::available()?;
        match self.iter().find(|cpu| !got.0.contains(cpu)) {
            Some(cpu) => Err(CpusError::Unavailable {
                cpu,
                available: got,
            }),
            None => Ok(()),
        }
    }
}

impl fmt::Display for Cpus {
    /// As a CPU list, ranges joined (`0,2-3`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let cpus: Vec<usize> = self.iter().collect();
        let mut parts = Vec::new();
        let mut i = 0;
        while i < cpus.len() {
            let mut j = i;
            while j + 1 < cpus.len() && cpus[j + 1] == cpus[j] + 1 {
                j += 1;
            }
            parts.push(if i == j {
                cpus[i].to_string()
            } else {
                format!("{}-{}", cpus[i], cpus[j])
            });
            i = j + 1;
        }
        f.write_str(&parts.join(","))
    }
}

/// Pins this process as [`CPUS_ENV`] says, when it is set: to be called
/// first thing in `main`, before any thread starts.
pub fn pin_from_env() -> Result<Option<Cpus>, CpusError> {
    match std::env::var(CPUS_ENV) {
        Ok(text) if !text.trim().is_empty() => {
            let cpus = Cpus::parse(&text)?;
            cpus.pin_current_thread()?;
            Ok(Some(cpus))
        }
        _ => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_writes_cpu_lists() {
        for (text, list) in [
            ("0", "0"),
            ("1-3", "1-3"),
            ("0, 2-3,5", "0,2-3,5"),
            ("3,1,2", "1-3"),
        ] {
            assert_eq!(Cpus::parse(text).unwrap().to_string(), list, "{text}");
        }
        for bad in ["", "x", "3-1", "-1", "1-", "0,,1", "99999", "1.5"] {
            assert!(
                matches!(Cpus::parse(bad), Err(CpusError::Malformed { .. })),
                "{bad:?} accepted"
            );
        }
    }

    #[test]
    fn splits_into_servers_and_the_rest() {
        let (low, high) = Cpus::parse("0-3").unwrap().split_in_two().unwrap();
        assert_eq!(
            (low.to_string(), high.to_string()),
            ("0-1".into(), "2-3".into())
        );
        let (low, high) = Cpus::parse("0-2").unwrap().split_in_two().unwrap();
        assert_eq!(
            (low.to_string(), high.to_string()),
            ("0".into(), "1-2".into())
        );
        assert!(Cpus::parse("5").unwrap().split_in_two().is_none());
        let (first, rest) = Cpus::parse("2,4-6").unwrap().split_after(1).unwrap();
        assert_eq!(
            (first.to_string(), rest.to_string()),
            ("2".into(), "4-6".into())
        );
        assert!(Cpus::parse("0-3").unwrap().split_after(4).is_none());
    }

    #[test]
    fn a_thread_is_pinned_and_an_unavailable_cpu_refused() {
        let available = Cpus::available().unwrap();
        assert!(!available.is_empty());
        // In a thread of its own, so the test runner's threads keep theirs.
        std::thread::spawn(move || {
            let first = Cpus(available.iter().take(1).collect());
            first.pin_current_thread().unwrap();
            assert_eq!(Cpus::available().unwrap(), first);
            // A pinned thread may move to another CPU of the machine.
            if let Some(other) = available.iter().nth(1) {
                let second = Cpus(BTreeSet::from([other]));
                second.pin_current_thread().unwrap();
                assert_eq!(Cpus::available().unwrap(), second);
            }
            // A CPU the machine does not have is refused by name.
            let absent = Cpus(BTreeSet::from([CpuSet::count() - 1]));
            let err = absent.pin_current_thread().unwrap_err();
            assert!(matches!(err, CpusError::Unavailable { .. }), "{err}");
        })
        .join()
        .unwrap();
    }
}
