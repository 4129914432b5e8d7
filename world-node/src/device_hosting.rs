//! The world's emulated devices as TCP servers, fed by the simulated world:
//! each cell's transmitter board fires the bursts its cell arms and tells
//! the world when they really left; each robot's receiver board frames the
//! arrivals, wheel ticks and gyro the world's sensors produced; each
//! robot's Marvelmind hedgehog measures from where the robot truly is.
//!
//! Every device runs as a task of the world's runtime, listening from the
//! moment the world starts (so that a cell or an agent started at the same
//! time connects as soon as it tries) and serving one host at a time, as a
//! board on a serial line does. What the world produces for a device while
//! no host is connected is framed and dropped, as a board with nobody
//! listening would.
//!
//! A robot on a device keeps the true time as its clock: its host (the
//! agent) learns the device's clock, which has its own offset and drift,
//! and stamps everything on its own (the system clock in a simulation).

use std::net::{SocketAddr, TcpListener as StdListener};

use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::Truth;
use ickon_proto::site::Site;
use ickon_proto::time::Time;
use ickon_runtime::{NodeError, system_now};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;

use crate::board::{BoardAir, BoardSpec, Emission, EmulatedBoard};
use crate::devices::{DeviceEndpoint, DeviceKind, DeviceOwner, EmissionLedger};
use crate::hedgehog::{EmulatedHedgehog, HedgehogSpec};
use crate::realtime::WorldOutput;
use ickon_sim::air::AirField;
use ickon_sim::air_sensor::{AirSensor, board_position};
use ickon_sim::profile::NoiseProfile;
use ickon_sim::rng::{normal, stream, uniform};

/// One-sigma drift of an emulated board's crystal, ppm (a common ±20 ppm
/// part's tolerance, taken as one sigma).
const BOARD_DRIFT_SIGMA_PPM: f64 = 20.0;
/// Timing jitter of a transmitter board's firing, nanoseconds (a
/// microcontroller timer's interrupt latency). Receiver boards add none:
/// the world's arrivals carry the profile's detection noise already.
const TRANSMITTER_JITTER_NS: f64 = 1_000.0;
/// A hedgehog's update rate in a simulation, Hz (Marvelmind's usual rate
/// with four beacons).
const KIT_RATE_HZ: f64 = 8.0;
/// The speed of sound a hedgehog is set to, m/s: the kit's factory
/// setting, which an agent's `[marvelmind]` configuration assumes unless
/// told otherwise (the agent rescales to the site's air).
const KIT_SPEED_OF_SOUND_M_S: f64 = 343.0;
/// A hedgehog's one-sigma range noise, metres (Marvelmind's stated ±2 cm).
const KIT_RANGE_SIGMA_M: f64 = 0.02;

/// The devices' listeners, bound when the world starts.
pub struct BoundDevices {
    listeners: Vec<(DeviceEndpoint, StdListener)>,
}

impl BoundDevices {
    /// Binds every endpoint; a port that cannot be bound is an error naming it.
    pub fn bind(endpoints: &[DeviceEndpoint]) -> Result<Self, NodeError> {
        let listeners = endpoints
            .iter()
            .map(|e| {
                let l = StdListener::bind(e.listen)
                    .and_then(|l| l.set_nonblocking(true).map(|()| l))
                    .map_err(|err| NodeError::Setup(format!("--device {e}: {err}")))?;
                Ok((e.clone(), l))
            })
            .collect::<Result<Vec<_>, NodeError>>()?;
        Ok(Self { listeners })
    }

    /// Whether there is nothing to emulate.
    pub fn is_empty(&self) -> bool {
        self.listeners.is_empty()
    }
}

/// What the world hands a receiver board.
enum ToBoard {
    /// One cycle's arrivals: (transmitter, receiver, true time, ns).
    Arrivals(Vec<(u32, u8, i64)>),
    /// Cumulative wheel ticks at a true time.
    Ticks(i64, i64, i64),
    /// A gyro sample at a true time.
    Imu(i64, f64),
}

/// A robot's device, as the world feeds it.
enum RobotDevice {
    /// A receiver board, and the number of arrival groups it framed.
    Board(mpsc::UnboundedSender<ToBoard>, u64),
    /// A hedgehog, measuring from the robot's true position.
    Kit(watch::Sender<[f64; 2]>),
}

/// A device task, stopped when the world stops.
struct Task(JoinHandle<()>);

impl Drop for Task {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// Something a device did that the world must know.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DeviceEvent {
    /// A transmitter board fired a burst.
    Fired(Emission),
    /// A hedgehog reported a position.
    KitPosition {
        /// Robot index.
        robot: usize,
        /// When, true time, nanoseconds.
        t_ns: i64,
        /// Where, metres.
        at_m: [f64; 2],
    },
}

/// The world's devices.
pub struct WorldDevices {
    /// By robot index (as in [`WorldOutput`]).
    robots: Vec<Option<RobotDevice>>,
    emissions: mpsc::UnboundedReceiver<Emission>,
    kit_positions: mpsc::UnboundedReceiver<(usize, i64, [f64; 2])>,
    ledger: EmissionLedger,
    cells_on_boards: bool,
    _idle_inboxes: Vec<mpsc::UnboundedSender<ToBoard>>,
    _tasks: Vec<Task>,
}

impl WorldDevices {
    /// Starts serving the `bound` devices of `site`'s cells and of the
    /// robots `robot_ids`, with clocks drawn from `seed`; a transmitter
    /// board has an air temperature sensor when `profile` gives the boards
    /// one (reading the profile's air from now on).
    pub fn start(
        bound: BoundDevices,
        site: &Site,
        profile: &NoiseProfile,
        robot_ids: &[String],
        seed: u64,
    ) -> Result<Self, NodeError> {
        let air = AirField::new(
            site,
            &profile.ultrasound.air,
            profile.ultrasound.temperature_error_c,
        );
        let air_start_ns = system_now().as_nanos();
        let (emitted, emissions) = mpsc::unbounded_channel();
        let (kit_tx, kit_positions) = mpsc::unbounded_channel();
        let mut robots: Vec<Option<RobotDevice>> = robot_ids.iter().map(|_| None).collect();
        let mut tasks = Vec::new();
        let mut cells_on_boards = false;
        let mut idle_inboxes = Vec::new();
        for (endpoint, std_listener) in bound.listeners {
            let listener = TcpListener::from_std(std_listener)
                .map_err(|e| NodeError::Setup(format!("--device {endpoint}: {e}")))?;
            let label = endpoint.to_string();
            let mut clock = stream(seed, &format!("device/{label}"));
            let now_ns = system_now().as_nanos();
            let unknown = |what: &str| NodeError::Setup(format!("--device {label}: {what}"));
            match (&endpoint.owner, endpoint.kind) {
                (DeviceOwner::Cell(cell), DeviceKind::TransmitterBoard) => {
                    let tx_ids: Vec<u32> = site
                        .transmitters
                        .iter()
                        .filter(|t| &t.cell == cell)
                        .map(|t| t.id)
                        .collect();
                    if tx_ids.is_empty() {
                        return Err(unknown("no such cell in the site"));
                    }
                    let mut spec = BoardSpec::transmitter(&tx_ids, seed ^ label_seed(&label));
                    board_clock(&mut spec, &mut clock, TRANSMITTER_JITTER_NS);
                    let sensors = &profile.air_sensors;
                    if let Some(at) = board_position(site, cell).filter(|_| sensors.rate_hz > 0.0) {
                        spec = spec.with_air_sensor(BoardAir {
                            sensor: AirSensor::new(cell, at, sensors, seed),
                            field: air.clone(),
                            start_ns: air_start_ns,
                        });
                    }
                    let board = EmulatedBoard::new(spec, now_ns);
                    // A transmitter board is fed nothing; its sender is
                    // kept, as a closed inbox ends a board's task.
                    let (inbox_tx, inbox) = mpsc::unbounded_channel();
                    idle_inboxes.push(inbox_tx);
                    cells_on_boards = true;
                    tasks.push(Task(tokio::spawn(serve_board(
                        listener,
                        board,
                        inbox,
                        emitted.clone(),
                        label,
                    ))));
                }
                (DeviceOwner::Robot(robot), kind) => {
                    let index = robot_ids
                        .iter()
                        .position(|r| r == robot)
                        .ok_or_else(|| unknown("not a robot of this world"))?;
                    let device = match kind {
                        DeviceKind::Marvelmind => {
                            let spec = HedgehogSpec {
                                robot: robot.clone(),
                                rate_hz: KIT_RATE_HZ,
                                range_sigma_m: KIT_RANGE_SIGMA_M,
                                kit_speed_of_sound_m_s: KIT_SPEED_OF_SOUND_M_S,
                                garbage: 0.0,
                                drop: 0.0,
                                address: 9,
                                seed: seed ^ label_seed(&label),
                            };
                            let hedgehog = EmulatedHedgehog::new(site, spec)
                                .map_err(|e| unknown(&e.to_string()))?;
                            let (pose_tx, pose) = watch::channel([f64::NAN; 2]);
                            let positions = kit_tx.clone();
                            tasks.push(Task(tokio::spawn(serve_kit(
                                listener, hedgehog, pose, positions, index, label,
                            ))));
                            RobotDevice::Kit(pose_tx)
                        }
                        _ => {
                            let angles = &site.msu.receiver_angles_rad;
                            let receivers = u8::try_from(angles.len().max(1))
                                .map_err(|_| unknown("more than 255 receivers"))?;
                            let mut spec =
                                BoardSpec::receiver(receivers, seed ^ label_seed(&label))
                                    .with_motion();
                            // The ring the site describes, in hundredths of a degree.
                            spec.identity.channels = angles
                                .iter()
                                .map(|a| (a.to_degrees() * 100.0).round() as i64)
                                .collect();
                            board_clock(&mut spec, &mut clock, 0.0);
                            let board = EmulatedBoard::new(spec, now_ns);
                            let (inbox_tx, inbox) = mpsc::unbounded_channel();
                            tasks.push(Task(tokio::spawn(serve_board(
                                listener,
                                board,
                                inbox,
                                emitted.clone(),
                                label,
                            ))));
                            RobotDevice::Board(inbox_tx, 0)
                        }
                    };
                    robots[index] = Some(device);
                }
                (DeviceOwner::Cell(_), _) => return Err(unknown("a cell has a transmitter board")),
            }
        }
        Ok(Self {
            robots,
            emissions,
            kit_positions,
            ledger: EmissionLedger::default(),
            cells_on_boards,
            _idle_inboxes: idle_inboxes,
            _tasks: tasks,
        })
    }

    /// Whether robot `index` is on a device (its clock is then the true time).
    pub fn robot_on_device(&self, index: usize) -> bool {
        self.robots.get(index).is_some_and(Option::is_some)
    }

    /// The next thing a device did; pending forever once no device can.
    pub async fn next_event(&mut self) -> DeviceEvent {
        tokio::select! {
            Some(e) = self.emissions.recv() => DeviceEvent::Fired(e),
            Some((robot, t_ns, at_m)) = self.kit_positions.recv() => DeviceEvent::KitPosition {
                robot,
                t_ns,
                at_m,
            },
            else => std::future::pending().await,
        }
    }

    /// Remembers a board's burst until its cell reports it.
    pub fn on_emission(&mut self, e: Emission) {
        self.ledger.record(e.tx_id, e.reference_ns);
    }

    /// A cell's burst report as the world takes it: with transmitter
    /// boards, at the time its board really fired it, or `None` when no
    /// board fired it (no sound left).
    pub fn burst(&mut self, mut b: Burst) -> Option<Burst> {
        if !self.cells_on_boards {
            return Some(b);
        }
        // A board's firing reaches the world before its cell's report, but
        // both may wait together: the firings are taken in first.
        while let Ok(e) = self.emissions.try_recv() {
            self.on_emission(e);
        }
        let fired_ns = self.ledger.take(b.tx_id, b.actual.as_nanos())?;
        b.actual = Time::from_nanos(fired_ns);
        Some(b)
    }

    /// Cell reports no board firing explained.
    pub fn unmatched_reports(&self) -> u64 {
        self.ledger.unmatched_reports
    }

    /// Hands a robot's sensor output to its device, if it has one; returns
    /// what is still published on Zenoh (stamped on the true time base for
    /// a robot on a device), if anything. `epoch`: the true time of the
    /// world's second 0.
    pub fn route(&mut self, output: WorldOutput, epoch: Time) -> Option<WorldOutput> {
        let index = robot_of(&output);
        let Some(device) = self.robots.get_mut(index).and_then(Option::as_mut) else {
            return Some(output);
        };
        let at = |t: Time| Time::from_nanos(epoch.as_nanos().saturating_add(t.as_nanos()));
        match (device, output) {
            (RobotDevice::Board(inbox, groups), WorldOutput::Arrivals(i, a)) => {
                let heard = a
                    .arrivals
                    .iter()
                    .map(|x| (x.tx_id, x.receiver_id, at(x.t_arrival).as_nanos()))
                    .collect();
                let _ = inbox.send(ToBoard::Arrivals(heard));
                *groups += 1;
                // Published too, numbered as the board numbers the group,
                // so that observers can time the pose made of it.
                let mut shown = a;
                shown.seq = *groups;
                for x in &mut shown.arrivals {
                    x.t_arrival = at(x.t_arrival);
                }
                Some(WorldOutput::Arrivals(i, shown))
            }
            (RobotDevice::Board(inbox, _), WorldOutput::Odometry(_, o)) => {
                let t = at(o.stamp).as_nanos();
                let _ = inbox.send(ToBoard::Ticks(t, o.left_ticks, o.right_ticks));
                None
            }
            (RobotDevice::Board(inbox, _), WorldOutput::Imu(_, m)) => {
                let _ = inbox.send(ToBoard::Imu(at(m.stamp).as_nanos(), m.gyro_z_rad_s));
                None
            }
            // The kit hears its own beacons: the cells' sound is not its.
            (RobotDevice::Kit(_), WorldOutput::Arrivals(..)) => None,
            (device, WorldOutput::Truth(i, t)) => {
                if let RobotDevice::Kit(pose) = device {
                    let _ = pose.send([t.x_m, t.y_m]);
                }
                Some(WorldOutput::Truth(
                    i,
                    Truth {
                        robot_clock: at(t.robot_clock),
                        ..t
                    },
                ))
            }
            (_, WorldOutput::Odometry(i, mut o)) => {
                o.stamp = at(o.stamp);
                Some(WorldOutput::Odometry(i, o))
            }
            (_, WorldOutput::Imu(i, mut m)) => {
                m.stamp = at(m.stamp);
                Some(WorldOutput::Imu(i, m))
            }
            (_, WorldOutput::Ranges(i, mut r)) => {
                r.stamp = at(r.stamp);
                Some(WorldOutput::Ranges(i, r))
            }
        }
    }
}

/// The robot an output belongs to.
fn robot_of(output: &WorldOutput) -> usize {
    match output {
        WorldOutput::Imu(i, _)
        | WorldOutput::Odometry(i, _)
        | WorldOutput::Ranges(i, _)
        | WorldOutput::Truth(i, _)
        | WorldOutput::Arrivals(i, _) => *i,
    }
}

/// A seed of its own for each device, from its label.
fn label_seed(label: &str) -> u64 {
    label.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// A board's clock: started at a random second (a board counts from its
/// power-up), drifting as its crystal does.
fn board_clock(spec: &mut BoardSpec, rng: &mut rand_chacha::ChaCha8Rng, jitter_ns: f64) {
    spec.clock_offset_ns = (uniform(rng, 1.0, 1_000.0) * 1e9) as i64;
    spec.drift_ppm = normal(rng, BOARD_DRIFT_SIGMA_PPM);
    spec.jitter_ns = jitter_ns;
}

/// Serves one board: one host at a time, firing armed bursts on time and
/// framing what the world feeds it.
async fn serve_board(
    listener: TcpListener,
    mut board: EmulatedBoard,
    mut inbox: mpsc::UnboundedReceiver<ToBoard>,
    emitted: mpsc::UnboundedSender<Emission>,
    label: String,
) {
    loop {
        let stream = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((s, _)) => s,
                Err(e) => {
                    tracing::warn!("world: device {label}: accept: {e}");
                    tokio::time::sleep(std::time::Duration::from_millis(100)).await;
                    continue;
                }
            },
            fed = inbox.recv() => match fed {
                // Nobody listening: framed (the board's counters move on) and lost.
                Some(m) => { let _ = feed(&mut board, m); continue; }
                None => return,
            },
        };
        let _ = stream.set_nodelay(true);
        tracing::info!("world: device {label}: host connected");
        let (mut reader, mut writer) = stream.into_split();
        let mut buf = [0u8; 4096];
        loop {
            let now_ns = system_now().as_nanos();
            let wait_ns = board.next_fire_ns().map_or(1_000_000_000, |t| {
                t.saturating_sub(now_ns).clamp(0, 1_000_000_000)
            });
            let mut out = tokio::select! {
                read = reader.read(&mut buf) => match read {
                    Ok(0) | Err(_) => break,
                    Ok(n) => board.on_bytes(system_now().as_nanos(), &buf[..n]),
                },
                fed = inbox.recv() => match fed {
                    Some(m) => feed(&mut board, m),
                    None => return,
                },
                _ = tokio::time::sleep(std::time::Duration::from_nanos(wait_ns as u64)) => Vec::new(),
            };
            let (fired, emissions) = board.fire_due(system_now().as_nanos());
            for e in emissions {
                let _ = emitted.send(e);
            }
            out.extend(fired);
            if !out.is_empty() && writer.write_all(&out).await.is_err() {
                break;
            }
        }
        tracing::info!("world: device {label}: host gone");
    }
}

/// The frames of what the world fed a board.
fn feed(board: &mut EmulatedBoard, m: ToBoard) -> Vec<u8> {
    let now_ns = system_now().as_nanos();
    match m {
        ToBoard::Arrivals(heard) => board.arrivals(now_ns, &heard),
        ToBoard::Ticks(t, left, right) => board.wheel_ticks(t, left, right),
        ToBoard::Imu(t, rate) => board.imu(t, rate),
    }
}

/// Serves one hedgehog: at its rate, it measures from where the world
/// last put the robot and writes the frames to the host, if one is connected.
async fn serve_kit(
    listener: TcpListener,
    mut hedgehog: EmulatedHedgehog,
    pose: watch::Receiver<[f64; 2]>,
    positions: mpsc::UnboundedSender<(usize, i64, [f64; 2])>,
    robot: usize,
    label: String,
) {
    let started = std::time::Instant::now();
    let mut tick = tokio::time::interval(std::time::Duration::from_secs_f64(hedgehog.period_s()));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut host: Option<(tokio::net::TcpStream, SocketAddr)> = None;
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((s, peer)) => {
                    let _ = s.set_nodelay(true);
                    tracing::info!("world: device {label}: host connected");
                    host = Some((s, peer));
                }
                Err(e) => tracing::warn!("world: device {label}: accept: {e}"),
            },
            _ = tick.tick() => {
                let at = *pose.borrow();
                if !at.iter().all(|v| v.is_finite()) {
                    continue;
                }
                let now_ns = system_now().as_nanos();
                let (bytes, reported) = hedgehog.measure(started.elapsed().as_secs_f64(), at);
                if let Some(p) = reported {
                    let _ = positions.send((robot, now_ns, p));
                }
                if let Some((s, _)) = host.as_mut()
                    && s.write_all(&bytes).await.is_err()
                {
                    tracing::info!("world: device {label}: host gone");
                    host = None;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::robot::{Arrival, Imu, Odometry, UltrasoundArrivals};

    #[test]
    fn every_device_has_a_seed_of_its_own() {
        assert_ne!(
            label_seed("cell/c1=transmitter-board@127.0.0.1:1"),
            label_seed("cell/c2=transmitter-board@127.0.0.1:1")
        );
    }

    #[test]
    fn an_endpoint_already_bound_is_refused_by_name() {
        let taken = StdListener::bind("127.0.0.1:0").unwrap();
        let e: DeviceEndpoint = format!("robot/r1=receiver-board@{}", taken.local_addr().unwrap())
            .parse()
            .unwrap();
        let err = BoundDevices::bind(&[e]).err().unwrap().to_string();
        assert!(err.contains("robot/r1=receiver-board@"), "{err}");
    }

    fn endpoint(text: &str) -> DeviceEndpoint {
        text.parse().unwrap()
    }

    fn arrivals(t_ns: i64) -> UltrasoundArrivals {
        UltrasoundArrivals {
            seq: 77,
            arrivals: vec![Arrival {
                tx_id: 11,
                receiver_id: 2,
                t_arrival: Time::from_nanos(t_ns),
            }],
        }
    }

    #[tokio::test]
    async fn a_robots_sensors_go_to_its_device_and_what_stays_public_is_on_the_true_time_base() {
        let site = Site::load_or_default(None).unwrap().0;
        let robots: Vec<String> = ["r1", "r2", "r3"].map(String::from).to_vec();
        let bound = BoundDevices::bind(&[
            endpoint("robot/r1=receiver-board@127.0.0.1:0"),
            endpoint("robot/r2=marvelmind@127.0.0.1:0"),
        ])
        .unwrap();
        let mut d = WorldDevices::start(bound, &site, &NoiseProfile::paper(), &robots, 1).unwrap();
        assert!(d.robot_on_device(0) && d.robot_on_device(1) && !d.robot_on_device(2));
        let epoch = Time::from_nanos(1_000_000_000_000);
        // The board's robot: arrivals go to the board and are shown numbered
        // as its groups, ticks and gyro go to the board only.
        let shown = d.route(WorldOutput::Arrivals(0, arrivals(5_000)), epoch);
        let Some(WorldOutput::Arrivals(0, a)) = shown else {
            panic!("{shown:?}")
        };
        assert_eq!(a.seq, 1);
        assert_eq!(a.arrivals[0].t_arrival.as_nanos(), 1_000_000_005_000);
        let odometry = Odometry {
            stamp: Time::from_nanos(7),
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            left_ticks: 1,
            right_ticks: 2,
        };
        assert_eq!(d.route(WorldOutput::Odometry(0, odometry), epoch), None);
        let gyro = Imu {
            stamp: Time::from_nanos(7),
            gyro_z_rad_s: 0.1,
        };
        assert_eq!(d.route(WorldOutput::Imu(0, gyro), epoch), None);
        // The kit's robot hears no cells; its odometry stays public, shifted.
        assert_eq!(
            d.route(WorldOutput::Arrivals(1, arrivals(5_000)), epoch),
            None
        );
        let Some(WorldOutput::Odometry(1, o)) = d.route(WorldOutput::Odometry(1, odometry), epoch)
        else {
            panic!("the kit robot's odometry is published")
        };
        assert_eq!(o.stamp.as_nanos(), 1_000_000_000_007);
        // A robot on no device is left as it is.
        assert_eq!(
            d.route(WorldOutput::Arrivals(2, arrivals(5_000)), epoch),
            Some(WorldOutput::Arrivals(2, arrivals(5_000)))
        );
        // Without transmitter boards, a cell's report is the emission.
        let burst = Burst {
            cell_id: "c1".into(),
            tx_id: 11,
            cycle: 3,
            scheduled: Time::from_nanos(10),
            actual: Time::from_nanos(12),
            epoch: 1,
        };
        assert_eq!(d.burst(burst.clone()), Some(burst));
    }

    #[tokio::test]
    async fn with_transmitter_boards_only_what_a_board_fired_makes_sound() {
        let site = Site::load_or_default(None).unwrap().0;
        let bound =
            BoundDevices::bind(&[endpoint("cell/c1=transmitter-board@127.0.0.1:0")]).unwrap();
        let mut d = WorldDevices::start(bound, &site, &NoiseProfile::paper(), &[], 1).unwrap();
        let burst = Burst {
            cell_id: "c1".into(),
            tx_id: 11,
            cycle: 3,
            scheduled: Time::from_nanos(2_000_000_000),
            actual: Time::from_nanos(2_000_000_000),
            epoch: 1,
        };
        assert_eq!(d.burst(burst.clone()), None);
        d.on_emission(Emission {
            tx_id: 11,
            reference_ns: 2_000_003_000,
        });
        let heard = d.burst(burst).unwrap();
        assert_eq!(heard.actual.as_nanos(), 2_000_003_000);
        assert_eq!(d.unmatched_reports(), 1);
    }

    #[tokio::test]
    async fn devices_of_cells_or_robots_the_world_does_not_have_are_refused() {
        let site = Site::load_or_default(None).unwrap().0;
        for e in [
            "cell/c9=transmitter-board@127.0.0.1:0",
            "robot/r7=receiver-board@127.0.0.1:0",
        ] {
            let bound = BoundDevices::bind(&[endpoint(e)]).unwrap();
            let err =
                WorldDevices::start(bound, &site, &NoiseProfile::paper(), &["r1".to_string()], 1)
                    .err()
                    .unwrap()
                    .to_string();
            assert!(err.contains(e.split('@').next().unwrap()), "{err}");
        }
    }
}
