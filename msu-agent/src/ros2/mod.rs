//! The MSU agent on ROS 2, with no glue for the user to write.
//!
//! With `--ros2` the agent also speaks ROS 2 over its Zenoh session, as
//! rmw_zenoh does (or as `zenoh-bridge-ros2dds` maps DDS topics):
//! - publishes the fused pose on `/<robot>/pose` and the raw fix on
//!   `/<robot>/ickon/fix` (`geometry_msgs/msg/PoseWithCovarianceStamped`,
//!   frame `map`) and `map -> odom` on `/tf` (`tf2_msgs/msg/TFMessage`), as
//!   AMCL does, so that nav2 runs on it unchanged;
//! - reads `/<robot>/odom` (`nav_msgs/msg/Odometry`) and `/<robot>/imu`
//!   (`sensor_msgs/msg/Imu`, its z rate) as its odometry and gyro;
//! - declares rmw_zenoh's liveliness tokens for the node and each endpoint
//!   (so `ros2 node list`, `ros2 topic list` and `ros2 topic echo` see it)
//!   and attaches rmw_zenoh's 33 bytes to every sample.
//!
//! Pure parts: [`options`] (flags and the config block), [`plan`] (validated
//! names, keys, tokens), [`inputs`] (ROS samples to MSU inputs),
//! [`outputs`] (MSU outputs to ROS messages), [`bad_input`] (counting and
//! rate-limited logging). The Zenoh adapter is [`link`]. The keys, tokens
//! and attachment themselves are spelled in [`ickon_proto::ros`].

pub mod bad_input;
pub mod inputs;
pub mod link;
pub mod options;
pub mod outputs;
pub mod plan;

#[cfg(test)]
mod tests;

pub use inputs::{InputDecoder, InputTopic, Ros2Input};
pub use link::{Ros2Counters, Ros2Link, next_input};
pub use options::{Ros2Mode, Ros2Options};
pub use plan::{Ros2ConfigError, Ros2Plan};
