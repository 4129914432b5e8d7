//! End-to-end tests on loopback meshes: real processes (router, central
//! unit, cells, world, MSU agents) started through the `ickon` binary, on
//! ports of their own. They measure timing: `.config/nextest.toml` runs
//! each alone. One module per subject.

mod bench_central;
mod cell_status_mesh;
mod fleet_check;
mod foxglove_live;
mod marvelmind_msu;
mod mesh_control;
mod router_limits;
mod router_mesh;
mod secure_mesh;
mod secure_tls;
mod sim_convert_tdoa;
mod sim_devices;
mod sim_grouped;
mod sim_health;
mod sim_mesh;
mod sim_ros2;
mod sim_zones;
