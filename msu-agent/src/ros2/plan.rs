//! [`Ros2Options`] validated into what the adapter uses: absolute topic
//! names, the data keys of both conventions, frames, and the liveliness
//! tokens of the node and each of its endpoints.

use ickon_proto::msg::ros::{Imu, Odometry, PoseWithCovarianceStamped, RosMessage, TfMessage};
use ickon_proto::ros::{
    EndpointKind, NodeIdentity, Qos, RosKeys, RosNameError, Transport, resolve_topic,
    validate_namespace,
};
use thiserror::Error;

use super::options::{Ros2Mode, Ros2Options};

/// The largest ROS domain id (ROS 2's documented range ends at 232).
pub const MAX_DOMAIN_ID: u32 = 232;

/// Why the ROS 2 options cannot be used.
#[derive(Debug, Error)]
pub enum Ros2ConfigError {
    /// A bad topic, namespace or frame name.
    #[error("ros2 {field}: {source}")]
    Name {
        /// Which option.
        field: &'static str,
        /// What is wrong with it.
        source: RosNameError,
    },
    /// A domain id out of range, or `ROS_DOMAIN_ID` not a number.
    #[error("ros2 domain: {0}")]
    Domain(String),
    /// A tolerance that is not a finite number of seconds in [0, 10].
    #[error("ros2 tf_tolerance_s must be between 0 and 10 s, got {0}")]
    Tolerance(f64),
}

/// A ROS 2 topic of the agent: its absolute name and data key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlannedTopic {
    /// Absolute ROS name (`/r1/pose`).
    pub name: String,
    /// The Zenoh key samples are put on (publishers) or the key expression
    /// declared (subscribers).
    pub key: String,
    /// `pkg/msg/Name`.
    pub type_name: &'static str,
    /// RIHS01 hash.
    pub type_hash: &'static str,
}

/// The agent's ROS 2 set-up, validated.
#[derive(Debug, Clone)]
pub struct Ros2Plan {
    /// Keys of the chosen convention.
    pub keys: RosKeys,
    /// Domain id (rmw_zenoh) or the one that would apply.
    pub domain: u32,
    /// Namespace (`/r1`).
    pub namespace: String,
    /// Node name.
    pub node_name: String,
    /// Fused pose publisher.
    pub pose: PlannedTopic,
    /// Raw fix publisher.
    pub fix: PlannedTopic,
    /// `map -> odom` publisher, when enabled.
    pub tf: Option<PlannedTopic>,
    /// Odometry subscriber, when inputs are read.
    pub odom: Option<PlannedTopic>,
    /// IMU subscriber, when inputs are read.
    pub imu: Option<PlannedTopic>,
    /// Fixed frame (of the pose, parent of the transform).
    pub map_frame: String,
    /// Odometry frame (child of the transform).
    pub odom_frame: String,
    /// How far ahead the transform is stamped, seconds.
    pub tf_tolerance_s: f64,
    /// Whether poses no fix has confirmed are published too.
    pub unconfirmed_poses: bool,
}

/// Publishers keep the last 10 samples (rclcpp's usual depth); `/tf` 100, as
/// tf2's broadcaster does.
const PUB_QOS: Qos = Qos::reliable(10);
const TF_QOS: Qos = Qos::reliable(100);
const SUB_QOS: Qos = Qos::reliable(10);

fn frame(field: &'static str, name: &str) -> Result<String, Ros2ConfigError> {
    // A frame id is a ROS name without the leading '/' (tf2 refuses one).
    resolve_topic("/", name)
        .map(|_| name.to_string())
        .and_then(|n| {
            if n.starts_with('/') {
                Err(RosNameError::Malformed(n))
            } else {
                Ok(n)
            }
        })
        .map_err(|source| Ros2ConfigError::Name { field, source })
}

/// The ROS domain id: the one of the options, else `ROS_DOMAIN_ID` as the
/// environment has it (`env_domain`), else 0; at most [`MAX_DOMAIN_ID`].
fn domain_id(option: Option<u32>, env_domain: Option<&str>) -> Result<u32, Ros2ConfigError> {
    let domain = match (option, env_domain.map(str::trim)) {
        (Some(d), _) => d,
        (None, Some(s)) if !s.is_empty() => s
            .parse::<u32>()
            .map_err(|_| Ros2ConfigError::Domain(format!("ROS_DOMAIN_ID={s:?} is not a number")))?,
        _ => 0,
    };
    if domain > MAX_DOMAIN_ID {
        return Err(Ros2ConfigError::Domain(format!(
            "{domain} is above {MAX_DOMAIN_ID}"
        )));
    }
    Ok(domain)
}

/// The node's namespace: the options', else `/<robot>`; checked.
fn namespace_of(options: &Ros2Options, robot: &str) -> Result<String, Ros2ConfigError> {
    let namespace = options
        .namespace
        .clone()
        .unwrap_or_else(|| format!("/{robot}"));
    validate_namespace(&namespace).map_err(|source| Ros2ConfigError::Name {
        field: "namespace",
        source,
    })?;
    Ok(namespace)
}

/// Resolves the node's topics in its namespace to Zenoh keys.
struct TopicPlanner<'a> {
    namespace: &'a str,
    keys: &'a RosKeys,
}

impl TopicPlanner<'_> {
    /// Topic `name` (the option `field`, named in errors) of type
    /// `type_name`, resolved in the namespace, with the key the node
    /// subscribes to (`subscriber`) or publishes on.
    fn topic(
        &self,
        field: &'static str,
        name: &str,
        type_name: &'static str,
        type_hash: &'static str,
        subscriber: bool,
    ) -> Result<PlannedTopic, Ros2ConfigError> {
        let err = |source| Ros2ConfigError::Name { field, source };
        let name = resolve_topic(self.namespace, name).map_err(err)?;
        let key = if subscriber {
            self.keys.subscription_key(&name)
        } else {
            self.keys.data_key(&name, type_name, type_hash)
        }
        .map_err(err)?;
        Ok(PlannedTopic {
            name,
            key,
            type_name,
            type_hash,
        })
    }
}

impl Ros2Plan {
    /// Validates `options` for robot `robot`; `env_domain` is `ROS_DOMAIN_ID`
    /// as the environment has it (read at the edge).
    pub fn new(
        options: &Ros2Options,
        robot: &str,
        env_domain: Option<&str>,
    ) -> Result<Self, Ros2ConfigError> {
        let domain = domain_id(options.domain, env_domain)?;
        let namespace = namespace_of(options, robot)?;
        // A node name is one ROS name token.
        frame("node_name", &options.node_name)?;
        if options.node_name.contains('/') {
            return Err(Ros2ConfigError::Name {
                field: "node_name",
                source: RosNameError::Malformed(options.node_name.clone()),
            });
        }
        let keys = RosKeys::new(match options.mode {
            Ros2Mode::RmwZenoh => Transport::RmwZenoh { domain },
            Ros2Mode::Bridge => Transport::Bridge {
                prefix: options.bridge_namespace.trim_matches('/').to_string(),
            },
        });
        let planner = TopicPlanner {
            namespace: &namespace,
            keys: &keys,
        };
        let topic = |field, name: &str, type_name, type_hash, subscriber| {
            planner.topic(field, name, type_name, type_hash, subscriber)
        };
        type Pose = PoseWithCovarianceStamped;
        let pose = topic(
            "pose_topic",
            &options.pose_topic,
            Pose::TYPE_NAME,
            Pose::TYPE_HASH,
            false,
        )?;
        let fix = topic(
            "fix_topic",
            &options.fix_topic,
            Pose::TYPE_NAME,
            Pose::TYPE_HASH,
            false,
        )?;
        let tf = options
            .publish_tf
            .then(|| {
                topic(
                    "tf_topic",
                    &options.tf_topic,
                    TfMessage::TYPE_NAME,
                    TfMessage::TYPE_HASH,
                    false,
                )
            })
            .transpose()?;
        let odom = options
            .inputs
            .then(|| {
                topic(
                    "odom_topic",
                    &options.odom_topic,
                    Odometry::TYPE_NAME,
                    Odometry::TYPE_HASH,
                    true,
                )
            })
            .transpose()?;
        let imu = options
            .inputs
            .then(|| {
                topic(
                    "imu_topic",
                    &options.imu_topic,
                    Imu::TYPE_NAME,
                    Imu::TYPE_HASH,
                    true,
                )
            })
            .transpose()?;
        if !(options.tf_tolerance_s.is_finite() && (0.0..=10.0).contains(&options.tf_tolerance_s)) {
            return Err(Ros2ConfigError::Tolerance(options.tf_tolerance_s));
        }
        Ok(Ros2Plan {
            keys,
            domain,
            namespace,
            node_name: options.node_name.clone(),
            pose,
            fix,
            tf,
            odom,
            imu,
            map_frame: frame("map_frame", &options.map_frame)?,
            odom_frame: frame("odom_frame", &options.odom_frame)?,
            tf_tolerance_s: options.tf_tolerance_s,
            unconfirmed_poses: options.unconfirmed_poses,
        })
    }

    /// The node's identity in session `zid` (node id 0).
    pub fn identity(&self, zid: &str) -> NodeIdentity {
        NodeIdentity {
            domain: self.domain,
            zid: zid.to_string(),
            nid: 0,
            enclave: String::new(),
            namespace: self.namespace.clone(),
            node: self.node_name.clone(),
        }
    }

    /// The liveliness tokens to declare in session `zid` (rmw_zenoh only;
    /// empty for the bridge): the node, then each publisher and subscriber
    /// with endpoint ids from 1 in the order pose, fix, tf, odom, imu.
    pub fn tokens(&self, zid: &str) -> Vec<String> {
        if !self.keys.is_rmw_zenoh() {
            return Vec::new();
        }
        let id = self.identity(zid);
        let mut out = vec![id.node_token()];
        let endpoints = [
            (Some(&self.pose), EndpointKind::Publisher, PUB_QOS),
            (Some(&self.fix), EndpointKind::Publisher, PUB_QOS),
            (self.tf.as_ref(), EndpointKind::Publisher, TF_QOS),
            (self.odom.as_ref(), EndpointKind::Subscriber, SUB_QOS),
            (self.imu.as_ref(), EndpointKind::Subscriber, SUB_QOS),
        ];
        let mut eid = 0;
        for (topic, kind, qos) in endpoints {
            let Some(t) = topic else { continue };
            eid += 1;
            // The names were validated when the plan was made.
            if let Ok(token) = id.endpoint_token(eid, kind, &t.name, t.type_name, t.type_hash, qos)
            {
                out.push(token);
            }
        }
        out
    }
}
