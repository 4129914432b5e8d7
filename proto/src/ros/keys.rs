//! The Zenoh keys of ROS 2 topics under both conventions, and rmw_zenoh's
//! liveliness tokens (what `ros2 node list` and `ros2 topic list` read).
//!
//! - rmw_zenoh data key: `<domain>/<topic without outer '/'>/<dds type>/<hash>`,
//!   e.g. `0/r1/pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/RIHS01_2643…`.
//! - `zenoh-bridge-ros2dds` data key: `[<bridge namespace>/]<topic without
//!   outer '/'>`, e.g. `r1/pose`; no type, no hash, no attachment.
//! - Liveliness tokens (rmw_zenoh only), every name with `/` replaced by `%`
//!   and an empty one written `%`:
//!   node `@ros2_lv/<domain>/<zid>/<nid>/<nid>/NN/<enclave>/<namespace>/<node>`,
//!   publisher `@ros2_lv/<domain>/<zid>/<nid>/<eid>/MP/<enclave>/<namespace>/<node>/<topic>/<type>/<hash>/<qos>`,
//!   subscriber the same with `MS`.

use super::names::{RosNameError, dds_type_name};

/// How ROS 2 topics map to Zenoh keys.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Transport {
    /// rmw_zenoh: keys with the domain, the type and its hash; attachment and
    /// liveliness tokens.
    RmwZenoh {
        /// The ROS domain id.
        domain: u32,
    },
    /// `zenoh-bridge-ros2dds`: the topic name only, under the bridge's
    /// namespace (empty: none).
    Bridge {
        /// The bridge's `namespace` setting, without outer `/` (may be empty).
        prefix: String,
    },
}

/// The data keys of topics under one [`Transport`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RosKeys {
    transport: Transport,
}

impl RosKeys {
    /// Keys under `transport`.
    pub fn new(transport: Transport) -> Self {
        Self { transport }
    }

    /// The transport.
    pub fn transport(&self) -> &Transport {
        &self.transport
    }

    /// Whether samples carry the rmw_zenoh attachment and nodes declare tokens.
    pub fn is_rmw_zenoh(&self) -> bool {
        matches!(self.transport, Transport::RmwZenoh { .. })
    }

    /// The data key of `topic` (absolute, resolved) carrying `type_name`
    /// (`pkg/msg/Name`) with hash `type_hash`.
    pub fn data_key(
        &self,
        topic: &str,
        type_name: &str,
        type_hash: &str,
    ) -> Result<String, RosNameError> {
        let bare = topic.trim_matches('/');
        if bare.is_empty() {
            return Err(RosNameError::Empty);
        }
        Ok(match &self.transport {
            Transport::RmwZenoh { domain } => {
                format!("{domain}/{bare}/{}/{type_hash}", dds_type_name(type_name)?)
            }
            Transport::Bridge { prefix } => {
                let prefix = prefix.trim_matches('/');
                if prefix.is_empty() {
                    bare.to_string()
                } else {
                    format!("{prefix}/{bare}")
                }
            }
        })
    }

    /// What a subscriber to `topic` declares: under rmw_zenoh any type and
    /// hash (`<domain>/<topic>/*/*`), so that a publisher of the wrong type
    /// is seen, counted and refused rather than silently missed.
    pub fn subscription_key(&self, topic: &str) -> Result<String, RosNameError> {
        let bare = topic.trim_matches('/');
        if bare.is_empty() {
            return Err(RosNameError::Empty);
        }
        Ok(match &self.transport {
            Transport::RmwZenoh { domain } => format!("{domain}/{bare}/*/*"),
            Transport::Bridge { .. } => self.data_key(topic, "x/msg/X", "")?,
        })
    }
}

/// The type and hash at the end of an rmw_zenoh data key
/// (`<domain>/<topic>/<dds type>/<hash>`), `None` when there are none.
pub fn split_type_and_hash(key: &str) -> Option<(&str, &str)> {
    let mut it = key.rsplitn(3, '/');
    let hash = it.next()?;
    let dds_type = it.next()?;
    it.next()?;
    Some((dds_type, hash))
}

/// A name in a liveliness token: `/` replaced by `%`, empty written `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".to_string()
    } else {
        name.replace('/', "%")
    }
}

/// A topic's QoS as rmw_zenoh writes it in a token.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// RELIABLE (true) or BEST_EFFORT.
    pub reliable: bool,
    /// TRANSIENT_LOCAL (true) or VOLATILE.
    pub transient_local: bool,
    /// KEEP_LAST depth.
    pub depth: u32,
}

/// rmw_zenoh's default depth, left out of a token.
const DEFAULT_DEPTH: u32 = 42;

impl Qos {
    /// Reliable, volatile, keep last `depth`: what publishers of poses and
    /// subscribers of sensor streams use.
    pub const fn reliable(depth: u32) -> Self {
        Qos {
            reliable: true,
            transient_local: false,
            depth,
        }
    }

    /// `rel:dur:hist,depth:dl_s,dl_ns:ls_s,ls_ns:liv,lease_s,lease_ns`, a
    /// field empty where it is rmw_zenoh's default (RELIABLE, VOLATILE,
    /// KEEP_LAST, depth 42, infinite deadline, lifespan and lease).
    pub fn token_string(&self) -> String {
        let rel = if self.reliable { "" } else { "2" };
        let dur = if self.transient_local { "1" } else { "" };
        let depth = if self.depth == DEFAULT_DEPTH {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!("{rel}:{dur}:,{depth}:,:,:,,")
    }
}

/// Who a node is, for its liveliness tokens.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeIdentity {
    /// The ROS domain id.
    pub domain: u32,
    /// The Zenoh session id, as the session prints it.
    pub zid: String,
    /// The node's id within the session.
    pub nid: u32,
    /// The security enclave (empty: none).
    pub enclave: String,
    /// The namespace (`/r1`, or `/`).
    pub namespace: String,
    /// The node name (`ickon_msu`).
    pub node: String,
}

/// A topic endpoint's kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndpointKind {
    /// `MP`.
    Publisher,
    /// `MS`.
    Subscriber,
}

impl NodeIdentity {
    fn namespace_token(&self) -> String {
        // The root namespace "/" is an empty namespace in a token.
        mangle(if self.namespace == "/" {
            ""
        } else {
            &self.namespace
        })
    }

    /// The node's token.
    pub fn node_token(&self) -> String {
        format!(
            "@ros2_lv/{}/{}/{}/{}/NN/{}/{}/{}",
            self.domain,
            self.zid,
            self.nid,
            self.nid,
            mangle(&self.enclave),
            self.namespace_token(),
            mangle(&self.node)
        )
    }

    /// The token of endpoint `eid` of this node on `topic` (absolute).
    pub fn endpoint_token(
        &self,
        eid: u32,
        kind: EndpointKind,
        topic: &str,
        type_name: &str,
        type_hash: &str,
        qos: Qos,
    ) -> Result<String, RosNameError> {
        let kind = match kind {
            EndpointKind::Publisher => "MP",
            EndpointKind::Subscriber => "MS",
        };
        Ok(format!(
            "@ros2_lv/{}/{}/{}/{eid}/{kind}/{}/{}/{}/{}/{}/{type_hash}/{}",
            self.domain,
            self.zid,
            self.nid,
            mangle(&self.enclave),
            self.namespace_token(),
            mangle(&self.node),
            mangle(topic),
            dds_type_name(type_name)?,
            qos.token_string()
        ))
    }
}
