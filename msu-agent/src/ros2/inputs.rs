//! The robot's ROS 2 odometry and IMU as the MSU's own inputs. Pure: bytes,
//! key and attachment in, an [`Odometry`] or [`Imu`] of ours (or the kind
//! of bad input) out.
//!
//! The estimators take wheel encoder ticks; a ROS 2 robot publishes the
//! pose its own dead reckoning integrated (`nav_msgs/msg/Odometry`). Each
//! step of that pose is turned back into the wheel travel that produces it
//! under the agent's drive geometry (midpoint arc: distance along the mean
//! heading, turn from the wheel difference), accumulated, and given as
//! ticks of the agent's tick size: the estimators then see the motion the
//! robot reported, whatever its drive. For odometry that came from ticks of
//! that same geometry (the simulated robots) this gives the ticks back.

use ickon_fusion::estimator::WheelGeometry;
use ickon_proto::msg::robot;
use ickon_proto::msg::ros::{self, RosMessage};
use ickon_proto::ros::keys::split_type_and_hash;
use ickon_proto::ros::names::dds_type_name;
use ickon_proto::ros::{Attachment, RosKeys};
use ickon_proto::time::Time;

use super::bad_input::BadInputKind;

/// Largest odometry step between two samples believed, metres: more than a
/// ground robot covers between two samples; beyond it the odometry was
/// reset or forged, and the track is re-anchored instead of driven.
pub const MAX_ODOM_STEP_M: f64 = 2.0;

/// Which input topic a sample came on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputTopic {
    /// `nav_msgs/msg/Odometry`.
    Odom,
    /// `sensor_msgs/msg/Imu`.
    Imu,
}

/// A sample converted to the MSU's inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ros2Input {
    /// Odometry, with ticks derived from the reported motion.
    Odometry(robot::Odometry),
    /// The z rate of the IMU as the gyro.
    Imu(robot::Imu),
}

#[derive(Debug, Clone, Copy)]
struct Track {
    x_m: f64,
    y_m: f64,
    yaw_rad: f64,
    /// Unwrapped heading handed to the core.
    theta_rad: f64,
    left_m: f64,
    right_m: f64,
}

/// The decoder's state: the odometry track and the newest stamp per topic.
#[derive(Debug, Clone)]
pub struct InputDecoder {
    keys: RosKeys,
    wheels: WheelGeometry,
    track: Option<Track>,
    newest_odom: Option<Time>,
    newest_imu: Option<Time>,
}

fn finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

fn wrap(a: f64) -> f64 {
    let w =
        (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
    if w <= -std::f64::consts::PI {
        w + 2.0 * std::f64::consts::PI
    } else {
        w
    }
}

impl InputDecoder {
    /// A decoder for keys of `keys`' convention, converting motion to ticks
    /// of `wheels`.
    pub fn new(keys: RosKeys, wheels: WheelGeometry) -> Self {
        Self {
            keys,
            wheels,
            track: None,
            newest_odom: None,
            newest_imu: None,
        }
    }

    /// Checks the key's type (rmw_zenoh) and the attachment.
    fn check_envelope<M: RosMessage>(
        &self,
        key: &str,
        attachment: Option<&[u8]>,
    ) -> Result<(), BadInputKind> {
        if !self.keys.is_rmw_zenoh() {
            return Ok(());
        }
        let expected = dds_type_name(M::TYPE_NAME).map_err(|_| BadInputKind::WrongType)?;
        match split_type_and_hash(key) {
            Some((t, h)) if t == expected && h == M::TYPE_HASH => {}
            _ => return Err(BadInputKind::WrongType),
        }
        let Some(bytes) = attachment else {
            return Err(BadInputKind::NoAttachment);
        };
        Attachment::parse(bytes).map_err(|_| BadInputKind::BadAttachment)?;
        Ok(())
    }

    /// Converts one sample of `topic` received on `key`.
    pub fn decode(
        &mut self,
        topic: InputTopic,
        key: &str,
        payload: &[u8],
        attachment: Option<&[u8]>,
    ) -> Result<Ros2Input, BadInputKind> {
        match topic {
            InputTopic::Odom => {
                self.check_envelope::<ros::Odometry>(key, attachment)?;
                let m: ros::Odometry =
                    ickon_proto::decode(payload).map_err(|_| BadInputKind::Undecodable)?;
                self.odometry(&m).map(Ros2Input::Odometry)
            }
            InputTopic::Imu => {
                self.check_envelope::<ros::Imu>(key, attachment)?;
                let m: ros::Imu =
                    ickon_proto::decode(payload).map_err(|_| BadInputKind::Undecodable)?;
                self.imu(&m).map(Ros2Input::Imu)
            }
        }
    }

    fn stamp(newest: &mut Option<Time>, stamp: ros::RosTime) -> Result<Time, BadInputKind> {
        let t = stamp.to_time().ok_or(BadInputKind::BadStamp)?;
        if newest.is_some_and(|n| t < n) {
            return Err(BadInputKind::Backwards);
        }
        *newest = Some(t);
        Ok(t)
    }

    /// One ROS odometry sample as ours.
    pub fn odometry(&mut self, m: &ros::Odometry) -> Result<robot::Odometry, BadInputKind> {
        let p = &m.pose.pose;
        let t = &m.twist.twist;
        if !(finite(&[p.position.x, p.position.y, p.position.z])
            && finite(&[
                p.orientation.x,
                p.orientation.y,
                p.orientation.z,
                p.orientation.w,
            ])
            && finite(&[
                t.linear.x,
                t.linear.y,
                t.linear.z,
                t.angular.x,
                t.angular.y,
                t.angular.z,
            ])
            && finite(&m.pose.covariance)
            && finite(&m.twist.covariance))
        {
            return Err(BadInputKind::NonFinite);
        }
        let norm = (p.orientation.x.powi(2)
            + p.orientation.y.powi(2)
            + p.orientation.z.powi(2)
            + p.orientation.w.powi(2))
        .sqrt();
        // A (near) zero quaternion is no rotation at all; the norm is finite here.
        if norm <= 1e-6 {
            return Err(BadInputKind::NonFinite);
        }
        let stamp = Self::stamp(&mut self.newest_odom, m.header.stamp)?;
        let yaw = p.orientation.yaw_rad();
        let (x, y) = (p.position.x, p.position.y);
        let mut jumped = false;
        let next = match self.track {
            None => Track {
                x_m: x,
                y_m: y,
                yaw_rad: yaw,
                theta_rad: yaw,
                left_m: 0.0,
                right_m: 0.0,
            },
            Some(prev) => {
                let (dx, dy) = (x - prev.x_m, y - prev.y_m);
                let dth = wrap(yaw - prev.yaw_rad);
                if dx.hypot(dy) > MAX_ODOM_STEP_M {
                    jumped = true;
                    Track {
                        x_m: x,
                        y_m: y,
                        yaw_rad: yaw,
                        ..prev
                    }
                } else {
                    let mid = prev.yaw_rad + 0.5 * dth;
                    let ds = dx * mid.cos() + dy * mid.sin();
                    let half_turn = 0.5 * dth * self.wheels.wheel_base_m;
                    Track {
                        x_m: x,
                        y_m: y,
                        yaw_rad: yaw,
                        theta_rad: prev.theta_rad + dth,
                        left_m: prev.left_m + ds - half_turn,
                        right_m: prev.right_m + ds + half_turn,
                    }
                }
            }
        };
        self.track = Some(next);
        if jumped {
            return Err(BadInputKind::Jump);
        }
        let ticks = |m: f64, per: f64| -> Result<i64, BadInputKind> {
            let t = (m / per).round();
            // i64 holds 9.2e18 ticks; a track beyond 1e15 is not a robot's.
            if t.is_finite() && t.abs() < 1e15 {
                Ok(t as i64)
            } else {
                Err(BadInputKind::Jump)
            }
        };
        Ok(robot::Odometry {
            stamp,
            x_m: x,
            y_m: y,
            theta_rad: next.theta_rad,
            left_ticks: ticks(next.left_m, self.wheels.left_m_per_tick)?,
            right_ticks: ticks(next.right_m, self.wheels.right_m_per_tick)?,
        })
    }

    /// One ROS IMU sample as our gyro.
    pub fn imu(&mut self, m: &ros::Imu) -> Result<robot::Imu, BadInputKind> {
        let (o, w, a) = (&m.orientation, &m.angular_velocity, &m.linear_acceleration);
        if !(finite(&[o.x, o.y, o.z, o.w, w.x, w.y, w.z, a.x, a.y, a.z])
            && finite(&m.orientation_covariance)
            && finite(&m.angular_velocity_covariance)
            && finite(&m.linear_acceleration_covariance))
        {
            return Err(BadInputKind::NonFinite);
        }
        let stamp = Self::stamp(&mut self.newest_imu, m.header.stamp)?;
        Ok(robot::Imu {
            stamp,
            gyro_z_rad_s: w.z,
        })
    }
}
