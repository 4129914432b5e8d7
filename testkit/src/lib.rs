//! # ickon-testkit: the loopback test kit
//!
//! What tests that run ICKON-rs processes over a loopback Zenoh mesh share,
//! so that parallel tests never cross-talk and never leave a process behind:
//!
//! - [`port`]: a free loopback port (bound on port 0, the port read back);
//! - [`child`]: [`ChildGuard`], a spawned process whose output goes to a log
//!   file and which is killed when the guard is dropped, panic or not;
//! - [`wait`]: [`poll_until`], every wait bounded by a deadline and done by
//!   polling a condition, never by sleeping a guessed time;
//! - [`observer`]: [`Observer`], a Zenoh session of the test itself,
//!   listening on `tcp/127.0.0.1:0` with multicast scouting off, its bound
//!   locators read back;
//! - [`rosbags`]: [`Rosbags`], the independent ROS 2 CDR decoder and
//!   encoder (PyPI `rosbags`) the ROS 2 tests check against;
//! - [`site`]: [`lab_site_file`], the built-in site under a test's own name;
//! - [`data`]: [`real_data`], the real measurement data (`ICKON_DATA`).
//!
//! The end-to-end tests that use it are the `ickon-tests` crate at the
//! top of the repository (e.g. `tests/mesh/mesh_control.rs`).

pub mod child;
pub mod data;
pub mod observer;
pub mod port;
pub mod rosbags;
pub mod site;
pub mod wait;

pub use child::ChildGuard;
pub use data::{DATA_VARIABLE, real_data};
pub use observer::Observer;
pub use port::{free_tcp_port, loopback_endpoint};
pub use rosbags::Rosbags;
pub use site::lab_site_file;
pub use wait::{TimedOut, poll_until};
