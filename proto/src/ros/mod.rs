//! ROS 2 over Zenoh: the conventions of rmw_zenoh (ROS 2 Jazzy and newer,
//! `rmw_zenoh_cpp` >= 0.2.4) and of `zenoh-bridge-ros2dds`, as pure
//! functions over strings and bytes, so that the MSU agent, the simulated
//! world and the recorders spell them one way. The messages themselves are
//! in [`crate::msg::ros`].
//!
//! - [`names`]: ROS names (`/r1/pose`), namespaces and their resolution;
//! - [`keys`]: the data keys of both conventions, and rmw_zenoh's liveliness
//!   tokens for nodes, publishers and subscribers with their QoS;
//! - [`attachment`]: the 33-byte attachment rmw_zenoh puts on every sample.
//!
//! The facts are from rmw_zenoh's `docs/design.md`, `liveliness_utils.cpp`
//! and `attachment_helpers.cpp` (docs/ros2.md, "The conventions in detail"); the
//! tests check the examples given there.

pub mod attachment;
pub mod keys;
pub mod names;

#[cfg(test)]
mod tests;

pub use attachment::{ATTACHMENT_LEN, Attachment, AttachmentError, SampleStamper, gid_for};
pub use keys::{EndpointKind, NodeIdentity, Qos, RosKeys, Transport};
pub use names::{RosNameError, resolve_topic, validate_namespace};
