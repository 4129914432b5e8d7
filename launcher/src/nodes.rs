//! Every node's command line for one run, built before the first process
//! starts: the routers (one per zone), the central unit (and its standby),
//! one cell controller per cell, the world, one MSU agent per robot.

use std::path::Path;
use std::process::Command;

use ickon_operator::secure::Identity;
use ickon_proto::site::Site;
use ickon_recording::sim_hook;
use ickon_sim::profile::NoiseProfile;
use rand::SeedableRng;

use crate::args::Mesh;
use crate::args::SimArgs;
use crate::core_split::{CoreSplit, Side};
use crate::device_plan::DevicePlan;
use crate::error::LaunchError;
use crate::faults;
use crate::launch::{self, CLOCK_STREAM, clock_flags, node_command, router_command};
use crate::msu_file;
use crate::secure::SimSecurity;
use crate::zones::ZonedMesh;

/// The command lines of one run, in the order they are started.
pub(crate) struct NodeCommands {
    /// The routers, one per zone, with their names (none in a full mesh
    /// of peers); the first is the hub the others link to.
    pub routers: Vec<(String, Command)>,
    /// The central unit.
    pub central: Command,
    /// The hot standby of `--standby`.
    pub standby: Option<Command>,
    /// One cell controller per cell, with its name.
    pub cells: Vec<(String, Command)>,
    /// The simulated world.
    pub world: Command,
    /// The MSU agents, with their names: one process per robot (`msu
    /// r1`), or per group of robots (`fleet r1..r16`).
    pub msus: Vec<(String, Command)>,
    /// Where the central unit serves the live map, with `--http`.
    pub web: Option<std::net::SocketAddr>,
    /// Where the central unit serves Foxglove, with `--foxglove`.
    pub foxglove: Option<std::net::SocketAddr>,
    /// The agents' configuration file, removed when the run is over.
    pub msu_file: tempfile::NamedTempFile,
}

impl NodeCommands {
    /// Builds every command line of the run; the nodes connect to their
    /// zone's router of `mesh` (in a full mesh, to its hub: the central
    /// unit; and those a replay needs to the recorder too); with robots
    /// added to the site, every node reads it from `extended_site`.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        args: &SimArgs,
        site: &Site,
        profile: &NoiseProfile,
        mesh: &ZonedMesh,
        recorder: Option<&str>,
        msus: &[sim_hook::MsuStart],
        security: Option<&SimSecurity>,
        extended_site: Option<&Path>,
    ) -> Result<Self, LaunchError> {
        // The clock steps of the plan (checked already), given to each node at
        // its start: it takes the next at each SIGUSR1 the plan sends.
        let plan = args
            .faults
            .as_deref()
            .and_then(|p| faults::parse_plan(p).ok())
            .unwrap_or_default();
        let robots: Vec<String> = msus.iter().map(|m| m.robot.clone()).collect();
        let router_ports: Vec<u16> = mesh.listeners().iter().map(|(_, p)| *p).collect();
        let devices =
            DevicePlan::for_run(args.devices, args.receivers, site, &robots, &router_ports)?;
        let b = Builder {
            args,
            site,
            site_file: extended_site.or(args.site.as_deref()),
            hub: mesh.hub(),
            mesh,
            security,
            plan,
            devices,
        };
        let (routers, central_at) = b.routers()?;
        let central_flags = central_flags(args, profile);
        let mut central = node_command(
            args,
            site,
            b.site_file,
            "central",
            central_at.0,
            central_at.1,
        )?;
        central.args(&central_flags);
        b.credential(&mut central, Identity::Central);
        let web = launch::http_flags(args, &mut central)?;
        let foxglove = launch::foxglove_flag(args, &mut central)?;
        b.clock_steps(&mut central, "central");
        let standby = if args.standby {
            // A second central unit that follows the first and takes over.
            let mut standby = node_command(
                args,
                site,
                b.site_file,
                "central",
                central_at.0,
                central_at.1,
            )?;
            standby.arg("--standby").args(&central_flags);
            b.clock_steps(&mut standby, "central standby");
            b.credential(&mut standby, Identity::Central);
            Some(standby)
        } else {
            None
        };
        // In a peer mesh, the nodes whose messages a replay needs also connect
        // to the recorder directly; through a router (a client keeps one
        // connection) the recorder hears them by the router, as every observer.
        let to_recorder: Vec<String> = recorder
            .iter()
            .filter(|_| args.mesh == Mesh::Peer)
            .flat_map(|e| ["--connect".to_string(), e.to_string()])
            .collect();
        let cells = b.cells(&to_recorder)?;
        let world = b.world(msus, &to_recorder)?;
        let (agents, msu_file) = b.agents(profile, msus, &to_recorder)?;
        let mut commands = Self {
            routers,
            central,
            standby,
            cells,
            world,
            msus: agents,
            web,
            foxglove,
            msu_file,
        };
        if args.split_cores {
            commands.pin(&CoreSplit::of_this_machine()?);
        }
        Ok(commands)
    }

    /// Pins every node to its side of `split`.
    fn pin(&mut self, split: &CoreSplit) {
        let servers = self
            .routers
            .iter_mut()
            .map(|(_, c)| c)
            .chain(std::iter::once(&mut self.central))
            .chain(self.standby.iter_mut())
            .chain(self.cells.iter_mut().map(|(_, c)| c));
        for cmd in servers {
            split.pin(cmd, Side::Servers);
        }
        for cmd in std::iter::once(&mut self.world).chain(self.msus.iter_mut().map(|(_, c)| c)) {
            split.pin(cmd, Side::Simulation);
        }
    }
}

/// The name of a fleet process as the run reports it: `fleet r1..r16`.
pub(crate) fn fleet_name(robots: &[String]) -> String {
    match robots {
        [] => "fleet".into(),
        [one] => format!("fleet {one}"),
        [first, .., last] => format!("fleet {first}..{last}"),
    }
}

/// A node's command line with its name.
type Named = (String, Command);

/// What every node's command line is built from.
struct Builder<'a> {
    args: &'a SimArgs,
    site: &'a Site,
    /// The file every node reads the site from (`lab` when `None`): the
    /// run's `--site`, or the site with the robots added to it.
    site_file: Option<&'a Path>,
    /// Where the central unit, its standby and the world connect: the
    /// first router (in a full mesh, the central unit's listener).
    hub: &'a str,
    /// The zones and their routers, where the cells and agents connect.
    mesh: &'a ZonedMesh,
    security: Option<&'a SimSecurity>,
    /// The faults of `--faults`, for each node's clock steps.
    plan: Vec<faults::Fault>,
    /// The devices the world emulates.
    devices: DevicePlan,
}

impl<'a> Builder<'a> {
    /// Gives `cmd` the credential of `who`, with `--secure`.
    fn credential(&self, cmd: &mut Command, who: Identity) {
        if let Some(s) = self.security {
            s.client(cmd, &who);
        }
    }

    /// Gives `cmd` the clock steps the plan has for `node`, if any.
    fn clock_steps(&self, cmd: &mut Command, node: &str) {
        if let Some(steps) = faults::clock_steps_flag(&self.plan, node) {
            cmd.arg("--sim-clock-steps-us").arg(steps);
        }
    }

    /// The routers, one per zone (none in a full mesh of peers), and
    /// where the central unit connects and listens. Routers 2 to N link to
    /// the first: a star, as `ickon site secure --routers N` writes their
    /// access control (the first trusts the others as linking routers).
    fn routers(&self) -> Result<(Vec<Named>, (&'a str, &'a str)), LaunchError> {
        Ok(match self.args.mesh {
            Mesh::Router => {
                let mut routers = Vec::new();
                for (k, (endpoint, _)) in self.mesh.listeners().iter().enumerate() {
                    let link = (k > 0).then_some(self.hub);
                    let mut router = router_command(endpoint, link)?;
                    if let Some(s) = self.security {
                        s.router(&mut router, k + 1);
                    }
                    routers.push((self.mesh.router_name(k), router));
                }
                (routers, (self.hub, ""))
            }
            Mesh::Peer => (Vec::new(), ("", self.hub)),
        })
    }

    /// One cell controller per cell, each with its own clock error drawn
    /// from the run's seed.
    fn cells(&self, to_recorder: &[String]) -> Result<Vec<(String, Command)>, LaunchError> {
        let (args, site) = (self.args, self.site);
        let mut clocks = rand_chacha::ChaCha8Rng::seed_from_u64(args.seed ^ CLOCK_STREAM);
        let mut cells = Vec::new();
        for cell in &site.cells {
            let hub = self.mesh.endpoint_of_cell(&cell.id);
            let mut cmd = node_command(args, site, self.site_file, "cell", hub, "tcp/127.0.0.1:0")?;
            cmd.args(["--cell", &cell.id])
                .args(clock_flags(&mut clocks))
                .args(to_recorder);
            if let Some(driver) = self.devices.cell_driver(&cell.id) {
                cmd.args(["--driver", &driver]);
            }
            let name = format!("cell {}", cell.id);
            self.clock_steps(&mut cmd, &name);
            self.credential(&mut cmd, Identity::Cell(cell.id.clone()));
            cells.push((name, cmd));
        }
        Ok(cells)
    }

    /// The simulated world, driving the robots of `msus`.
    fn world(
        &self,
        msus: &[sim_hook::MsuStart],
        to_recorder: &[String],
    ) -> Result<Command, LaunchError> {
        let args = self.args;
        let robots: Vec<&str> = msus.iter().map(|m| m.robot.as_str()).collect();
        let mut world = node_command(
            args,
            self.site,
            self.site_file,
            "world",
            self.hub,
            "tcp/127.0.0.1:0",
        )?;
        world.args([
            "--robots",
            &robots.join(","),
            "--profile",
            &args.profile,
            "--seed",
            &args.seed.to_string(),
        ]);
        world.args(to_recorder).args(self.devices.world_flags());
        if let Some(items) = args
            .faults
            .as_deref()
            .and_then(crate::faults::transmitter_items)
        {
            world.args(["--transmitter-faults", &items]);
        }
        self.credential(&mut world, Identity::World);
        if args.ros2 {
            world.arg("--ros2");
        }
        Ok(world)
    }

    /// One MSU agent per robot, with the configuration file they all read.
    fn agents(
        &self,
        profile: &NoiseProfile,
        msus: &[sim_hook::MsuStart],
        to_recorder: &[String],
    ) -> Result<(Vec<(String, Command)>, tempfile::NamedTempFile), LaunchError> {
        let (args, site) = (self.args, self.site);
        // Every agent reads one configuration file, as a deployed one does: the
        // estimator as `ickon eval` sets it up for the profile's data sheet,
        // the simulated robots' nominal drive, the arrivals' timing noise (the
        // site gives each agent its robot's start pose).
        let drive = ickon_sim::robot::DriveSpec::default();
        let msu_file = msu_file::write_temp(&msu_file::render(
            &ickon_sim::engine::estimator_config(
                &args.estimator,
                [0.0; 3],
                site,
                profile,
                args.filter_options(),
            )?,
            ickon_sim::engine::timing_sigma_s(profile),
            drive.geometry(),
            args.ros2,
        )?)
        .map_err(|e| LaunchError::MsuFile(e.to_string()))?;
        let robots: Vec<String> = msus.iter().map(|m| m.robot.clone()).collect();
        let groups = crate::zones::fleets(site, &robots, args.robots_per_process(), args.routers);
        if !groups.is_empty() {
            let mut agents = Vec::new();
            for group in groups {
                let hub = self.mesh.endpoint_of_robot(&group[0]);
                let mut cmd =
                    node_command(args, site, self.site_file, "fleet", hub, "tcp/127.0.0.1:0")?;
                cmd.args(["--robots", &group.join(","), "--config"])
                    .arg(msu_file.path())
                    .args(to_recorder);
                for robot in &group {
                    if let Some(receivers) = self.devices.robot_receivers(robot) {
                        cmd.args(["--receivers", &format!("{robot}={receivers}")]);
                    }
                }
                let name = fleet_name(&group);
                self.credential(&mut cmd, Identity::Fleet(group));
                agents.push((name, cmd));
            }
            return Ok((agents, msu_file));
        }
        let mut agents = Vec::new();
        for msu in msus {
            let hub = self.mesh.endpoint_of_robot(&msu.robot);
            let mut cmd = node_command(args, site, self.site_file, "msu", hub, "tcp/127.0.0.1:0")?;
            cmd.args(["--robot", &msu.robot, "--config"])
                .arg(msu_file.path())
                .args(to_recorder);
            if let Some(receivers) = self.devices.robot_receivers(&msu.robot) {
                cmd.args(["--receivers", &receivers]);
            }
            self.credential(&mut cmd, Identity::Robot(msu.robot.clone()));
            agents.push((format!("msu {}", msu.robot), cmd));
        }
        Ok((agents, msu_file))
    }
}

/// The central unit's firing plan and survey calibration flags (its
/// standby gets the same).
fn central_flags(args: &SimArgs, profile: &NoiseProfile) -> Vec<String> {
    // The flag's own spelling, from the same clap definition that parses it.
    let firing = clap::ValueEnum::to_possible_value(&args.firing)
        .map(|v| v.get_name().to_string())
        .unwrap_or_default();
    let mut flags = vec!["--firing".to_string(), firing];
    if args.no_speed_of_sound {
        flags.push("--no-speed-of-sound".into());
    }
    if args.no_survey_calibration {
        flags.push("--no-survey-calibration".into());
    } else {
        flags.extend([
            "--timing-sigma-us".to_string(),
            format!("{}", ickon_sim::engine::timing_sigma_s(profile) * 1e6),
            "--cell-sync-sigma-us".to_string(),
            format!("{}", ickon_sim::engine::cell_sync_sigma_s(profile) * 1e6),
        ]);
    }
    flags
}

/// What each MSU agent is started with: the same estimator set-up as `ickon
/// eval` (the robot's start pose and the profile's sensor data sheet), and
/// the nominal drive of the simulated robots (what the agent converts
/// encoder ticks with).
pub(crate) fn msu_starts(
    args: &SimArgs,
    site: &Site,
    profile: &NoiseProfile,
    robots: &[String],
) -> Result<Vec<sim_hook::MsuStart>, LaunchError> {
    let drive = ickon_sim::robot::DriveSpec::default();
    robots
        .iter()
        .map(|robot| {
            let start = site
                .robots
                .iter()
                .find(|r| &r.id == robot)
                .map_or([0.0; 3], |r| r.start);
            let config = ickon_sim::engine::estimator_config(
                &args.estimator,
                start,
                site,
                profile,
                args.filter_options(),
            )?;
            // The value the agent's configuration file holds (`msu_file`):
            // a float written in full, so the replay uses the agent's value.
            let timing_sigma_us = ickon_sim::engine::timing_sigma_s(profile) * 1e6;
            Ok(sim_hook::MsuStart {
                robot: robot.clone(),
                estimator_json: serde_json::to_string(&config)
                    .map_err(|e| LaunchError::MsuFile(e.to_string()))?,
                timing_sigma_us,
                wheel_base_m: drive.wheel_base_m,
                m_per_tick: drive.m_per_tick(),
            })
        })
        .collect()
}
