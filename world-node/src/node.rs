//! The world as a Zenoh node (`ickon node world`): the [`RealtimeWorld`]
//! driven by the system clock, fed with the cells' burst reports, publishing
//! each robot's sensors and the ground truth. In a real-time simulation the
//! system clock is the true time base: the cells report their actual emission
//! times on it, and the robots' own clocks are simulated on top of it.

use std::future::Future;
use std::process::ExitCode;
use std::time::Duration;

use clap::Args;

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::Truth;
use ickon_proto::time::Time;
use ickon_proto::{decode, encode};
use ickon_runtime::site_join::QueuedSubscriber;
use ickon_runtime::{JoinedSite, LogLimiter, NodeError, SiteJoin, system_now, zerr};
use zenoh::Session;
use zenoh::pubsub::Publisher;

use crate::device_hosting::{BoundDevices, DeviceEvent, WorldDevices};
use crate::devices::{DeviceEndpoint, DeviceKind, DeviceOwner};
use crate::fleet_args::SimulatedRobotsArgs;
use crate::realtime::{RealtimeWorld, WorldEvent, WorldOutput};
use crate::ros2_sensors::RosSensorPublishers;
use ickon_sim::profile::NoiseProfile;

/// Physics and sensors advance this often.
const TICK: Duration = Duration::from_millis(5);

/// What the world process needs besides its session.
#[derive(Debug, Clone)]
pub struct WorldSettings {
    /// Site name (the `<site>` of every key).
    pub site_name: String,
    /// Robots to simulate.
    pub robots: Vec<String>,
    /// Noise profile.
    pub profile: NoiseProfile,
    /// Run seed.
    pub seed: u64,
    /// Publish odometry and gyro as ROS 2 topics (rmw_zenoh) instead of on
    /// the ICKON keys.
    pub ros2: bool,
    /// The devices to emulate, fed by this world.
    pub devices: Vec<DeviceEndpoint>,
    /// Transmitters that fail during the run, as `--faults` items
    /// ([`ickon_sim::tx_faults`]), read against the site once it is known.
    pub transmitter_faults: Option<String>,
}

/// One robot's publishers.
struct RobotPublishers {
    ultrasound: Publisher<'static>,
    odom: Publisher<'static>,
    imu: Publisher<'static>,
    range: Publisher<'static>,
    truth: Publisher<'static>,
    /// The position its emulated ranging kit reported, if it has one.
    kit: Option<Publisher<'static>>,
    /// With `--ros2`: odometry and gyro go here instead.
    ros: Option<RosSensorPublishers>,
}

/// Runs the world until `shutdown` completes; returns the bursts it heard.
pub async fn run(
    session: &Session,
    settings: WorldSettings,
    shutdown: impl Future<Output = ()>,
) -> Result<u64, NodeError> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&settings.site_name)?;
    // Listening at once: cells and agents started with the world connect
    // as soon as they try, and are served once the site is known.
    let bound = BoundDevices::bind(&settings.devices)?;
    let join = SiteJoin::new(session, &keys);
    let _token = join.announce(keys.alive_world()).await?;
    let Some(JoinedSite { site, .. }) = join.site(&mut shutdown).await? else {
        return Ok(0);
    };
    let mut world = RealtimeWorld::new(&site, &settings.robots, &settings.profile, settings.seed)
        .map_err(|e| NodeError::Setup(e.to_string()))?;
    if let Some(plan) = &settings.transmitter_faults {
        let faults = ickon_sim::tx_faults::TransmitterFault::parse_plan(plan, &site)
            .map_err(|e| NodeError::Setup(e.to_string()))?;
        world.set_transmitter_faults(&faults);
    }
    let mut devices = if bound.is_empty() {
        None
    } else {
        let d = WorldDevices::start(
            bound,
            &site,
            &settings.profile,
            world.robot_ids(),
            settings.seed,
        )?;
        for i in 0..world.robot_ids().len() {
            if d.robot_on_device(i) {
                world.use_true_clock(i);
            }
        }
        Some(d)
    };
    let inputs = WorldInputs {
        schedule: join.subscribe(keys.central_schedule()).await?,
        bursts: join.subscribe(keys.cell_burst_all()).await?,
        triggers: join.subscribe(keys.central_cycle()).await?,
    };
    // `None`: stopped while waiting (the shutdown future is then spent).
    let Some(schedule) = join.schedule(&mut shutdown).await? else {
        return Ok(0);
    };
    let _ = world.handle(system_now(), WorldEvent::Schedule(schedule));
    let kits: Vec<bool> = settings_kits(&settings.devices, world.robot_ids());
    let mut pubs =
        robot_publishers(session, &keys, world.robot_ids(), &kits, settings.ros2).await?;
    tracing::info!(
        "world: {} robots on site {:?}, profile {}",
        pubs.len(),
        site.name,
        settings.profile.name
    );

    let bursts_heard = serve(&mut world, &inputs, &mut pubs, &mut devices, &mut shutdown).await?;
    if let Some(d) = &devices
        && d.unmatched_reports() > 0
    {
        tracing::warn!(
            "world: {} burst reports no transmitter board fired (no sound left)",
            d.unmatched_reports()
        );
    }
    if world.bursts_ignored() > 0 {
        tracing::warn!(
            "world: {} burst reports ignored (stamped more than 10 s from now)",
            world.bursts_ignored()
        );
    }
    Ok(bursts_heard)
}

/// Opens each robot's publishers (and with `ros2` its ROS 2 sensor
/// publishers), in the order of `ids`.
async fn robot_publishers(
    session: &Session,
    keys: &Keys,
    ids: &[String],
    kits: &[bool],
    ros2: bool,
) -> Result<Vec<RobotPublishers>, NodeError> {
    let mut pubs = Vec::new();
    for (id, &kit) in ids.iter().zip(kits) {
        // Block, not drop, when a subscriber's link is full: a sample lost
        // to one subscriber only (the MSU or a recorder) would make a
        // recording differ from what the MSU saw. Not express: the world
        // puts every robot's samples of a tick at once, and Zenoh's adaptive
        // batching packs them into few writes when the link is busy (at 64
        // robots express writes cost the router and the world half their
        // CPU, and the MSUs a third of their arrivals).
        let publisher = |key: String| {
            session
                .declare_publisher(key)
                .congestion_control(zenoh::qos::CongestionControl::Block)
        };
        pubs.push(RobotPublishers {
            ultrasound: publisher(keys.robot(id, RobotTopic::Ultrasound)?)
                .await
                .map_err(zerr)?,
            odom: publisher(keys.robot(id, RobotTopic::Odom)?)
                .await
                .map_err(zerr)?,
            imu: publisher(keys.robot(id, RobotTopic::Imu)?)
                .await
                .map_err(zerr)?,
            range: publisher(keys.robot(id, RobotTopic::Range)?)
                .await
                .map_err(zerr)?,
            truth: publisher(keys.sim_truth(id)?).await.map_err(zerr)?,
            kit: if kit {
                Some(publisher(keys.sim_kit(id)?).await.map_err(zerr)?)
            } else {
                None
            },
            ros: if ros2 {
                let nid = u32::try_from(pubs.len()).unwrap_or(u32::MAX);
                Some(RosSensorPublishers::open(session, id, nid).await?)
            } else {
                None
            },
        });
    }
    Ok(pubs)
}

/// What the world hears.
struct WorldInputs {
    /// The central unit's schedules.
    schedule: QueuedSubscriber,
    /// Every cell's burst reports.
    bursts: QueuedSubscriber,
    /// Which transmitters fire each cycle: a cycle is over when they have.
    triggers: QueuedSubscriber,
}

/// The event loop: feeds the world each input and each tick and publishes
/// what it outputs, until `shutdown` completes; returns the bursts heard.
async fn serve(
    world: &mut RealtimeWorld,
    inputs: &WorldInputs,
    pubs: &mut [RobotPublishers],
    devices: &mut Option<WorldDevices>,
    shutdown: &mut (impl Future<Output = ()> + Unpin),
) -> Result<u64, NodeError> {
    let mut tick = tokio::time::interval(TICK);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut bursts_heard = 0u64;
    let mut log_limit = LogLimiter::<&'static str>::default();
    loop {
        let event = tokio::select! {
            _ = &mut *shutdown => break,
            Ok(s) = inputs.schedule.recv_async() => {
                decoded(&mut log_limit, "schedule", &s).map(WorldEvent::Schedule)
            }
            Ok(s) = inputs.bursts.recv_async() => {
                decoded::<Burst>(&mut log_limit, "burst", &s).and_then(|b| {
                    bursts_heard += 1;
                    match devices.as_mut() {
                        Some(d) => d.burst(b),
                        None => Some(b),
                    }
                    .map(WorldEvent::Burst)
                })
            }
            device = next_device_event(devices) => {
                match device {
                    DeviceEvent::Fired(e) => {
                        if let Some(d) = devices.as_mut() {
                            d.on_emission(e);
                        }
                    }
                    DeviceEvent::KitPosition { robot, t_ns, at_m } => {
                        publish_kit(pubs, robot, t_ns, at_m).await?;
                    }
                }
                continue;
            }
            Ok(s) = inputs.triggers.recv_async() => {
                decoded(&mut log_limit, "cycle trigger", &s).map(WorldEvent::Trigger)
            }
            _ = tick.tick() => Some(WorldEvent::Tick),
        };
        let Some(event) = event else { continue };
        let outputs = world.handle(system_now(), event);
        let epoch = world.epoch().unwrap_or(Time::ZERO);
        for o in outputs {
            let o = match devices.as_mut() {
                Some(d) => d.route(o, epoch),
                None => Some(o),
            };
            if let Some(o) = o {
                publish(pubs, o, epoch).await?;
            }
        }
    }
    Ok(bursts_heard)
}

/// The next thing a device did; pending forever without devices.
async fn next_device_event(devices: &mut Option<WorldDevices>) -> DeviceEvent {
    match devices {
        Some(d) => d.next_event().await,
        None => std::future::pending().await,
    }
}

/// Which robots of `ids` carry a ranging kit.
fn settings_kits(devices: &[DeviceEndpoint], ids: &[String]) -> Vec<bool> {
    ids.iter()
        .map(|id| {
            devices.iter().any(|d| {
                d.kind == DeviceKind::Marvelmind && d.owner == DeviceOwner::Robot(id.clone())
            })
        })
        .collect()
}

/// Publishes a position robot `index`'s kit reported at true time `t_ns`
/// (the robot's clock is the true time on a device).
async fn publish_kit(
    pubs: &[RobotPublishers],
    index: usize,
    t_ns: i64,
    at: [f64; 2],
) -> Result<(), NodeError> {
    let Some(publisher) = pubs.get(index).and_then(|p| p.kit.as_ref()) else {
        return Ok(());
    };
    let stamp = Time::from_nanos(t_ns);
    let position = Truth {
        stamp,
        robot_clock: stamp,
        x_m: at[0],
        y_m: at[1],
        theta_rad: 0.0,
        v_m_s: 0.0,
        omega_rad_s: 0.0,
    };
    publisher.put(encode(&position)?).await.map_err(zerr)
}

/// The message in `sample`, or `None` when it does not decode (logged at
/// a bounded rate per kind, with the key it came under).
fn decoded<T: serde::de::DeserializeOwned>(
    log_limit: &mut LogLimiter<&'static str>,
    kind: &'static str,
    sample: &zenoh::sample::Sample,
) -> Option<T> {
    match decode::<T>(&sample.payload().to_bytes()) {
        Ok(message) => Some(message),
        Err(e) => {
            if let Some(held) = log_limit.admit(kind, std::time::Instant::now()) {
                tracing::warn!(
                    "undecodable {kind} on {}: {e} ({held} more since)",
                    sample.key_expr()
                );
            }
            None
        }
    }
}

async fn publish(
    pubs: &mut [RobotPublishers],
    output: WorldOutput,
    t0: Time,
) -> Result<(), NodeError> {
    // With --ros2 the robot's odometry and gyro are ROS 2 topics.
    match &output {
        WorldOutput::Odometry(i, m) => {
            if let Some(ros) = pubs.get_mut(*i).and_then(|p| p.ros.as_mut()) {
                return ros.odometry(m).await;
            }
        }
        WorldOutput::Imu(i, m) => {
            if let Some(ros) = pubs.get_mut(*i).and_then(|p| p.ros.as_mut()) {
                return ros.imu(m).await;
            }
        }
        _ => {}
    }
    let (robot, bytes, publisher) = match &output {
        WorldOutput::Imu(i, m) => (*i, encode(m)?, pubs.get(*i).map(|p| &p.imu)),
        WorldOutput::Odometry(i, m) => (*i, encode(m)?, pubs.get(*i).map(|p| &p.odom)),
        WorldOutput::Ranges(i, m) => (*i, encode(m)?, pubs.get(*i).map(|p| &p.range)),
        WorldOutput::Arrivals(i, m) => (*i, encode(m)?, pubs.get(*i).map(|p| &p.ultrasound)),
        WorldOutput::Truth(i, m) => {
            // Truth goes out on the true time base (the system clock).
            let mut t = *m;
            t.stamp = Time::from_nanos(t0.as_nanos().saturating_add(t.stamp.as_nanos()));
            (*i, encode(&t)?, pubs.get(*i).map(|p| &p.truth))
        }
    };
    match publisher {
        Some(p) => p.put(bytes).await.map_err(zerr),
        None => Err(NodeError::Setup(format!(
            "world output for unknown robot index {robot}"
        ))),
    }
}

/// Arguments of `ickon-world` (and `ickon node world`).
#[derive(Debug, Clone, Args)]
pub struct WorldArgs {
    /// The mesh, the robots, their noise profile and the seed.
    #[command(flatten)]
    pub fleet: SimulatedRobotsArgs,
    /// Publish each robot's odometry and gyro as ROS 2 topics (rmw_zenoh,
    /// domain 0, `/<robot>/odom` and `/<robot>/imu`) instead of on the ICKON keys.
    #[arg(long)]
    pub ros2: bool,
    /// Emulate a device fed by this world, listening on TCP:
    /// `cell/ID=transmitter-board@HOST:PORT` (the cell runs `--driver
    /// tcp:HOST:PORT`), `robot/ID=receiver-board@HOST:PORT` (the robot's
    /// arrivals, wheel ticks and gyro; its agent runs `--receivers
    /// tcp:HOST:PORT`) or `robot/ID=marvelmind@HOST:PORT` (a hedgehog;
    /// `--receivers marvelmind:tcp:HOST:PORT`). Repeat for each device.
    #[arg(long = "device", value_name = "OWNER=KIND@HOST:PORT")]
    pub devices: Vec<DeviceEndpoint>,
    /// Transmitters that fail, comma-separated, times from the world's
    /// start: `dead:tx/ID@T`, `weak:tx/ID@T=FRACTION`,
    /// `moved:tx/ID@T=DX,DY,DZ` (metres); T in s or ms.
    #[arg(long)]
    pub transmitter_faults: Option<String>,
}

/// Runs the world as a process until Ctrl-C/SIGTERM. Exit code 2 for bad
/// arguments, 1 for a failure at run time.
pub fn main_with(args: WorldArgs) -> ExitCode {
    let profile = match NoiseProfile::load(&args.fleet.profile) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let settings = WorldSettings {
        site_name: args.fleet.mesh.site_name().to_string(),
        robots: args.fleet.robots.clone(),
        profile,
        seed: args.fleet.seed,
        ros2: args.ros2,
        devices: args.devices.clone(),
        transmitter_faults: args.transmitter_faults.clone(),
    };
    ickon_runtime::run_node(2, async {
        let session = args.fleet.mesh.open().await?;
        let r = run(&session, settings, args.fleet.mesh.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

#[cfg(test)]
mod tests {
    use clap::Args;

    /// The `ickon-world` binary's command line (`src/main.rs`): a flag defined
    /// twice panics only when parsed, so the definition is checked here.
    #[test]
    fn the_binarys_command_line_is_well_formed() {
        let command = clap::Command::new("ickon-world").version("0");
        super::WorldArgs::augment_args(command).debug_assert();
    }
}
