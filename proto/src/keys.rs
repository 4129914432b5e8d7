//! Every Zenoh key expression of ICKON-rs, built and parsed here and nowhere else.
//!
//! Layout (prefix `ickon/<site>`):
//!
//! | key | payload |
//! |---|---|
//! | `ickon/<site>/central/site` (queryable) | [`msg::control::SiteInfo`](crate::msg::control::SiteInfo) |
//! | `ickon/<site>/central/schedule` (put + queryable) | [`msg::control::Schedule`](crate::msg::control::Schedule) |
//! | `ickon/<site>/central/cycle` | [`msg::control::CycleTrigger`](crate::msg::control::CycleTrigger) |
//! | `ickon/<site>/central/clock` (queryable) | [`msg::control::ClockRequest`](crate::msg::control::ClockRequest) in, [`msg::control::ClockReply`](crate::msg::control::ClockReply) out |
//! | `ickon/<site>/central/admin/<command>` (queryables) | [`msg::admin`](crate::msg::admin) |
//! | `ickon/<site>/alive/central`, `.../alive/cell/<id>`, `.../alive/robot/<id>`, `.../alive/world` | liveliness tokens, no payload (`world`: the simulated world, simulation only) |
//! | `ickon/<site>/cell/<id>/burst` | [`msg::control::Burst`](crate::msg::control::Burst) |
//! | `ickon/<site>/cell/<id>/status` | [`msg::control::CellStatus`](crate::msg::control::CellStatus) |
//! | `ickon/<site>/cell/<id>/air` | [`msg::control::AirTemperature`](crate::msg::control::AirTemperature) |
//! | `ickon/<site>/cell/<id>/link`, `.../robot/<id>/link` | [`msg::control::RouterLink`](crate::msg::control::RouterLink) |
//! | `ickon/<site>/robot/<id>/ultrasound` | [`msg::robot::UltrasoundArrivals`](crate::msg::robot::UltrasoundArrivals) |
//! | `ickon/<site>/robot/<id>/odom` | [`msg::robot::Odometry`](crate::msg::robot::Odometry) |
//! | `ickon/<site>/robot/<id>/imu` | [`msg::robot::Imu`](crate::msg::robot::Imu) |
//! | `ickon/<site>/robot/<id>/range` | [`msg::robot::ObstacleRanges`](crate::msg::robot::ObstacleRanges) |
//! | `ickon/<site>/robot/<id>/fix` | [`msg::robot::Fix`](crate::msg::robot::Fix) |
//! | `ickon/<site>/robot/<id>/pose` | [`msg::robot::RobotPose`](crate::msg::robot::RobotPose) |
//! | `ickon/<site>/sim/truth/<id>` | [`msg::robot::Truth`](crate::msg::robot::Truth) |
//! | `ickon/<site>/sim/probe` | `u64` sequence number: one-hop latency probes of `ickon sim` |
//!
//! Identifiers (site, cell and robot ids) are checked by [`validate_id`]: a
//! non-empty chunk of letters, digits, `-` and `_`, so that no id can smuggle
//! a `/` or a wildcard into a key.

use thiserror::Error;

/// The first chunk of every key.
pub const ROOT: &str = "ickon";

/// Why an id or a key was refused.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum KeyError {
    /// An id that is empty, too long, or has characters other than `[A-Za-z0-9_-]`.
    #[error(
        "invalid id {0:?}: use 1 to 64 letters, digits, '-' or '_' (no '/', spaces or wildcards)"
    )]
    InvalidId(String),
    /// A key that does not follow the ICKON layout.
    #[error("not an ICKON key: {0:?}")]
    Unknown(String),
}

/// Checks that `id` can stand as one chunk of a key expression.
pub fn validate_id(id: &str) -> Result<(), KeyError> {
    let ok = !id.is_empty()
        && id.len() <= 64
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if ok {
        Ok(())
    } else {
        Err(KeyError::InvalidId(id.to_string()))
    }
}

/// The per-robot streams under `robot/<id>/...`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RobotTopic {
    /// Arrivals of one cycle on the MSU clock.
    Ultrasound,
    /// Wheel odometry.
    Odom,
    /// Gyro z rate.
    Imu,
    /// Obstacle sensor ranges.
    Range,
    /// Raw MSU fix.
    Fix,
    /// Fused pose.
    Pose,
}

impl RobotTopic {
    /// Every robot topic, in a fixed order.
    pub const ALL: [RobotTopic; 6] = [
        RobotTopic::Ultrasound,
        RobotTopic::Odom,
        RobotTopic::Imu,
        RobotTopic::Range,
        RobotTopic::Fix,
        RobotTopic::Pose,
    ];

    /// The last chunk of the key.
    pub const fn chunk(self) -> &'static str {
        match self {
            RobotTopic::Ultrasound => "ultrasound",
            RobotTopic::Odom => "odom",
            RobotTopic::Imu => "imu",
            RobotTopic::Range => "range",
            RobotTopic::Fix => "fix",
            RobotTopic::Pose => "pose",
        }
    }
}

/// A parsed ICKON key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Key {
    /// `central/site`
    CentralSite,
    /// `central/schedule`
    CentralSchedule,
    /// `central/cycle`
    CentralCycle,
    /// `central/clock`
    CentralClock,
    /// `central/survey`
    CentralSurvey,
    /// `central/admin/<command>`
    CentralAdmin(String),
    /// `alive/central`
    AliveCentral,
    /// `alive/cell/<id>`
    AliveCell(String),
    /// `alive/robot/<id>`
    AliveRobot(String),
    /// `alive/world`
    AliveWorld,
    /// `cell/<id>/burst`
    CellBurst(String),
    /// `cell/<id>/status`
    CellStatus(String),
    /// `cell/<id>/air`
    CellAir(String),
    /// `cell/<id>/link`
    CellLink(String),
    /// `robot/<id>/<topic>`
    Robot(String, RobotTopic),
    /// `robot/<id>/status`
    RobotStatus(String),
    /// `robot/<id>/summary`
    RobotSummary(String),
    /// `robot/<id>/link`
    RobotLink(String),
    /// `sim/truth/<id>`
    SimTruth(String),
    /// `sim/kit/<id>`
    SimKit(String),
    /// `sim/probe`
    SimProbe,
}

/// Builds and parses the keys of one site.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Keys {
    prefix: String,
}

impl Keys {
    /// Keys for the site named `site` (checked with [`validate_id`]).
    pub fn new(site: &str) -> Result<Self, KeyError> {
        validate_id(site)?;
        Ok(Keys {
            prefix: format!("{ROOT}/{site}"),
        })
    }

    /// `ickon/<site>`: the prefix of every key of this site.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// `ickon/<site>/**`: everything of this site.
    pub fn everything(&self) -> String {
        format!("{}/**", self.prefix)
    }

    /// `ickon/<site>/central/site`: queryable answering [`SiteInfo`](crate::msg::control::SiteInfo).
    pub fn central_site(&self) -> String {
        format!("{}/central/site", self.prefix)
    }

    /// `ickon/<site>/central/schedule`: put and queryable of [`Schedule`](crate::msg::control::Schedule).
    pub fn central_schedule(&self) -> String {
        format!("{}/central/schedule", self.prefix)
    }

    /// `ickon/<site>/central/cycle`: [`CycleTrigger`](crate::msg::control::CycleTrigger) puts.
    pub fn central_cycle(&self) -> String {
        format!("{}/central/cycle", self.prefix)
    }

    /// `ickon/<site>/central/survey`: [`SurveyCalibration`](crate::msg::control::SurveyCalibration) puts.
    pub fn central_survey(&self) -> String {
        format!("{}/central/survey", self.prefix)
    }

    /// `ickon/<site>/central/clock`: queryable, [`ClockRequest`](crate::msg::control::ClockRequest)
    /// in the query payload, [`ClockReply`](crate::msg::control::ClockReply) back.
    pub fn central_clock(&self) -> String {
        format!("{}/central/clock", self.prefix)
    }

    /// `ickon/<site>/central/admin/<command>`: admin queryables ([`msg::admin`](crate::msg::admin)).
    pub fn central_admin(&self, command: &str) -> Result<String, KeyError> {
        validate_id(command)?;
        Ok(format!("{}/central/admin/{command}", self.prefix))
    }

    /// `ickon/<site>/central/admin/**`: what the central unit declares to answer every admin command.
    pub fn central_admin_all(&self) -> String {
        format!("{}/central/admin/**", self.prefix)
    }

    /// `ickon/<site>/alive/central`: liveliness token of the central unit.
    pub fn alive_central(&self) -> String {
        format!("{}/alive/central", self.prefix)
    }

    /// `ickon/<site>/alive/cell/<id>`: liveliness token of a cell controller.
    pub fn alive_cell(&self, cell: &str) -> Result<String, KeyError> {
        validate_id(cell)?;
        Ok(format!("{}/alive/cell/{cell}", self.prefix))
    }

    /// `ickon/<site>/alive/robot/<id>`: liveliness token of an MSU agent.
    pub fn alive_robot(&self, robot: &str) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/alive/robot/{robot}", self.prefix))
    }

    /// `ickon/<site>/alive/world`: liveliness token of the simulated world (simulation only).
    pub fn alive_world(&self) -> String {
        format!("{}/alive/world", self.prefix)
    }

    /// `ickon/<site>/alive/**`: every liveliness token of the site.
    pub fn alive_all(&self) -> String {
        format!("{}/alive/**", self.prefix)
    }

    /// `ickon/<site>/cell/<id>/burst`: [`Burst`](crate::msg::control::Burst) emission reports.
    pub fn cell_burst(&self, cell: &str) -> Result<String, KeyError> {
        validate_id(cell)?;
        Ok(format!("{}/cell/{cell}/burst", self.prefix))
    }

    /// `ickon/<site>/cell/*/burst`: bursts of every cell.
    pub fn cell_burst_all(&self) -> String {
        format!("{}/cell/*/burst", self.prefix)
    }

    /// `ickon/<site>/cell/<id>/status`: [`CellStatus`](crate::msg::control::CellStatus) reports.
    pub fn cell_status(&self, cell: &str) -> Result<String, KeyError> {
        validate_id(cell)?;
        Ok(format!("{}/cell/{cell}/status", self.prefix))
    }

    /// `ickon/<site>/cell/*/status`: status of every cell.
    pub fn cell_status_all(&self) -> String {
        format!("{}/cell/*/status", self.prefix)
    }

    /// `ickon/<site>/cell/<id>/air`: [`AirTemperature`](crate::msg::control::AirTemperature)
    /// readings of the cell board's sensor.
    pub fn cell_air(&self, cell: &str) -> Result<String, KeyError> {
        validate_id(cell)?;
        Ok(format!("{}/cell/{cell}/air", self.prefix))
    }

    /// `ickon/<site>/cell/*/air`: air temperatures of every cell.
    pub fn cell_air_all(&self) -> String {
        format!("{}/cell/*/air", self.prefix)
    }

    /// `ickon/<site>/cell/<id>/link`: the cell controller's
    /// [`RouterLink`](crate::msg::control::RouterLink).
    pub fn cell_link(&self, cell: &str) -> Result<String, KeyError> {
        validate_id(cell)?;
        Ok(format!("{}/cell/{cell}/link", self.prefix))
    }

    /// `ickon/<site>/cell/*/link`: every cell's link to its router.
    pub fn cell_link_all(&self) -> String {
        format!("{}/cell/*/link", self.prefix)
    }

    /// `ickon/<site>/robot/<id>/link`: the MSU agent's
    /// [`RouterLink`](crate::msg::control::RouterLink).
    pub fn robot_link(&self, robot: &str) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/robot/{robot}/link", self.prefix))
    }

    /// `ickon/<site>/robot/*/link`: every robot's link to its router.
    pub fn robot_link_all(&self) -> String {
        format!("{}/robot/*/link", self.prefix)
    }

    /// `ickon/<site>/robot/<id>/<topic>`: see [`RobotTopic`] for the payloads.
    pub fn robot(&self, robot: &str, topic: RobotTopic) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/robot/{robot}/{}", self.prefix, topic.chunk()))
    }

    /// `ickon/<site>/robot/<id>/status`: the MSU agent's
    /// [`MsuStatus`](crate::msg::robot::MsuStatus).
    pub fn robot_status(&self, robot: &str) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/robot/{robot}/status", self.prefix))
    }

    /// `ickon/<site>/robot/*/status`: every agent's status.
    pub fn robot_status_all(&self) -> String {
        format!("{}/robot/*/status", self.prefix)
    }

    /// `ickon/<site>/robot/<id>/summary`: the robot's
    /// [`RobotSummary`](crate::msg::robot::RobotSummary) for the central unit.
    pub fn robot_summary(&self, robot: &str) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/robot/{robot}/summary", self.prefix))
    }

    /// `ickon/<site>/robot/*/summary`: every robot's summary.
    pub fn robot_summary_all(&self) -> String {
        format!("{}/robot/*/summary", self.prefix)
    }

    /// `ickon/<site>/robot/*/<topic>`: one topic of every robot.
    pub fn robot_all(&self, topic: RobotTopic) -> String {
        format!("{}/robot/*/{}", self.prefix, topic.chunk())
    }

    /// `ickon/<site>/sim/truth/<id>`: ground truth [`Truth`](crate::msg::robot::Truth) (simulation only).
    pub fn sim_truth(&self, robot: &str) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/sim/truth/{robot}", self.prefix))
    }

    /// `ickon/<site>/sim/kit/<id>`: the position a robot's emulated ranging
    /// kit (a Marvelmind hedgehog) reported, on the layout of a
    /// [`Truth`](crate::msg::robot::Truth) (its `robot_clock` the instant
    /// on the robot's clock; speed and heading 0), to score the kit as an
    /// estimator of its own (simulation only).
    pub fn sim_kit(&self, robot: &str) -> Result<String, KeyError> {
        validate_id(robot)?;
        Ok(format!("{}/sim/kit/{robot}", self.prefix))
    }

    /// `ickon/<site>/sim/kit/*`: the kit positions of every robot.
    pub fn sim_kit_all(&self) -> String {
        format!("{}/sim/kit/*", self.prefix)
    }

    /// `ickon/<site>/sim/probe`: latency probes of `ickon sim` (a CDR `u64`
    /// sequence number), to measure the plain one-hop Zenoh latency of a run.
    pub fn sim_probe(&self) -> String {
        format!("{}/sim/probe", self.prefix)
    }

    /// `ickon/<site>/sim/truth/*`: ground truth of every robot.
    pub fn sim_truth_all(&self) -> String {
        format!("{}/sim/truth/*", self.prefix)
    }

    /// Parses a concrete key of this site.
    pub fn parse(&self, key: &str) -> Result<Key, KeyError> {
        let unknown = || KeyError::Unknown(key.to_string());
        let rest = key
            .strip_prefix(self.prefix.as_str())
            .and_then(|r| r.strip_prefix('/'))
            .ok_or_else(unknown)?;
        let chunks: Vec<&str> = rest.split('/').collect();
        let id = |s: &str| -> Result<String, KeyError> {
            validate_id(s).map_err(|_| unknown())?;
            Ok(s.to_string())
        };
        match chunks.as_slice() {
            ["central", "site"] => Ok(Key::CentralSite),
            ["central", "schedule"] => Ok(Key::CentralSchedule),
            ["central", "cycle"] => Ok(Key::CentralCycle),
            ["central", "clock"] => Ok(Key::CentralClock),
            ["central", "survey"] => Ok(Key::CentralSurvey),
            ["central", "admin", cmd] => Ok(Key::CentralAdmin(id(cmd)?)),
            ["alive", "central"] => Ok(Key::AliveCentral),
            ["alive", "world"] => Ok(Key::AliveWorld),
            ["alive", "cell", c] => Ok(Key::AliveCell(id(c)?)),
            ["alive", "robot", r] => Ok(Key::AliveRobot(id(r)?)),
            ["cell", c, "burst"] => Ok(Key::CellBurst(id(c)?)),
            ["cell", c, "status"] => Ok(Key::CellStatus(id(c)?)),
            ["cell", c, "air"] => Ok(Key::CellAir(id(c)?)),
            ["cell", c, "link"] => Ok(Key::CellLink(id(c)?)),
            ["robot", r, "status"] => Ok(Key::RobotStatus(id(r)?)),
            ["robot", r, "summary"] => Ok(Key::RobotSummary(id(r)?)),
            ["robot", r, "link"] => Ok(Key::RobotLink(id(r)?)),
            ["robot", r, topic] => {
                let topic = RobotTopic::ALL
                    .into_iter()
                    .find(|t| t.chunk() == *topic)
                    .ok_or_else(unknown)?;
                Ok(Key::Robot(id(r)?, topic))
            }
            ["sim", "truth", r] => Ok(Key::SimTruth(id(r)?)),
            ["sim", "kit", r] => Ok(Key::SimKit(id(r)?)),
            ["sim", "probe"] => Ok(Key::SimProbe),
            _ => Err(unknown()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_key_parses_back_to_what_built_it() {
        let k = Keys::new("lab").unwrap();
        let cases = vec![
            (k.central_site(), Key::CentralSite),
            (k.central_schedule(), Key::CentralSchedule),
            (k.central_cycle(), Key::CentralCycle),
            (k.central_clock(), Key::CentralClock),
            (k.central_survey(), Key::CentralSurvey),
            (
                k.central_admin("status").unwrap(),
                Key::CentralAdmin("status".into()),
            ),
            (k.alive_central(), Key::AliveCentral),
            (k.alive_world(), Key::AliveWorld),
            (k.alive_cell("c1").unwrap(), Key::AliveCell("c1".into())),
            (k.alive_robot("r1").unwrap(), Key::AliveRobot("r1".into())),
            (k.cell_burst("c2").unwrap(), Key::CellBurst("c2".into())),
            (k.cell_status("c2").unwrap(), Key::CellStatus("c2".into())),
            (k.cell_air("c2").unwrap(), Key::CellAir("c2".into())),
            (k.sim_truth("r9").unwrap(), Key::SimTruth("r9".into())),
            (k.sim_kit("r9").unwrap(), Key::SimKit("r9".into())),
            (k.robot_status("r9").unwrap(), Key::RobotStatus("r9".into())),
            (k.cell_link("c2").unwrap(), Key::CellLink("c2".into())),
            (k.robot_link("r9").unwrap(), Key::RobotLink("r9".into())),
            (
                k.robot_summary("r9").unwrap(),
                Key::RobotSummary("r9".into()),
            ),
            (k.sim_probe(), Key::SimProbe),
        ];
        for (key, expected) in cases {
            assert_eq!(k.parse(&key).unwrap(), expected, "{key}");
        }
        for topic in RobotTopic::ALL {
            let key = k.robot("r-2", topic).unwrap();
            assert_eq!(k.parse(&key).unwrap(), Key::Robot("r-2".into(), topic));
        }
    }

    #[test]
    fn keys_have_the_documented_layout() {
        let k = Keys::new("lab").unwrap();
        assert_eq!(k.central_cycle(), "ickon/lab/central/cycle");
        assert_eq!(
            k.robot("r1", RobotTopic::Pose).unwrap(),
            "ickon/lab/robot/r1/pose"
        );
        assert_eq!(k.cell_burst_all(), "ickon/lab/cell/*/burst");
    }

    #[test]
    fn ids_cannot_smuggle_separators_or_wildcards() {
        for bad in ["", "a/b", "*", "**", "a b", "x$", "é", &"x".repeat(65)] {
            assert!(validate_id(bad).is_err(), "{bad:?} accepted");
        }
        let k = Keys::new("lab").unwrap();
        assert!(k.alive_cell("c1/../c2").is_err());
        assert!(Keys::new("my site").is_err());
    }

    #[test]
    fn foreign_and_malformed_keys_are_refused() {
        let k = Keys::new("lab").unwrap();
        for bad in [
            "ickon/other/central/site",
            "ickon/lab",
            "ickon/lab/robot/r1/nonsense",
            "ickon/lab/robot/r1",
            "ickon/lab/cell/c1/burst/extra",
            "ickon/labx/central/site",
        ] {
            assert!(k.parse(bad).is_err(), "{bad} accepted");
        }
    }
}
