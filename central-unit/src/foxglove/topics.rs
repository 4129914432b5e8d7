//! The topics of the Foxglove live server (and of the Foxglove channels of
//! a recording): their names, and the channels made per robot and per cell.
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/site/scene` | `foxglove.SceneUpdate` | walls, racks and pillars, routes (simulation) |
//! | `/site/cells` | `foxglove.SceneUpdate` | cell outlines by state, transmitters lit while firing |
//! | `/site/status` | JSON `ickon.SiteStatus` | cycle, rate, paused |
//! | `/robots/scene` | `foxglove.SceneUpdate` | every robot: pose, ellipse, fix, state, truth |
//! | `/tf` | `foxglove.FrameTransforms` | `map` -> `<robot>` |
//! | `/log` | `foxglove.Log` | cells and robots going wrong and well again |
//! | `/robot/<id>/pose` | `foxglove.PoseInFrame` | fused pose |
//! | `/robot/<id>/fix` | `foxglove.PoseInFrame` | latest raw fix (heading when it has one) |
//! | `/robot/<id>/truth` | `foxglove.PoseInFrame` | true pose at the fused pose's time (simulation only) |
//! | `/robot/<id>/state` | JSON `ickon.RobotState` | state, sigmas, error, fix rate |
//! | `/cell/<id>/sync` | JSON `ickon.CellSync` | sync error, offset, drift, firing |
//! | `/site/speed_of_sound` | JSON `ickon.SpeedOfSound` | the speed of sound in use, its sigma, the site file's, the boards' air's |
//! | `/transmitters/scene` | `foxglove.SceneUpdate` | a sphere per transmitter coloured by its health |
//! | `/transmitters/status` | JSON `ickon.TransmitterHealth` | each transmitter's health, heard share, residuals, last heard |

use std::sync::Arc;

use foxglove::messages::{PoseInFrame, Timestamp};
use foxglove::{Channel, Context, RawChannel};

use super::plots;
use super::scene::{MAP_FRAME, yaw_pose};
use crate::http::view::{CellSnapshot, PoseView, RobotSnapshot};

/// The site's fixed scene.
pub const SITE_SCENE: &str = "/site/scene";
/// The cells and transmitters.
pub const CELLS_SCENE: &str = "/site/cells";
/// The central unit's cycle, rate and pause.
pub const SITE_STATUS: &str = "/site/status";
/// The fleet as a scene.
pub const ROBOTS_SCENE: &str = "/robots/scene";
/// The frame of every robot in the map.
pub const TF: &str = "/tf";
/// The site's log.
pub const LOG: &str = "/log";
/// The speed of sound in use.
pub const SPEED_OF_SOUND: &str = "/site/speed_of_sound";
/// The transmitters by health, as a scene.
pub const TRANSMITTERS_SCENE: &str = "/transmitters/scene";
/// The transmitters' health, to read and plot.
pub const TRANSMITTERS_STATUS: &str = "/transmitters/status";

/// `/robot/<id>/<what>`.
pub fn robot_topic(id: &str, what: &str) -> String {
    format!("/robot/{id}/{what}")
}

/// `/cell/<id>/sync`.
pub fn cell_topic(id: &str) -> String {
    format!("/cell/{id}/sync")
}

fn pose_in_frame(p: &PoseView, stamp: Timestamp) -> PoseInFrame {
    PoseInFrame {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.into(),
        pose: Some(yaw_pose(p.x_m, p.y_m, 0.0, p.theta_rad)),
    }
}

/// The channels of one robot.
pub struct RobotChannels {
    pose: Channel<PoseInFrame>,
    fix: Channel<PoseInFrame>,
    truth: Channel<PoseInFrame>,
    state: Arc<RawChannel>,
}

impl RobotChannels {
    /// Advertises the channels of robot `id` on `context`.
    pub fn new(context: &Arc<Context>, id: &str) -> Self {
        Self {
            pose: context.channel_builder(robot_topic(id, "pose")).build(),
            fix: context.channel_builder(robot_topic(id, "fix")).build(),
            truth: context.channel_builder(robot_topic(id, "truth")).build(),
            state: plots::robot_channel(context, &robot_topic(id, "state")),
        }
    }

    /// Sends what the snapshot knows of the robot.
    pub fn send(&self, r: &RobotSnapshot, stamp: Timestamp) {
        if let Some(p) = &r.fused {
            self.pose.log(&pose_in_frame(p, stamp));
        }
        if let Some(f) = &r.fix {
            let heading = f.heading_rad.unwrap_or(0.0);
            self.fix.log(&pose_in_frame(
                &PoseView {
                    x_m: f.x_m,
                    y_m: f.y_m,
                    theta_rad: heading,
                },
                stamp,
            ));
        }
        // The truth at the pose's own time, so that the two differ by the
        // pose's error, not by the motion between their stamps.
        if let Some(t) = &r.truth_at_pose {
            self.truth.log(&pose_in_frame(t, stamp));
        }
        plots::log_robot(&self.state, r);
    }
}

/// The channel of one cell.
pub struct CellChannels {
    sync: Arc<RawChannel>,
}

impl CellChannels {
    /// Advertises the channel of cell `id` on `context`.
    pub fn new(context: &Arc<Context>, id: &str) -> Self {
        Self {
            sync: plots::cell_channel(context, &cell_topic(id)),
        }
    }

    /// Sends the cell's figures; `cycle_period_ms` tells whether it fired
    /// in the current cycle.
    pub fn send(&self, c: &CellSnapshot, cycle_period_ms: f64) {
        plots::log_cell(&self.sync, c, cycle_period_ms);
    }
}
