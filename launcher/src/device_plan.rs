//! Which nodes of `ickon sim` run through a device the world emulates:
//! with `--devices emulated` every cell fires through a transmitter board
//! and every robot hears through a receiver board; with `--receivers
//! marvelmind` every robot ranges with a Marvelmind hedgehog. Each device
//! gets a loopback port the world listens on and its node connects to,
//! as it would to a board on a serial-to-network bridge.

use std::collections::BTreeMap;

use clap::ValueEnum;
use ickon_proto::site::Site;

use crate::error::LaunchError;
use crate::ports::free_port;

/// How the nodes reach the simulated hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum Devices {
    /// Straight to the simulated world (the simulated driver and receivers).
    #[default]
    Direct,
    /// Through emulated boards of the ICKON device protocol, over TCP.
    Emulated,
}

/// What every robot's agent hears.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum SimReceivers {
    /// The cells' bursts (through a receiver board with `--devices emulated`).
    #[default]
    Sim,
    /// A Marvelmind hedgehog's distances to the site's transmitters as its
    /// beacons (the world emulates the kit).
    Marvelmind,
}

/// The devices of one run.
#[derive(Debug, Default)]
pub(crate) struct DevicePlan {
    cells: BTreeMap<String, u16>,
    robots: BTreeMap<String, (SimReceivers, u16)>,
}

impl DevicePlan {
    /// Ports for the devices `devices` and `receivers` ask for, none of
    /// them in `taken`.
    pub fn for_run(
        devices: Devices,
        receivers: SimReceivers,
        site: &Site,
        robots: &[String],
        taken: &[u16],
    ) -> Result<Self, LaunchError> {
        let mut used = taken.to_vec();
        let mut port = || -> Result<u16, LaunchError> {
            let p = free_port(&used).map_err(LaunchError::Port)?;
            used.push(p);
            Ok(p)
        };
        let mut plan = Self::default();
        if devices == Devices::Emulated {
            for cell in &site.cells {
                plan.cells.insert(cell.id.clone(), port()?);
            }
        }
        if devices == Devices::Emulated || receivers == SimReceivers::Marvelmind {
            for robot in robots {
                plan.robots.insert(robot.clone(), (receivers, port()?));
            }
        }
        Ok(plan)
    }

    /// `--driver` of cell `id`, if it fires through a board.
    pub fn cell_driver(&self, id: &str) -> Option<String> {
        self.cells.get(id).map(|p| format!("tcp:127.0.0.1:{p}"))
    }

    /// `--receivers` of robot `id`'s agent, if it hears through a device.
    pub fn robot_receivers(&self, id: &str) -> Option<String> {
        self.robots.get(id).map(|(kind, p)| match kind {
            SimReceivers::Sim => format!("tcp:127.0.0.1:{p}"),
            SimReceivers::Marvelmind => format!("marvelmind:tcp:127.0.0.1:{p}"),
        })
    }

    /// The world's `--device` flags.
    pub fn world_flags(&self) -> Vec<String> {
        let cells = self
            .cells
            .iter()
            .map(|(id, p)| format!("cell/{id}=transmitter-board@127.0.0.1:{p}"));
        let robots = self.robots.iter().map(|(id, (kind, p))| {
            let kind = match kind {
                SimReceivers::Sim => "receiver-board",
                SimReceivers::Marvelmind => "marvelmind",
            };
            format!("robot/{id}={kind}@127.0.0.1:{p}")
        });
        cells
            .chain(robots)
            .flat_map(|d| ["--device".to_string(), d])
            .collect()
    }
}

/// Why `--receivers marvelmind` cannot run on `site`, if it cannot: a
/// hedgehog hears at least three beacons, and a beacon's address is 1-254.
pub(crate) fn marvelmind_refusal(site: &Site) -> Option<String> {
    if let Some(t) = site
        .transmitters
        .iter()
        .find(|t| !(1..=254).contains(&t.id))
    {
        return Some(format!(
            "--receivers marvelmind: transmitter {} of site {:?} cannot be a Marvelmind beacon \
             (addresses are 1-254)",
            t.id, site.name
        ));
    }
    (site.transmitters.len() < 3).then(|| {
        format!(
            "--receivers marvelmind: site {:?} has {} transmitter(s); a hedgehog needs 3 beacons",
            site.name,
            site.transmitters.len()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lab() -> Site {
        Site::load_or_default(None).unwrap().0
    }

    #[test]
    fn emulated_devices_give_every_cell_and_robot_a_port_of_its_own() {
        let site = lab();
        let robots = vec!["r1".to_string(), "r2".to_string()];
        let plan =
            DevicePlan::for_run(Devices::Emulated, SimReceivers::Sim, &site, &robots, &[]).unwrap();
        let flags = plan.world_flags();
        assert_eq!(flags.len(), 2 * (site.cells.len() + 2));
        let driver = plan.cell_driver(&site.cells[0].id).unwrap();
        assert!(driver.starts_with("tcp:127.0.0.1:"), "{driver}");
        assert!(plan.robot_receivers("r2").unwrap().starts_with("tcp:"));
        let mut ports: Vec<&str> = flags
            .iter()
            .filter_map(|f| f.rsplit_once(':').map(|(_, p)| p))
            .collect();
        let n = ports.len();
        ports.sort_unstable();
        ports.dedup();
        assert_eq!(ports.len(), n, "{flags:?}");
    }

    #[test]
    fn a_kit_replaces_only_the_robots_receivers() {
        let site = lab();
        let robots = vec!["r1".to_string()];
        let plan = DevicePlan::for_run(
            Devices::Direct,
            SimReceivers::Marvelmind,
            &site,
            &robots,
            &[],
        )
        .unwrap();
        assert_eq!(plan.cell_driver(&site.cells[0].id), None);
        assert!(
            plan.robot_receivers("r1")
                .unwrap()
                .starts_with("marvelmind:tcp:127.0.0.1:")
        );
        assert_eq!(
            plan.world_flags()[1].split('@').next(),
            Some("robot/r1=marvelmind")
        );
        assert_eq!(plan.robot_receivers("r2"), None);
    }

    #[test]
    fn sites_whose_transmitters_cannot_be_beacons_are_refused_by_name() {
        let mut site = lab();
        assert_eq!(marvelmind_refusal(&site), None);
        site.transmitters[3].id = 300;
        let why = marvelmind_refusal(&site).unwrap();
        assert!(why.contains("transmitter 300"), "{why}");
        site.transmitters.truncate(2);
        site.transmitters[0].id = 1;
        site.transmitters[1].id = 2;
        assert!(
            marvelmind_refusal(&site)
                .unwrap()
                .contains("2 transmitter(s)")
        );
    }
}
