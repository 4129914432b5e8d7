//! # ickon-world
//!
//! The simulated world as a node of the mesh, beside the central unit,
//! the cells and the MSU agents: the pure world and the virtual-time
//! engine of [`ickon_sim`] driven by the system clock and fed over Zenoh.
//!
//! - [`realtime`]: the world driven by the wall clock and real burst reports.
//! - [`node`]: the world as a Zenoh node (`ickon node world`, `ickon-world`).
//! - [`devices`], [`device_hosting`]: devices of the world emulated on TCP
//!   (transmitter and receiver boards, Marvelmind hedgehogs), fed by it.
//! - [`board`]: an emulated transmitter or receiver board of the device protocol.
//! - [`hedgehog`]: an emulated Marvelmind hedgehog streaming raw distances on a route.
//! - [`emulate`], [`emulate_hedgehog`]: one emulated device on a
//!   pseudo-terminal or TCP, without a world (`ickon emulate`).
//! - [`ros2_sensors`]: each robot's odometry and gyro as ROS 2 topics.
//! - [`synthetic_fleet`]: many robots' agents stood in for by one process
//!   (`ickon node synthetic-fleet`, for `ickon bench central`).
//! - [`fleet_args`]: the flags both of these nodes simulating robots take.

pub mod board;
pub mod device_hosting;
pub mod devices;
pub mod emulate;
pub mod emulate_hedgehog;
mod emulate_listen;
pub mod fleet_args;
pub mod hedgehog;
pub mod node;
pub mod realtime;
pub mod ros2_sensors;
pub mod synthetic_fleet;

#[cfg(test)]
mod emulated_board_tests;
#[cfg(test)]
mod fuzz_world_tests;
