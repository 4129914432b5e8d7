//! The MSU agent as a Zenoh node: fetches the site and the schedule from the
//! central unit, follows schedule changes, feeds its robot's messages to an
//! [`MsuCore`], and publishes fixes and poses. The core does the work; this
//! module only moves bytes.

use std::future::Future;
use std::process::ExitCode;
use std::time::Duration;

use clap::Args;

use ickon_fusion::estimator::{self, EstimatorConfig, WheelGeometry};
use ickon_proto::decode;
use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::control::{Schedule, SiteInfo};
use ickon_proto::msg::robot::{Imu, ObstacleRanges, Odometry};
use ickon_proto::site::Site;
use ickon_runtime::{NodeArgs, NodeError, fetch, put_counted, zerr};
use zenoh::Session;
use zenoh::qos::{CongestionControl, Priority};

use crate::receivers::{ReceiverKind, ReceiverSource};
use crate::ros2::{Ros2Input, Ros2Link, Ros2Options, Ros2Plan};
use crate::{MsuConfig, MsuCore};

/// How often the site and schedule are asked for until the central unit answers.
const FETCH_RETRY: Duration = Duration::from_millis(500);

/// What an MSU agent needs besides its session.
#[derive(Debug, Clone)]
pub struct MsuSettings {
    /// Site name (the `<site>` of every key).
    pub site_name: String,
    /// Robot id.
    pub robot: String,
    /// Estimator configuration (name and parameters); `None`: the registry
    /// defaults of `estimator_name`, starting at the robot's start pose.
    pub estimator: Option<EstimatorConfig>,
    /// Estimator name, used when `estimator` is `None`.
    pub estimator_name: String,
    /// One-sigma timing noise of one arrival, seconds.
    pub timing_sigma_s: f64,
    /// The robot's nominal drive geometry.
    pub wheels: WheelGeometry,
    /// Where the arrivals come from.
    pub receivers: ReceiverKind,
    /// The ROS 2 side, when enabled (validated).
    pub ros2: Option<Ros2Plan>,
}

/// Counters of one agent's run, logged at the end.
#[derive(Debug, Default, Clone, Copy)]
pub struct MsuCounters {
    /// Arrival messages received.
    pub arrival_messages: u64,
    /// Fixes published.
    pub fixes: u64,
    /// Poses published.
    pub poses: u64,
    /// Messages that could not be decoded (dropped).
    pub bad_messages: u64,
    /// Inputs the core or the estimator refused (dropped).
    pub refused_inputs: u64,
    /// Fixes and poses that could not be published (logged at debug level).
    pub failed_puts: u64,
}

/// Runs the agent until `shutdown` completes; returns its counters.
pub async fn run(
    session: &Session,
    settings: MsuSettings,
    shutdown: impl Future<Output = ()>,
) -> Result<MsuCounters, NodeError> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&settings.site_name)?;
    let robot = settings.robot.as_str();
    let _token = session
        .liveliness()
        .declare_token(keys.alive_robot(robot)?)
        .await
        .map_err(zerr)?;

    let Some(info) = fetch::<SiteInfo>(
        session,
        &keys.central_site(),
        None,
        FETCH_RETRY,
        &mut shutdown,
    )
    .await?
    else {
        return Ok(MsuCounters::default());
    };
    let site = Site::from_toml(&info.site_toml, "<site from the central unit>")?;
    let spec = site.robots.iter().find(|r| r.id == robot).ok_or_else(|| {
        NodeError::Setup(format!("robot {robot:?} is not in site {:?}", site.name))
    })?;
    let config = match settings.estimator.clone() {
        Some(c) => c,
        None => crate::estimator_for_site(&settings.estimator_name, &site, spec.start)
            .map_err(|e| NodeError::Setup(e.to_string()))?,
    };
    let estimator = estimator::build(&config).map_err(|e| NodeError::Setup(e.to_string()))?;
    let mut core = MsuCore::new(
        MsuConfig::for_site(&site, settings.timing_sigma_s, settings.wheels),
        estimator,
    );
    let schedule_sub = session
        .declare_subscriber(keys.central_schedule())
        .await
        .map_err(zerr)?;
    let Some(schedule) = fetch::<Schedule>(
        session,
        &keys.central_schedule(),
        None,
        FETCH_RETRY,
        &mut shutdown,
    )
    .await?
    else {
        return Ok(MsuCounters::default());
    };
    tracing::info!(
        "robot {robot}: site {:?} v{}, schedule v{}, estimator {}",
        site.name,
        info.version,
        schedule.version,
        core.estimator_name()
    );
    core.set_schedule(schedule);

    let sub = |topic| keys.robot(robot, topic);
    let receivers = ReceiverSource::open(settings.receivers, session, &keys, robot).await?;
    let odom = session
        .declare_subscriber(sub(RobotTopic::Odom)?)
        .await
        .map_err(zerr)?;
    let imu = session
        .declare_subscriber(sub(RobotTopic::Imu)?)
        .await
        .map_err(zerr)?;
    let range = session
        .declare_subscriber(sub(RobotTopic::Range)?)
        .await
        .map_err(zerr)?;
    let fix_pub = session
        .declare_publisher(sub(RobotTopic::Fix)?)
        .express(true)
        .priority(Priority::InteractiveHigh)
        .await
        .map_err(zerr)?;
    let pose_pub = session
        .declare_publisher(sub(RobotTopic::Pose)?)
        .express(true)
        .priority(Priority::InteractiveHigh)
        .congestion_control(CongestionControl::Drop)
        .await
        .map_err(zerr)?;

    let mut ros = match settings.ros2.clone() {
        Some(plan) => Some(Ros2Link::open(session, plan, settings.wheels).await?),
        None => None,
    };

    let mut n = MsuCounters::default();
    // Every pose goes out on our key and, with --ros2, on ROS 2.
    macro_rules! publish_pose {
        ($pose:expr) => {{
            let pose = $pose;
            if !put_counted(&pose_pub, &pose).await {
                n.failed_puts += 1;
            }
            n.poses += 1;
            if let Some(r) = ros.as_mut() {
                r.publish_pose(&pose).await;
            }
        }};
    }
    // Odometry from our key or from ROS 2: the same handling.
    macro_rules! on_odometry {
        ($msg:expr) => {{
            let msg = $msg;
            match core.on_odometry(&msg) {
                Ok(()) => {
                    if let Some(r) = ros.as_mut() {
                        r.note_odometry(&msg);
                    }
                    if let Some(pose) = core.pose() {
                        publish_pose!(pose);
                    }
                }
                Err(e) => {
                    n.refused_inputs += 1;
                    tracing::debug!("robot {robot}: odometry refused: {e}");
                }
            }
        }};
    }
    macro_rules! decoded {
        ($sample:expr, $t:ty) => {
            match decode::<$t>(&$sample.payload().to_bytes()) {
                Ok(v) => Some(v),
                Err(e) => {
                    n.bad_messages += 1;
                    tracing::debug!("dropped undecodable {}: {e}", $sample.key_expr());
                    None
                }
            }
        };
    }
    loop {
        tokio::select! {
            _ = &mut shutdown => break,
            Ok(s) = schedule_sub.recv_async() => {
                if let Some(schedule) = decoded!(s, Schedule) {
                    tracing::info!("robot {robot}: schedule v{} from cycle {}", schedule.version, schedule.effective_cycle);
                    core.set_schedule(schedule);
                }
            }
            Some(received) = receivers.recv() => {
                let msg = match received {
                    Ok(msg) => Some(msg),
                    Err(e) => {
                        n.bad_messages += 1;
                        tracing::debug!("robot {robot}: dropped undecodable arrivals: {e}");
                        None
                    }
                };
                if let Some(msg) = msg {
                    n.arrival_messages += 1;
                    match core.on_arrivals(&msg) {
                        Ok(Some(fix)) => {
                            if !put_counted(&fix_pub, &fix).await { n.failed_puts += 1; }
                            n.fixes += 1;
                            // Publish the pose that absorbed the fix at once:
                            // this is the latency a user of the pose sees.
                            if let Some(pose) = core.pose() { publish_pose!(pose); }
                            if let Some(r) = ros.as_mut() { r.publish_fix(&fix).await; }
                        }
                        Ok(None) => {}
                        Err(e) => {
                            n.refused_inputs += 1;
                            tracing::debug!("robot {robot}: cycle {} not used: {e}", msg.seq);
                        }
                    }
                }
            }
            Ok(s) = odom.recv_async() => {
                if let Some(msg) = decoded!(s, Odometry) { on_odometry!(msg); }
            }
            input = crate::ros2::next_input(&mut ros) => match input {
                Ros2Input::Odometry(msg) => on_odometry!(msg),
                Ros2Input::Imu(msg) => {
                    if core.on_imu(&msg).is_err() { n.refused_inputs += 1; }
                }
            },
            Ok(s) = imu.recv_async() => {
                if let Some(msg) = decoded!(s, Imu) {
                    if core.on_imu(&msg).is_err() {
                        n.refused_inputs += 1;
                    }
                }
            }
            Ok(s) = range.recv_async() => {
                if let Some(msg) = decoded!(s, ObstacleRanges) {
                    if core.on_range(&msg).is_err() {
                        n.refused_inputs += 1;
                    }
                }
            }
        }
    }
    tracing::info!("robot {robot}: stopping: {n:?}");
    if let Some(r) = &ros {
        tracing::info!("robot {robot}: ros2: {:?}", r.counters());
    }
    Ok(n)
}

/// Metres per encoder tick of a Pioneer 3-DX (wheel radius 0.0975 m, 500
/// lines x 38.3 gear per wheel turn): the default drive of the site's robots.
pub const PIONEER_M_PER_TICK: f64 = 2.0 * std::f64::consts::PI * 0.0975 / (500.0 * 38.3);

/// Arguments of `ickon-msu` (and `ickon node msu`).
#[derive(Debug, Clone, Args)]
pub struct MsuArgs {
    /// Connection and simulation flags.
    #[command(flatten)]
    pub mesh: NodeArgs,
    /// The robot this agent serves.
    #[arg(long)]
    pub robot: String,
    /// Estimator name (`tdoa-ekf`, ours and the most accurate; the seeds'
    /// `odometry`, `msu-raw`, `ickon-akf`, `gyro-ckf`, `cda`, `cda-msu`).
    #[arg(long, default_value = "tdoa-ekf")]
    pub estimator: String,
    /// Estimator configuration as JSON (`{"name": "...", ...}`); overrides `--estimator`.
    #[arg(long)]
    pub estimator_json: Option<String>,
    /// One-sigma timing noise of one arrival, microseconds (the MSU's data sheet).
    #[arg(long, default_value_t = 50.0)]
    pub timing_sigma_us: f64,
    /// Wheel base of the robot, metres.
    #[arg(long, default_value_t = 0.33)]
    pub wheel_base_m: f64,
    /// Where the arrivals come from.
    #[arg(long, value_enum, default_value_t = ReceiverKind::Sim)]
    pub receivers: ReceiverKind,
    /// Distance per encoder tick, metres (a Pioneer 3-DX by default).
    #[arg(long, default_value_t = PIONEER_M_PER_TICK)]
    pub m_per_tick: f64,
    /// The ROS 2 side (`--ros2` and `--ros2-*`); boxed, as it is most of
    /// the arguments' size.
    #[command(flatten)]
    pub ros2: Box<Ros2Options>,
}

/// Runs an MSU agent as a process until Ctrl-C/SIGTERM. Exit code 2 for bad
/// arguments, 1 for a failure at run time.
pub fn main_with(args: MsuArgs) -> ExitCode {
    let estimator = match &args.estimator_json {
        Some(json) => match serde_json::from_str::<EstimatorConfig>(json) {
            Ok(c) => Some(c),
            Err(e) => {
                eprintln!("error: --estimator-json: {e}");
                return ExitCode::from(2);
            }
        },
        None => match EstimatorConfig::default_for(&args.estimator) {
            Ok(_) => None,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        },
    };
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(args.timing_sigma_us) && positive(args.wheel_base_m) && positive(args.m_per_tick))
    {
        eprintln!(
            "error: --timing-sigma-us, --wheel-base-m and --m-per-tick must be positive numbers"
        );
        return ExitCode::from(2);
    }
    let ros2 = if args.ros2.enabled {
        let env_domain = std::env::var("ROS_DOMAIN_ID").ok();
        match Ros2Plan::new(&args.ros2, &args.robot, env_domain.as_deref()) {
            Ok(plan) => Some(plan),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        }
    } else {
        None
    };
    let settings = MsuSettings {
        site_name: args.mesh.site_name.clone(),
        robot: args.robot.clone(),
        estimator,
        estimator_name: args.estimator.clone(),
        timing_sigma_s: args.timing_sigma_us * 1e-6,
        wheels: WheelGeometry {
            wheel_base_m: args.wheel_base_m,
            left_m_per_tick: args.m_per_tick,
            right_m_per_tick: args.m_per_tick,
        },
        receivers: args.receivers,
        ros2,
    };
    ickon_runtime::run_node(2, async {
        let session = args.mesh.open().await?;
        let r = run(&session, settings, args.mesh.shutdown()).await;
        let _ = session.close().await;
        r
    })
}
