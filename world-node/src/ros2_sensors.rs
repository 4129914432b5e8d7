//! The simulated robots' odometry and gyro as ROS 2 topics (`ickon sim
//! --ros2`): each robot is a node `sim_robot` in namespace `/<robot id>`
//! publishing `nav_msgs/msg/Odometry` on `/<robot>/odom` and
//! `sensor_msgs/msg/Imu` on `/<robot>/imu` the way rmw_zenoh does (domain 0:
//! typed keys, the attachment on every sample, liveliness tokens), so that
//! the MSU agents read them through their ROS 2 side, as on a ROS 2 robot.

use ickon_proto::encode;
use ickon_proto::msg::robot::{Imu, Odometry};
use ickon_proto::msg::ros::{self, RosMessage};
use ickon_proto::ros::{
    EndpointKind, NodeIdentity, Qos, RosKeys, SampleStamper, Transport, resolve_topic,
};
use ickon_proto::time::Time;
use ickon_runtime::{NodeError, system_now, zerr};
use zenoh::Session;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;

/// The domain the simulated robots use (ROS 2's default).
const DOMAIN: u32 = 0;
/// Variances published with the odometry: x, y (m^2) and yaw (rad^2) of a
/// wheeled robot's dead reckoning over a few metres, forward speed and turn
/// rate; nominal (the MSU does not read them), never zeros.
const POSE_VARIANCE: [f64; 3] = [1e-3, 1e-3, 3e-3];
const TWIST_VARIANCE: [f64; 2] = [1e-4, 1e-4];
/// The gyro's rate variance, (rad/s)^2, nominal.
const GYRO_VARIANCE: f64 = 1e-5;

fn name_err(e: impl std::fmt::Display) -> NodeError {
    NodeError::Setup(format!("ros2 name: {e}"))
}

/// One robot's ROS 2 sensor publishers.
pub struct RosSensorPublishers {
    odom: Publisher<'static>,
    imu: Publisher<'static>,
    odom_stamper: SampleStamper,
    imu_stamper: SampleStamper,
    previous: Option<(Time, [f64; 3])>,
    _tokens: Vec<LivelinessToken>,
}

impl RosSensorPublishers {
    /// Declares robot `robot`'s node (node id `nid` in this session), its
    /// two publishers and their tokens.
    pub async fn open(session: &Session, robot: &str, nid: u32) -> Result<Self, NodeError> {
        let keys = RosKeys::new(Transport::RmwZenoh { domain: DOMAIN });
        let namespace = format!("/{robot}");
        let odom_topic = resolve_topic(&namespace, "odom").map_err(name_err)?;
        let imu_topic = resolve_topic(&namespace, "imu").map_err(name_err)?;
        let odom_key = keys
            .data_key(
                &odom_topic,
                ros::Odometry::TYPE_NAME,
                ros::Odometry::TYPE_HASH,
            )
            .map_err(name_err)?;
        let imu_key = keys
            .data_key(&imu_topic, ros::Imu::TYPE_NAME, ros::Imu::TYPE_HASH)
            .map_err(name_err)?;
        let id = NodeIdentity {
            domain: DOMAIN,
            zid: session.zid().to_string(),
            // One session carries every robot's node: each its own node id.
            nid,
            enclave: String::new(),
            namespace,
            node: "sim_robot".into(),
        };
        let qos = Qos::reliable(10);
        let token_names = [
            id.node_token(),
            id.endpoint_token(
                1,
                EndpointKind::Publisher,
                &odom_topic,
                ros::Odometry::TYPE_NAME,
                ros::Odometry::TYPE_HASH,
                qos,
            )
            .map_err(name_err)?,
            id.endpoint_token(
                2,
                EndpointKind::Publisher,
                &imu_topic,
                ros::Imu::TYPE_NAME,
                ros::Imu::TYPE_HASH,
                qos,
            )
            .map_err(name_err)?,
        ];
        let mut tokens = Vec::new();
        for t in token_names {
            tokens.push(session.liveliness().declare_token(t).await.map_err(zerr)?);
        }
        let publisher = |key: String| session.declare_publisher(key).express(true);
        Ok(Self {
            odom_stamper: SampleStamper::new(&odom_key),
            imu_stamper: SampleStamper::new(&imu_key),
            odom: publisher(odom_key).await.map_err(zerr)?,
            imu: publisher(imu_key).await.map_err(zerr)?,
            previous: None,
            _tokens: tokens,
        })
    }

    /// Publishes one odometry sample; the twist is the motion since the
    /// previous one.
    pub async fn odometry(&mut self, m: &Odometry) -> Result<(), NodeError> {
        let pose = [m.x_m, m.y_m, m.theta_rad];
        let twist = match self.previous {
            Some((t, p)) if m.stamp > t => {
                let dt = m.stamp.since(t).as_secs_f64();
                let (dx, dy) = (pose[0] - p[0], pose[1] - p[1]);
                let mid = 0.5 * (pose[2] + p[2]);
                [
                    (dx * mid.cos() + dy * mid.sin()) / dt,
                    (pose[2] - p[2]) / dt,
                ]
            }
            _ => [0.0, 0.0],
        };
        self.previous = Some((m.stamp, pose));
        let msg = ros::Odometry::planar(
            m.stamp,
            "odom",
            "base_link",
            pose,
            twist,
            POSE_VARIANCE,
            TWIST_VARIANCE,
        );
        let attachment = self.odom_stamper.next(system_now().as_nanos()).to_bytes();
        self.odom
            .put(encode(&msg)?)
            .attachment(attachment.to_vec())
            .await
            .map_err(zerr)
    }

    /// Publishes one gyro sample.
    pub async fn imu(&mut self, m: &Imu) -> Result<(), NodeError> {
        let msg = ros::Imu::from_gyro_z(m.stamp, "imu_link", m.gyro_z_rad_s, GYRO_VARIANCE);
        let attachment = self.imu_stamper.next(system_now().as_nanos()).to_bytes();
        self.imu
            .put(encode(&msg)?)
            .attachment(attachment.to_vec())
            .await
            .map_err(zerr)
    }
}
