//! `ickon node <role>`: one node of the mesh in this process. `ickon sim`
//! spawns itself with these subcommands so that `cargo run -p ickon -- sim`
//! needs no other binary; they run the same library code (the same argument
//! structs and `main_with`) as the standalone binaries meant for deployment:
//! `ickon-central`, `ickon-cell`, `ickon-world` and `ickon-msu` (the fleet
//! role hosts several `ickon-msu` agents in one simulation process).

use std::process::ExitCode;

use clap::Subcommand;

/// The roles a node can play.
#[derive(Debug, Subcommand)]
pub enum Role {
    /// The central unit.
    Central(ickon_central::node::CentralArgs),
    /// One cell controller.
    Cell(ickon_cell::node::CellArgs),
    /// The simulated world.
    World(ickon_world::node::WorldArgs),
    /// One robot's MSU agent.
    Msu(ickon_msu::node::MsuArgs),
    /// Several robots' MSU agents in one process, each as a lone agent,
    /// sharing one Zenoh session (`ickon sim --robots-per-process`).
    Fleet(ickon_msu::fleet::FleetArgs),
    /// A benchmark tool, not a node of a site: stands in for the MSU
    /// agents of many robots in one process, publishing what they publish
    /// (`ickon bench central`).
    SyntheticFleet(ickon_world::synthetic_fleet::SyntheticFleetArgs),
}

/// Runs one node and returns the exit code.
pub fn run(role: Role) -> ExitCode {
    match role {
        Role::Central(args) => ickon_central::node::main_with(args),
        Role::Cell(args) => ickon_cell::node::main_with(args),
        Role::World(args) => ickon_world::node::main_with(args),
        Role::Msu(args) => ickon_msu::node::main_with(args),
        Role::Fleet(args) => ickon_msu::fleet::main_with(args),
        Role::SyntheticFleet(args) => ickon_world::synthetic_fleet::main_with(args),
    }
}
