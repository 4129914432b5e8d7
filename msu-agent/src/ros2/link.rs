//! The Zenoh adapter of the ROS 2 side: declares the node's liveliness
//! tokens, publishers and subscribers as the [`Ros2Plan`] says, puts each
//! sample with its attachment (rmw_zenoh), and turns received samples into
//! MSU inputs through the pure [`InputDecoder`]. Bad samples are counted
//! and logged by [`BadInputLog`]; nothing here ends the agent.

use std::collections::BTreeMap;
use std::time::Instant;

use ickon_fusion::estimator::WheelGeometry;
use ickon_proto::msg::robot::{Fix, Odometry, PoseStatus, RobotPose};
use ickon_proto::ros::SampleStamper;
use ickon_proto::time::Time;
use ickon_runtime::{LogLimiter, NodeError, system_now, zerr};
use serde::Serialize;
use zenoh::Session;
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Sample;

use super::bad_input::BadInputKind;
use super::inputs::{InputDecoder, InputTopic, Ros2Input};
use super::outputs::{OdomHistory, fix_message, pose_message, tf_message};
use super::plan::{PlannedTopic, Ros2Plan};

/// Counters of the ROS 2 side, logged when the agent stops.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Ros2Counters {
    /// Odometry and IMU samples used.
    pub inputs: u64,
    /// Samples dropped as bad input (by kind in the log).
    pub bad_inputs: u64,
    /// Poses, fixes and transforms published.
    pub published: u64,
    /// Poses or fixes not published because a value was not finite.
    pub not_finite: u64,
    /// Puts that failed.
    pub failed_puts: u64,
    /// Poses (and their transforms) held back because no fix has confirmed
    /// the pose yet ([`PoseStatus::Localising`]): a ROS 2 pose has no status
    /// field, and nav2 would steer by a start pose the robot is not at.
    pub withheld_localising: u64,
}

struct RosPublisher {
    publisher: Publisher<'static>,
    stamper: SampleStamper,
    rmw: bool,
}

impl RosPublisher {
    async fn open(session: &Session, topic: &PlannedTopic, rmw: bool) -> Result<Self, NodeError> {
        let publisher = session
            .declare_publisher(topic.key.clone())
            .express(true)
            .priority(Priority::InteractiveHigh)
            .congestion_control(CongestionControl::Drop)
            .await
            .map_err(zerr)?;
        Ok(Self {
            stamper: SampleStamper::new(&topic.key),
            publisher,
            rmw,
        })
    }

    /// Encodes and puts `value`; `false` if that failed.
    async fn put<T: Serialize>(&mut self, value: &T) -> bool {
        let Ok(bytes) = ickon_proto::encode(value) else {
            return false;
        };
        let put = self.publisher.put(bytes);
        let result = if self.rmw {
            let a = self.stamper.next(system_now().as_nanos());
            put.attachment(a.to_bytes().to_vec()).await
        } else {
            put.await
        };
        match result {
            Ok(()) => true,
            Err(e) => {
                tracing::debug!("ros2 put on {} failed: {e}", self.publisher.key_expr());
                false
            }
        }
    }
}

type Sub = Subscriber<FifoChannelHandler<Sample>>;

/// The agent's ROS 2 node.
pub struct Ros2Link {
    plan: Ros2Plan,
    _tokens: Vec<LivelinessToken>,
    pose: RosPublisher,
    fix: RosPublisher,
    tf: Option<RosPublisher>,
    odom_sub: Option<Sub>,
    imu_sub: Option<Sub>,
    decoder: InputDecoder,
    log: LogLimiter<BadInputKind>,
    bad_by_kind: BTreeMap<BadInputKind, u64>,
    odom: OdomHistory,
    /// The pose stamp of the last `map -> odom` sent.
    last_tf_stamp: Option<Time>,
    counters: Ros2Counters,
}

/// Longest time between two `map -> odom` transforms without a fix, seconds
/// of pose time: well inside the 1 s the transform is stamped ahead.
pub const TF_REFRESH_S: f64 = 0.25;

impl Ros2Link {
    /// Declares the node on `session`; `wheels` is the drive geometry the
    /// odometry is converted to ticks of.
    pub async fn open(
        session: &Session,
        plan: Ros2Plan,
        wheels: WheelGeometry,
    ) -> Result<Self, NodeError> {
        let rmw = plan.keys.is_rmw_zenoh();
        let mut tokens = Vec::new();
        for t in plan.tokens(&session.zid().to_string()) {
            tokens.push(session.liveliness().declare_token(t).await.map_err(zerr)?);
        }
        let pose = RosPublisher::open(session, &plan.pose, rmw).await?;
        let fix = RosPublisher::open(session, &plan.fix, rmw).await?;
        let tf = match &plan.tf {
            Some(t) => Some(RosPublisher::open(session, t, rmw).await?),
            None => None,
        };
        let subscribe = async |t: &Option<PlannedTopic>| -> Result<Option<Sub>, NodeError> {
            match t {
                Some(t) => Ok(Some(
                    session
                        .declare_subscriber(t.key.clone())
                        .await
                        .map_err(zerr)?,
                )),
                None => Ok(None),
            }
        };
        let odom_sub = subscribe(&plan.odom).await?;
        let imu_sub = subscribe(&plan.imu).await?;
        tracing::info!(
            "ros2: node {}/{} ({}), pose on {}",
            plan.namespace,
            plan.node_name,
            if rmw {
                "rmw_zenoh"
            } else {
                "zenoh-bridge-ros2dds"
            },
            plan.pose.key
        );
        Ok(Self {
            decoder: InputDecoder::new(plan.keys.clone(), wheels),
            plan,
            _tokens: tokens,
            pose,
            fix,
            tf,
            odom_sub,
            imu_sub,
            log: LogLimiter::default(),
            bad_by_kind: BTreeMap::new(),
            odom: OdomHistory::default(),
            last_tf_stamp: None,
            counters: Ros2Counters::default(),
        })
    }

    /// The next usable odometry or IMU sample; bad ones are counted, logged
    /// and skipped. Cancel-safe: a sample is taken and handled without an
    /// await in between. Never completes without subscribers.
    pub async fn recv(&mut self) -> Ros2Input {
        loop {
            let (topic, sample) = tokio::select! {
                Some(Ok(s)) = recv_opt(&self.odom_sub) => (InputTopic::Odom, s),
                Some(Ok(s)) = recv_opt(&self.imu_sub) => (InputTopic::Imu, s),
                else => std::future::pending().await,
            };
            let attachment = sample.attachment().map(|a| a.to_bytes());
            let key = sample.key_expr().as_str();
            match self.decoder.decode(
                topic,
                key,
                &sample.payload().to_bytes(),
                attachment.as_deref(),
            ) {
                Ok(input) => {
                    self.counters.inputs += 1;
                    return input;
                }
                Err(kind) => {
                    self.counters.bad_inputs += 1;
                    let count = self.bad_by_kind.entry(kind).or_default();
                    *count += 1;
                    if let Some(held) = self.log.admit(kind, Instant::now()) {
                        tracing::warn!(
                            "ros2 {key}: dropped: {} ({held} more since the last report; {count} so far)",
                            kind.describe()
                        );
                    }
                }
            }
        }
    }

    /// Notes an odometry sample the core accepted (for `map -> odom`).
    pub fn note_odometry(&mut self, odom: &Odometry) {
        self.odom.push(odom);
    }

    /// Publishes the fused pose and, when enabled, `map -> odom`: with a
    /// pose that has just absorbed a fix (`absorbed_fix`), or when the last
    /// transform is [`TF_REFRESH_S`] older than the pose. Between fixes the
    /// pose moves with the odometry and `map -> odom` stays as it was, so
    /// sending it with every odometry-rate pose would only add work (AMCL
    /// too sends it per scan, not per odometry sample).
    pub async fn publish_pose(&mut self, pose: &RobotPose, absorbed_fix: bool) {
        if pose.status == PoseStatus::Localising && !self.plan.unconfirmed_poses {
            self.counters.withheld_localising += 1;
            return;
        }
        let Some(msg) = pose_message(pose, &self.plan.map_frame) else {
            self.counters.not_finite += 1;
            return;
        };
        let ok = self.pose.put(&msg).await;
        self.count(ok);
        let due = absorbed_fix
            || self.last_tf_stamp.is_none_or(|t| {
                pose.stamp.since(t).as_secs_f64() >= TF_REFRESH_S || pose.stamp < t
            });
        if !due {
            return;
        }
        let tf = tf_message(
            pose,
            &self.odom,
            &self.plan.map_frame,
            &self.plan.odom_frame,
            self.plan.tf_tolerance_s,
        );
        if let (Some(publisher), Some(msg)) = (self.tf.as_mut(), tf) {
            let ok = publisher.put(&msg).await;
            self.count(ok);
            self.last_tf_stamp = Some(pose.stamp);
        }
    }

    /// Publishes the raw fix.
    pub async fn publish_fix(&mut self, fix: &Fix) {
        let Some(msg) = fix_message(fix, &self.plan.map_frame) else {
            self.counters.not_finite += 1;
            return;
        };
        let ok = self.fix.put(&msg).await;
        self.count(ok);
    }

    fn count(&mut self, ok: bool) {
        if ok {
            self.counters.published += 1;
        } else {
            self.counters.failed_puts += 1;
        }
    }

    /// The counters so far.
    pub fn counters(&self) -> Ros2Counters {
        self.counters
    }

    /// Bad input seen, by kind.
    pub fn bad_input(&self) -> &BTreeMap<BadInputKind, u64> {
        &self.bad_by_kind
    }
}

async fn recv_opt(sub: &Option<Sub>) -> Option<zenoh::Result<Sample>> {
    match sub {
        Some(s) => Some(s.recv_async().await),
        None => std::future::pending().await,
    }
}

/// The next input of `link`, or never without one: for a `select!` branch.
pub async fn next_input(link: &mut Option<Ros2Link>) -> Ros2Input {
    match link {
        Some(l) => l.recv().await,
        None => std::future::pending().await,
    }
}
