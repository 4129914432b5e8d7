//! `--split-cores`: the site's servers (router, central unit, cells) on one
//! half of the machine's CPUs, the simulation (world, agents, the
//! launcher's observer) on the other, so that what the servers need is
//! measured as on a site, where every robot has a computer of its own.
//! Each child is pinned through [`CPUS_ENV`], which `ickon` applies before
//! it starts a thread; the launcher pins itself.

use std::process::Command;

use ickon_runtime::cpus::{CPUS_ENV, Cpus, CpusError};

/// Which side of the split a process runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The router, the central unit (and its standby), the cells.
    Servers,
    /// The world, the agents, the launcher.
    Simulation,
}

impl Side {
    /// The side of a process of this kind (the first word of its name).
    pub fn of_kind(kind: &str) -> Side {
        match kind {
            "router" | "central" | "cell" => Side::Servers,
            _ => Side::Simulation,
        }
    }
}

/// The two CPU sets of a split machine.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CoreSplit {
    /// Where the servers run: the lower half of the CPUs.
    pub servers: Cpus,
    /// Where the simulation runs: the rest.
    pub simulation: Cpus,
}

/// Why the machine cannot be split.
#[derive(Debug, thiserror::Error)]
pub enum SplitError {
    /// The CPUs could not be read.
    #[error(transparent)]
    Cpus(#[from] CpusError),
    /// The split could not be made when first asked for.
    #[error("{0}")]
    Read(String),
    /// One CPU is all there is.
    #[error("this process may use only CPU {0}; splitting needs two or more")]
    OneCpu(Cpus),
}

impl CoreSplit {
    /// Splits the CPUs this process may use (its affinity, which `taskset`
    /// or a container may have narrowed) in two. Read once, at the first
    /// call: the launcher then pins itself to one side, and later calls
    /// must still see the whole machine.
    pub fn of_this_machine() -> Result<Self, SplitError> {
        static SPLIT: std::sync::OnceLock<Result<CoreSplit, String>> = std::sync::OnceLock::new();
        SPLIT
            .get_or_init(|| Self::split(Cpus::available()).map_err(|e| e.to_string()))
            .clone()
            .map_err(SplitError::Read)
    }

    /// The first CPU this process may use alone, and the rest (`ickon
    /// bench central`: the central unit on one core, everything else on
    /// the others).
    pub fn first_alone() -> Result<Self, SplitError> {
        let available = Cpus::available()?;
        match available.split_after(1) {
            Some((servers, simulation)) => Ok(Self {
                servers,
                simulation,
            }),
            None => Err(SplitError::OneCpu(available)),
        }
    }

    /// Splits `available` in two.
    fn split(available: Result<Cpus, CpusError>) -> Result<Self, SplitError> {
        let available = available?;
        available
            .split_in_two()
            .map(|(servers, simulation)| Self {
                servers,
                simulation,
            })
            .ok_or(SplitError::OneCpu(available))
    }

    /// The CPUs of `side`.
    pub fn cpus(&self, side: Side) -> &Cpus {
        match side {
            Side::Servers => &self.servers,
            Side::Simulation => &self.simulation,
        }
    }

    /// Has the child `cmd` pin itself to the CPUs of `side`.
    pub fn pin(&self, cmd: &mut Command, side: Side) {
        cmd.env(CPUS_ENV, self.cpus(side).to_string());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn servers_and_simulation_kinds() {
        for kind in ["router", "central", "cell"] {
            assert_eq!(Side::of_kind(kind), Side::Servers, "{kind}");
        }
        for kind in ["world", "msu", "fleet", "launcher"] {
            assert_eq!(Side::of_kind(kind), Side::Simulation, "{kind}");
        }
    }

    #[test]
    fn one_cpu_cannot_be_split() {
        let err = CoreSplit::split(Cpus::parse("3")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "this process may use only CPU 3; splitting needs two or more"
        );
        let two = CoreSplit::split(Cpus::parse("2,5")).unwrap();
        assert_eq!(
            (two.servers.to_string(), two.simulation.to_string()),
            ("2".into(), "5".into())
        );
    }

    #[test]
    fn the_first_cpu_alone_and_the_rest() {
        // This machine's: at least the shape, whatever its CPUs.
        if let Ok(split) = CoreSplit::first_alone() {
            assert_eq!(split.servers.len(), 1);
            let all = Cpus::available().unwrap();
            assert_eq!(split.servers.len() + split.simulation.len(), all.len());
            assert_eq!(split.servers.iter().next(), all.iter().next());
        }
    }

    #[test]
    fn a_child_is_given_its_sides_cpus() {
        let split = CoreSplit {
            servers: Cpus::parse("0").unwrap(),
            simulation: Cpus::parse("1-3").unwrap(),
        };
        let mut cmd = Command::new("true");
        split.pin(&mut cmd, Side::Simulation);
        let env: Vec<_> = cmd.get_envs().collect();
        assert_eq!(env, [(CPUS_ENV.as_ref(), Some("1-3".as_ref()))]);
    }
}
