//! The viewers as sinks of the node's loop: the web map and the Foxglove
//! server are handed what the loop received and the status it made, and
//! never subscribe on their own.

use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::{RobotSummary, Truth};

/// How often the viewers are handed the whole status (every robot's
/// health, every cell's): as often as a robot's health can change, at its
/// summary (the robots move on the viewers with each summary, handed over
/// as it is taken: `SUMMARY_PERIOD`). At the viewers' own 20 Hz, 10,000 robots' health made
/// and copied twenty times a second was a large part of the central
/// unit's core.
pub(super) const VIEWER_STATUS_PERIOD: std::time::Duration = std::time::Duration::from_millis(500);

/// Whoever watches the central unit's status live: the web map
/// (`--http`) and the Foxglove server (`--foxglove`), each optional.
#[derive(Default)]
pub struct Viewers {
    /// The web map.
    pub web: Option<crate::http::WebMap>,
    /// The Foxglove live server.
    pub foxglove: Option<crate::foxglove::FoxgloveLive>,
}

impl Viewers {
    /// Whether there is any.
    pub fn any(&self) -> bool {
        self.web.is_some() || self.foxglove.is_some()
    }

    /// Hands the transmitters report `make` gives to the Foxglove server,
    /// made only when there is one (never waits).
    pub fn publish_transmitters(
        &self,
        make: impl FnOnce() -> ickon_proto::msg::admin::TransmittersReport,
    ) {
        if let Some(f) = &self.foxglove {
            f.publish_transmitters(make());
        }
    }

    /// Hands `status` to each (never waits).
    pub fn publish(&self, status: ickon_proto::msg::admin::StatusReport) {
        if let Some(f) = &self.foxglove {
            f.publish(status.clone());
        }
        if let Some(w) = &self.web {
            w.publish(status);
        }
    }

    /// Where each draws from: what the central unit's loop hands them is
    /// all they see of the robots.
    fn sinks(&self) -> impl Iterator<Item = &crate::http::feed::ViewSink> {
        let web = self.web.as_ref().map(|w| w.sink());
        web.into_iter()
            .chain(self.foxglove.as_ref().map(|f| f.sink()))
    }

    /// A robot's summary the central unit took.
    pub(super) fn summary(&self, robot: &str, summary: &RobotSummary) {
        self.sinks().for_each(|v| v.summary(robot, summary));
    }

    /// A burst report.
    pub(super) fn burst(&self, burst: &Burst) {
        self.sinks().for_each(|v| v.burst(burst));
    }

    /// A robot's truth (simulation only).
    pub(super) fn truth(&self, robot: &str, truth: Truth) {
        self.sinks().for_each(|v| v.truth(robot, truth));
    }
}
