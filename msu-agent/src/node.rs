//! The MSU agent as a Zenoh node: fetches the site and the schedule from the
//! central unit, follows schedule changes, feeds its robot's messages to an
//! [`MsuCore`], and publishes fixes and poses. The core does the work; this
//! module only moves bytes.

use std::future::Future;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use clap::Args;

use ickon_fusion::estimator;
use ickon_proto::keys::{Key, Keys, RobotTopic};
use ickon_proto::msg::control::{CellStatus, CycleTrigger, Schedule, SurveyCalibration};
use ickon_proto::msg::robot::{Imu, MsuStatus, ObstacleRanges, Odometry, UltrasoundArrivals};
use ickon_proto::{DecodeError, decode};
use ickon_runtime::{JoinedSite, LogLimiter, NodeArgs, NodeError, SiteJoin, put_counted, zerr};
use zenoh::Session;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Sample;

use crate::hedgehog::HedgehogInput;
use crate::marvelmind_receivers::RangingSite;
use crate::receivers::{ReceiverInput, ReceiverKind, ReceiverSource, SourceContext};
use crate::ros2::{Ros2Input, Ros2Link, Ros2Options, Ros2Plan};
use crate::summary::SummaryMaker;
use crate::{Event, InputKind, MsuCore, MsuTuning, Output};

/// What an MSU agent needs besides its session.
#[derive(Debug, Clone)]
pub struct MsuSettings {
    /// Site name (the `<site>` of every key).
    pub site_name: String,
    /// Robot id.
    pub robot: String,
    /// The estimator, the solver's noise and gates, and the drive geometry
    /// (a configuration file's, or one estimator's defaults); the site
    /// fetched from the central unit fills in the rest.
    pub tuning: MsuTuning,
    /// Where the arrivals come from.
    pub receivers: ReceiverKind,
    /// The agent's clock (the time base of a receiver board's arrivals).
    pub clock: ickon_runtime::SimulatedClock,
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
    /// Inputs dropped because the input queue was full (the core fell behind).
    pub queue_full: u64,
    /// Odometry and gyro samples from Zenoh dropped because the receiver
    /// board reports the robot's own (one source each, on one clock).
    pub motion_from_board_only: u64,
}

/// Inputs the agent's queue holds (seconds of a robot's sensor stream).
const INPUT_QUEUE: usize = 4096;

/// One input as it arrived, decoded in the receiving callback.
enum Arrived {
    Arrivals(Result<UltrasoundArrivals, DecodeError>),
    Odometry(Result<Odometry, DecodeError>),
    Imu(Result<Imu, DecodeError>),
    Range(Result<ObstacleRanges, DecodeError>),
    Schedule(Result<Schedule, DecodeError>),
    Trigger(Result<CycleTrigger, DecodeError>),
    /// With the key it came under (a cell may speak only under its own).
    CellStatus(String, Result<CellStatus, DecodeError>),
    Survey(Result<SurveyCalibration, DecodeError>),
    /// A ranging kit's distances or position.
    Ranging(HedgehogInput),
    /// Wheel ticks from the receiver board.
    BoardOdometry(Odometry),
    /// A gyro sample from the receiver board.
    BoardImu(Imu),
}

impl Arrived {
    /// The core's event, or what could not be decoded (with its kind, for
    /// the rate-limited log). A cell status is checked against its key by
    /// the caller.
    fn into_event(self) -> Result<Event, (&'static str, String)> {
        let bad = |kind: &'static str| move |e: DecodeError| (kind, e.to_string());
        Ok(match self {
            Arrived::Arrivals(r) => Event::Arrivals(r.map_err(bad("undecodable arrivals"))?),
            Arrived::Odometry(r) => Event::Odometry(r.map_err(bad("undecodable odometry"))?),
            Arrived::Imu(r) => Event::Imu(r.map_err(bad("undecodable imu"))?),
            Arrived::Range(r) => Event::Range(r.map_err(bad("undecodable ranges"))?),
            Arrived::Schedule(r) => Event::Schedule(r.map_err(bad("undecodable schedule"))?),
            Arrived::Trigger(r) => Event::Trigger(r.map_err(bad("undecodable cycle trigger"))?),
            Arrived::CellStatus(key, r) => {
                let status = r.map_err(|e| ("undecodable cell status", format!("{key}: {e}")))?;
                Event::CellStatus(status)
            }
            Arrived::Survey(r) => Event::Survey(r.map_err(bad("undecodable survey calibration"))?),
            Arrived::Ranging(HedgehogInput::Distances(d)) => Event::BeaconDistances(d),
            Arrived::Ranging(HedgehogInput::KitPosition(p)) => Event::KitPosition(p),
            Arrived::Ranging(HedgehogInput::Gyro(i)) => Event::Imu(i),
            Arrived::BoardOdometry(o) => Event::Odometry(o),
            Arrived::BoardImu(i) => Event::Imu(i),
        })
    }
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
    let join = SiteJoin::new(session, &keys);
    let _token = join.announce(keys.alive_robot(robot)?).await?;
    let Some(JoinedSite { info, site }) = join.site(&mut shutdown).await? else {
        return Ok(MsuCounters::default());
    };
    let config = settings
        .tuning
        .estimator_for_robot(&site, robot)
        .map_err(|e| NodeError::Setup(e.to_string()))?;
    let estimator = estimator::build(&config).map_err(|e| NodeError::Setup(e.to_string()))?;
    let msu_config = settings.tuning.msu_config(&site);
    let ranging_site = RangingSite {
        speed_of_sound_m_s: msu_config.speed_of_sound_m_s,
        beacons: msu_config.transmitters.clone(),
    };
    let mut core = MsuCore::new(msu_config, estimator);
    // Every input, the central unit's and the cells' as well as the
    // robot's, goes through one queue in the order the session received
    // it, so that the core sees one defined order: the order a recorder of
    // the site stores them in (the central unit's messages reach every
    // subscriber in the order it sent them, and the robot's in the order
    // its sensors did), which a replay then follows. A full queue drops and
    // counts.
    let (tx, mut inputs) = tokio::sync::mpsc::channel::<Arrived>(INPUT_QUEUE);
    let queue_full = Arc::new(AtomicU64::new(0));
    let queue = InputQueue {
        tx,
        full: queue_full.clone(),
    };
    let _control_inputs = ControlInputs::declare(join, &queue).await?;
    let Some(schedule) = join.schedule(&mut shutdown).await? else {
        return Ok(MsuCounters::default());
    };
    tracing::info!(
        "robot {robot}: site {:?} v{}, schedule v{}, estimator {}",
        site.name,
        info.version,
        schedule.version,
        core.estimator_name()
    );
    if let Err(e) = core.set_schedule(schedule) {
        tracing::warn!("robot {robot}: the central unit's schedule refused: {e}");
    }

    let source = SourceContext {
        robot,
        clock: settings.clock,
        site: ranging_site,
        marvelmind: settings.tuning.marvelmind,
        wheels: settings.tuning.wheels,
    };
    let robot_inputs =
        RobotInputs::declare(join, (settings.receivers.clone(), source), &queue).await?;
    let _status = StatusTask::start(
        session,
        keys.robot_status(robot)?,
        settings.clock,
        robot_inputs.receivers.summary(),
    )
    .await?;
    // Its link to the router, for `ickon admin status` (when it last came back).
    ickon_runtime::router_watch::report(session.clone(), keys.robot_link(robot)?, robot.into())
        .map_err(|e| NodeError::Setup(format!("cannot start the router link report: {e}")))?;
    drop(queue);
    let publishers = Publishers::declare(session, &keys, robot).await?;
    let ros = match settings.ros2.clone() {
        Some(plan) => Some(Ros2Link::open(session, plan, settings.tuning.wheels).await?),
        None => None,
    };

    let mut agent = Agent {
        robot,
        keys: &keys,
        core,
        publishers,
        summary: SummaryMaker::default(),
        ros,
        n: MsuCounters::default(),
        log_limit: LogLimiter::default(),
        refusal_limit: LogLimiter::default(),
        last_schedule_logged: None,
        board_motion: BoardMotion::default(),
    };
    agent.serve(&mut inputs, &mut shutdown).await;
    let mut n = agent.n;
    n.queue_full = queue_full.load(Ordering::Relaxed);
    tracing::info!("robot {robot}: stopping: {n:?}");
    if let Some(r) = &agent.ros {
        tracing::info!("robot {robot}: ros2: {:?}", r.counters());
    }
    Ok(n)
}

/// How often the agent publishes its [`MsuStatus`].
const STATUS_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// Publishes the agent's status once a second until dropped.
struct StatusTask(tokio::task::JoinHandle<()>);

impl Drop for StatusTask {
    fn drop(&mut self) {
        self.0.abort();
    }
}

impl StatusTask {
    async fn start(
        session: &Session,
        key: String,
        clock: ickon_runtime::SimulatedClock,
        receivers: crate::receivers::SharedSummary,
    ) -> Result<Self, NodeError> {
        let publisher = session.declare_publisher(key).await.map_err(zerr)?;
        Ok(Self(tokio::spawn(async move {
            let mut every = tokio::time::interval(STATUS_EVERY);
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            loop {
                every.tick().await;
                let status = MsuStatus {
                    stamp: clock.now(),
                    receivers: receivers.get(),
                };
                if let Ok(bytes) = ickon_proto::encode(&status) {
                    let _ = publisher.put(bytes).await;
                }
            }
        })))
    }
}

/// The sending end of the agent's one input queue, with the count of
/// inputs a full queue dropped.
struct InputQueue {
    tx: tokio::sync::mpsc::Sender<Arrived>,
    full: Arc<AtomicU64>,
}

impl InputQueue {
    /// A subscriber's callback: queues each sample as `wrap` decodes it, or
    /// counts it when the queue is full.
    fn sink(&self, wrap: fn(&Sample) -> Arrived) -> impl Fn(Sample) + Send + Sync + 'static {
        let (tx, full) = (self.tx.clone(), self.full.clone());
        move |sample: Sample| {
            if tx.try_send(wrap(&sample)).is_err() {
                full.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

/// The subscriptions to the central unit's and the cells' messages, held
/// for the agent's run.
struct ControlInputs {
    _schedule: Subscriber<()>,
    _trigger: Subscriber<()>,
    _status: Subscriber<()>,
    _survey: Subscriber<()>,
}

impl ControlInputs {
    /// Subscribes to the schedule, the cycle triggers, the cells' statuses
    /// and the survey calibration, each into `queue`.
    async fn declare(join: SiteJoin<'_>, queue: &InputQueue) -> Result<Self, NodeError> {
        let keys = join.keys();
        let schedule = join
            .subscribe_with(
                keys.central_schedule(),
                queue.sink(|s| Arrived::Schedule(decode(&s.payload().to_bytes()))),
            )
            .await?;
        // The triggers name the transmitters of each cycle when the central unit
        // fires only where robots are; the core matches arrivals to them.
        let trigger = join
            .subscribe_with(
                keys.central_cycle(),
                queue.sink(|s| Arrived::Trigger(decode(&s.payload().to_bytes()))),
            )
            .await?;
        // Each cell's sync sigma: the prior of its clock bias in `tdoa-ekf`.
        let status = join
            .subscribe_with(
                keys.cell_status_all(),
                queue.sink(|s| {
                    Arrived::CellStatus(
                        s.key_expr().as_str().to_string(),
                        decode(&s.payload().to_bytes()),
                    )
                }),
            )
            .await?;
        // The fleet's survey calibration: the transmitters' corrected positions.
        let survey = join
            .subscribe_with(
                keys.central_survey(),
                queue.sink(|s| Arrived::Survey(SurveyCalibration::decode(&s.payload().to_bytes()))),
            )
            .await?;
        Ok(Self {
            _schedule: schedule,
            _trigger: trigger,
            _status: status,
            _survey: survey,
        })
    }
}

/// The subscriptions to the robot's own messages, held for the agent's run.
struct RobotInputs {
    receivers: ReceiverSource,
    _odom: Subscriber<()>,
    _imu: Subscriber<()>,
    _range: Subscriber<()>,
}

impl RobotInputs {
    /// Opens the robot's receivers and subscribes to its odometry, gyro and
    /// obstacle ranges, each into `queue`.
    async fn declare(
        join: SiteJoin<'_>,
        (receivers, source): (ReceiverKind, SourceContext<'_>),
        queue: &InputQueue,
    ) -> Result<Self, NodeError> {
        let (session, keys) = (join.session(), join.keys());
        let robot = source.robot;
        let sub = |topic| keys.robot(robot, topic);
        let receivers = {
            let (tx, full) = (queue.tx.clone(), queue.full.clone());
            ReceiverSource::open(receivers, source, session, keys, move |input| {
                let arrived = match input {
                    ReceiverInput::Arrivals(a) => Arrived::Arrivals(a),
                    ReceiverInput::Ranging(r) => Arrived::Ranging(r),
                    ReceiverInput::Odometry(o) => Arrived::BoardOdometry(o),
                    ReceiverInput::Imu(i) => Arrived::BoardImu(i),
                };
                if tx.try_send(arrived).is_err() {
                    full.fetch_add(1, Ordering::Relaxed);
                }
            })
            .await?
        };
        let odom = join
            .subscribe_with(
                sub(RobotTopic::Odom)?,
                queue.sink(|s| Arrived::Odometry(decode(&s.payload().to_bytes()))),
            )
            .await?;
        let imu = join
            .subscribe_with(
                sub(RobotTopic::Imu)?,
                queue.sink(|s| Arrived::Imu(decode(&s.payload().to_bytes()))),
            )
            .await?;
        let range = join
            .subscribe_with(
                sub(RobotTopic::Range)?,
                queue.sink(|s| Arrived::Range(decode(&s.payload().to_bytes()))),
            )
            .await?;
        Ok(Self {
            receivers,
            _odom: odom,
            _imu: imu,
            _range: range,
        })
    }
}

/// Where the agent publishes its robot's fixes, poses and summaries.
struct Publishers {
    fix: Publisher<'static>,
    pose: Publisher<'static>,
    summary: Publisher<'static>,
}

impl Publishers {
    /// Declares the fix, pose and summary publishers of `robot`.
    async fn declare(session: &Session, keys: &Keys, robot: &str) -> Result<Self, NodeError> {
        // Not express: batched with other samples only when the link is busy
        // (Zenoh's adaptive batching), which is when one write per pose costs
        // the router most.
        let fix = session
            .declare_publisher(keys.robot(robot, RobotTopic::Fix)?)
            .priority(Priority::InteractiveHigh)
            .await
            .map_err(zerr)?;
        let pose = session
            .declare_publisher(keys.robot(robot, RobotTopic::Pose)?)
            .priority(Priority::InteractiveHigh)
            .congestion_control(CongestionControl::Drop)
            .await
            .map_err(zerr)?;
        // The central unit's view of the robot: a lost one is replaced by
        // the next half a second later.
        let summary = session
            .declare_publisher(keys.robot_summary(robot)?)
            .priority(Priority::InteractiveHigh)
            .congestion_control(CongestionControl::Drop)
            .await
            .map_err(zerr)?;
        Ok(Self { fix, pose, summary })
    }
}

/// The running agent: its core, where it publishes, its counters and the
/// rate limits of its logs.
struct Agent<'a> {
    robot: &'a str,
    keys: &'a Keys,
    core: MsuCore,
    publishers: Publishers,
    /// The summaries for the central unit, from the poses and fixes published.
    summary: SummaryMaker,
    ros: Option<Ros2Link>,
    n: MsuCounters,
    /// Bad input is logged once per kind per window, with the count held back.
    log_limit: LogLimiter<&'static str>,
    /// Refused input likewise, per input kind.
    refusal_limit: LogLimiter<InputKind>,
    /// The schedule (epoch, version) last logged.
    last_schedule_logged: Option<(u64, u32)>,
    /// Which of odometry and gyro the receiver board has reported: from
    /// then on that input comes from the board only.
    board_motion: BoardMotion,
}

/// The motion inputs a receiver board has supplied.
#[derive(Debug, Default, Clone, Copy)]
struct BoardMotion {
    odometry: bool,
    imu: bool,
}

impl Agent<'_> {
    /// The event loop: hands each queued input (and with `--ros2` each ROS 2
    /// input) to the core and publishes what it outputs, until `shutdown`
    /// completes.
    async fn serve(
        &mut self,
        inputs: &mut tokio::sync::mpsc::Receiver<Arrived>,
        shutdown: &mut (impl Future<Output = ()> + Unpin),
    ) {
        loop {
            let event = tokio::select! {
                _ = &mut *shutdown => break,
                Some(input) = inputs.recv() => self.admit(input),
                // With --ros2: the robot's odometry and gyro from ROS 2 topics.
                input = crate::ros2::next_input(&mut self.ros) => Some(match input {
                    Ros2Input::Odometry(msg) => Event::Odometry(msg),
                    Ros2Input::Imu(msg) => Event::Imu(msg),
                }),
            };
            let Some(event) = event else { continue };
            self.handle(event).await;
        }
    }

    /// The core's event for a queued input, or `None` when it does not
    /// decode or a cell status came under another cell's key (counted and
    /// logged); counts arrivals and logs each new schedule.
    fn admit(&mut self, input: Arrived) -> Option<Event> {
        let robot = self.robot;
        let status_key = match &input {
            Arrived::CellStatus(key, _) => Some(key.clone()),
            _ => None,
        };
        match &input {
            Arrived::BoardOdometry(_) => self.board_motion.odometry = true,
            Arrived::BoardImu(_) | Arrived::Ranging(HedgehogInput::Gyro(_)) => {
                self.board_motion.imu = true;
            }
            Arrived::Odometry(_) | Arrived::Imu(_) => {
                let from_board = match &input {
                    Arrived::Odometry(_) => self.board_motion.odometry,
                    _ => self.board_motion.imu,
                };
                if from_board {
                    // Two sources of one input on two clocks would
                    // corrupt the track: the device's wins.
                    self.n.motion_from_board_only += 1;
                    if let Some(held) = self.log_limit.admit("motion", std::time::Instant::now()) {
                        tracing::info!(
                            "robot {robot}: odometry or gyro from the receivers' device; \
                             the same on Zenoh ignored ({held} more since)"
                        );
                    }
                    return None;
                }
            }
            _ => {}
        }
        match input.into_event() {
            Ok(Event::Arrivals(a)) => {
                self.n.arrival_messages += 1;
                Some(Event::Arrivals(a))
            }
            Ok(Event::Schedule(schedule)) => {
                // The central re-announces its schedule every second:
                // only a new one is worth a line.
                if self.last_schedule_logged != Some((schedule.epoch, schedule.version)) {
                    self.last_schedule_logged = Some((schedule.epoch, schedule.version));
                    tracing::info!(
                        "robot {robot}: schedule v{} from cycle {}",
                        schedule.version,
                        schedule.effective_cycle
                    );
                }
                Some(Event::Schedule(schedule))
            }
            Ok(Event::CellStatus(status)) => {
                let key = status_key.unwrap_or_default();
                let key_cell = match self.keys.parse(&key) {
                    Ok(Key::CellStatus(cell)) => Some(cell),
                    _ => None,
                };
                match MsuCore::status_under_key(key_cell.as_deref(), status) {
                    Ok(status) => Some(Event::CellStatus(status)),
                    Err(e) => {
                        self.bad("cell status", format!("{key}: {e}"));
                        None
                    }
                }
            }
            Ok(event) => Some(event),
            Err((kind, e)) => {
                self.bad(kind, e);
                None
            }
        }
    }

    /// Counts a dropped input and logs it at a bounded rate per kind.
    fn bad(&mut self, kind: &'static str, what: String) {
        let robot = self.robot;
        self.n.bad_messages += 1;
        if let Some(held) = self.log_limit.admit(kind, std::time::Instant::now()) {
            tracing::warn!(
                "robot {robot}: dropped {kind}: {what} ({held} more since the last report)"
            );
        }
    }

    /// Hands `event` to the core and publishes its outputs, on ROS 2 as
    /// well when it is on.
    async fn handle(&mut self, event: Event) {
        if let (Some(r), Event::Odometry(odom)) = (self.ros.as_mut(), &event) {
            // The odometry frame's track, for map -> odom.
            r.note_odometry(odom);
        }
        let survey_before = self.core.newest_survey_calibration();
        let survey_fixes = match &event {
            Event::Survey(c) => Some(c.fixes_taken),
            _ => None,
        };
        let outputs = self.core.handle(event);
        self.log_survey(survey_before, survey_fixes);
        self.publish(outputs).await;
    }

    /// Logs a survey calibration from `fixes` fixes that the core took up
    /// (once per calibration epoch at info level, each new version at
    /// debug level); `before` is the one it had.
    fn log_survey(&self, before: Option<(u64, u32)>, fixes: Option<u64>) {
        let robot = self.robot;
        if let (Some(fixes), Some((epoch, version))) =
            (fixes, self.core.newest_survey_calibration())
        {
            if before.is_none_or(|(e, _)| e != epoch) {
                tracing::info!(
                    "robot {robot}: solving with the fleet's survey calibration (v{version}, from {fixes} fixes; newer ones follow silently)"
                );
            } else if before != Some((epoch, version)) {
                tracing::debug!("robot {robot}: survey calibration v{version} ({fixes} fixes)");
            }
        }
    }

    /// Publishes the core's outputs in order (a fix's ROS 2 copy after the
    /// pose that absorbed it) and counts them; logs refusals at a bounded
    /// rate.
    async fn publish(&mut self, outputs: Vec<Output>) {
        let robot = self.robot;
        let mut ros_fix = None;
        for output in outputs {
            match output {
                Output::Fix(fix) => {
                    if !put_counted(&self.publishers.fix, &fix).await {
                        self.n.failed_puts += 1;
                    }
                    self.n.fixes += 1;
                    self.summary.on_fix(&fix);
                    // Its ROS 2 copy waits until the pose that absorbed it is out.
                    ros_fix = Some(fix);
                }
                Output::Pose(pose) => {
                    if !put_counted(&self.publishers.pose, &pose).await {
                        self.n.failed_puts += 1;
                    }
                    self.n.poses += 1;
                    if let Some(summary) = self.summary.on_pose(&pose)
                        && !put_counted(&self.publishers.summary, &summary).await
                    {
                        self.n.failed_puts += 1;
                    }
                    // The ROS 2 copy after ours: it adds nothing ahead of it.
                    // A pose after a fix in one batch absorbed it.
                    if let Some(r) = self.ros.as_mut() {
                        r.publish_pose(&pose, ros_fix.is_some()).await;
                    }
                }
                Output::Refused { input, error } => {
                    self.n.refused_inputs += 1;
                    if let Some(held) = self.refusal_limit.admit(input, std::time::Instant::now()) {
                        tracing::debug!(
                            "robot {robot}: {input:?} not used: {error} ({held} more since)"
                        );
                    }
                }
            }
        }
        if let (Some(r), Some(fix)) = (self.ros.as_mut(), ros_fix) {
            r.publish_fix(&fix).await;
        }
    }
}

/// Arguments of `ickon-msu` (and `ickon node msu`).
#[derive(Debug, Clone, Args)]
pub struct MsuArgs {
    /// Connection and simulation flags.
    #[command(flatten)]
    pub mesh: NodeArgs,
    /// The robot this agent serves.
    #[arg(long)]
    pub robot: String,
    /// The MSU configuration file (TOML: estimator, each input's noise and
    /// gate, drive geometry; see `deploy/msu.toml`). Without it, the
    /// defaults of `--estimator`.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Estimator name when there is no configuration file (`tdoa-ekf`, ours
    /// and the most accurate; the baselines `odometry` and `msu-raw` and
    /// the papers' `ickon-akf`, `gyro-ckf`, `cda`, `cda-msu`).
    #[arg(long, conflicts_with = "config")]
    pub estimator: Option<String>,
    /// One-sigma timing noise of one arrival, microseconds (the MSU's data
    /// sheet); overrides the file's `fix.timing_sigma_us` (default 50).
    #[arg(long)]
    pub timing_sigma_us: Option<f64>,
    /// Wheel base of the robot, metres; overrides the file's `robot.wheel_base_m`.
    #[arg(long)]
    pub wheel_base_m: Option<f64>,
    /// Distance per encoder tick, metres; overrides the file's
    /// `robot.m_per_tick` (default: a Pioneer 3-DX).
    #[arg(long)]
    pub m_per_tick: Option<f64>,
    /// Where the arrivals come from: `sim` (the simulated world's), a
    /// receiver board of the ICKON device protocol at `serial:PATH[@BAUD]`
    /// (115200 baud when not given) or `tcp:HOST:PORT`, or a Marvelmind
    /// hedgehog's raw distances at `marvelmind:serial:PATH[@BAUD]` or
    /// `marvelmind:tcp:HOST:PORT` (its settings: the configuration file's
    /// `[marvelmind]` block).
    #[arg(long, default_value_t = ReceiverKind::Sim, value_name = "sim|serial:PATH[@BAUD]|tcp:HOST:PORT|marvelmind:ADDRESS")]
    pub receivers: ReceiverKind,
    /// The ROS 2 side (`--ros2` and `--ros2-*`); boxed, as it is most of
    /// the arguments' size.
    #[command(flatten)]
    pub ros2: Box<Ros2Options>,
}

/// The agent's tuning from its flags: the configuration file or the
/// estimator's defaults, then the flags that override single values.
pub fn tuning_from_args(args: &MsuArgs) -> Result<MsuTuning, String> {
    let mut tuning = match (&args.config, &args.estimator) {
        (Some(path), _) => MsuTuning::load(path).map_err(|e| e.to_string())?,
        (None, name) => MsuTuning::defaults(name.as_deref().unwrap_or(DEFAULT_ESTIMATOR))
            .map_err(|e| e.to_string())?,
    };
    let positive = |flag: &str, v: Option<f64>| match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(format!("{flag} must be a positive number")),
        other => Ok(other),
    };
    if let Some(us) = positive("--timing-sigma-us", args.timing_sigma_us)? {
        tuning.solver.timing_sigma_s = us * 1e-6;
    }
    if let Some(m) = positive("--wheel-base-m", args.wheel_base_m)? {
        tuning.wheels.wheel_base_m = m;
    }
    if let Some(m) = positive("--m-per-tick", args.m_per_tick)? {
        tuning.wheels.left_m_per_tick = m;
        tuning.wheels.right_m_per_tick = m;
    }
    Ok(tuning)
}

/// The estimator an agent runs when neither a file nor `--estimator` names one.
pub const DEFAULT_ESTIMATOR: &str = "tdoa-ekf";

/// An agent's settings from its flags, with the configuration file's
/// warnings (each naming the file); the error is the text to print before
/// exit code 2.
pub fn settings_from_args(args: &MsuArgs) -> Result<(MsuSettings, Vec<String>), String> {
    let tuning = tuning_from_args(args)?;
    let file = args
        .config
        .as_ref()
        .map_or(String::new(), |p| p.display().to_string());
    let warnings = tuning
        .warnings
        .iter()
        .map(|w| format!("{file}:{w}"))
        .collect();
    Ok((settings_with_tuning(args, tuning)?, warnings))
}

/// An agent's settings from its flags and a tuning already read (a
/// process hosting several robots reads their shared file once).
pub fn settings_with_tuning(args: &MsuArgs, tuning: MsuTuning) -> Result<MsuSettings, String> {
    let ros2_options = match &tuning.ros2 {
        Some(file) => Ros2Options::under_flags(file, &args.ros2),
        None => (*args.ros2).clone(),
    };
    let ros2 = if ros2_options.enabled {
        let env_domain = std::env::var("ROS_DOMAIN_ID").ok();
        Some(
            Ros2Plan::new(&ros2_options, &args.robot, env_domain.as_deref())
                .map_err(|e| e.to_string())?,
        )
    } else {
        None
    };
    let settings = MsuSettings {
        site_name: args.mesh.site_name().to_string(),
        robot: args.robot.clone(),
        tuning,
        receivers: args.receivers.clone(),
        clock: args.mesh.clock(),
        ros2,
    };
    Ok(settings)
}

/// Runs an MSU agent as a process until Ctrl-C/SIGTERM. Exit code 2 for bad
/// arguments or configuration, 1 for a failure at run time.
pub fn main_with(args: MsuArgs) -> ExitCode {
    let settings = match settings_from_args(&args) {
        Ok((settings, warnings)) => {
            for w in &warnings {
                tracing::warn!("{w}");
            }
            settings
        }
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    ickon_runtime::run_node(2, async {
        let session = args.mesh.open().await?;
        let r = run(&session, settings, args.mesh.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

#[cfg(test)]
mod tests {
    use clap::Args;

    /// The `ickon-msu` binary's command line (`src/main.rs`): a flag defined
    /// twice panics only when parsed, so the definition is checked here.
    #[test]
    fn the_binarys_command_line_is_well_formed() {
        let command = clap::Command::new("ickon-msu").version("0");
        super::MsuArgs::augment_args(command).debug_assert();
    }
}
