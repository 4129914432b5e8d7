//! # ickon-recording
//!
//! A running site kept and played again:
//!
//! - `ickon record` ([`RecordArgs`], [`run_record`]): every message of a
//!   site into an MCAP file of the ROS 2 profile, which Foxglove and
//!   `ros2 bag` open; `ickon sim --record` runs the same loop in the
//!   launcher ([`sim_hook`]);
//! - `ickon replay mcap` ([`McapArgs`], [`run_replay`]): a recording through
//!   the MSU cores again, scored against its truth, the live agents' poses
//!   compared with the replayed ones;
//! - `ickon convert mcap` ([`ConvertMcapArgs`], [`run_convert`]): a
//!   recording written in the arrival-time log format of
//!   `ickon replay tdoa`.

mod convert;
mod record;
mod replay;

pub use convert::{ConvertMcapArgs, run as run_convert};
pub use record::sim_hook;
pub use record::{RecordArgs, RecordReport, run as run_record};
pub use replay::{McapArgs, run as run_replay};
