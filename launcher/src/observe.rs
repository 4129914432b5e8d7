//! Watching the mesh of `ickon sim` with the launcher's own Zenoh session:
//! liveliness, bursts, arrivals, fixes, poses and the truth, into [`RunStats`].

use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

use ickon_proto::keys::{Key, Keys, RobotTopic};
use ickon_proto::msg::control::{Burst, CycleTrigger};
use ickon_proto::msg::robot::{RobotPose, Truth, UltrasoundArrivals};
use ickon_proto::site::Site;
use zenoh::handlers::FifoChannelHandler;
use zenoh::sample::{Sample, SampleKind};

use crate::args::Mesh;
use crate::args::SimArgs;
use crate::error::LaunchError;
use crate::metrics::RunStats;
use crate::report::status_line;
use crate::supervisor;

/// The launcher's own session: a client of the run's router, or a peer of
/// the full mesh (`Mesh::Peer`), connected to `hub`; with `--secure`,
/// authenticated by the credential in `credential` (a client configuration).
pub(crate) async fn open_observer(
    hub: &str,
    mesh: Mesh,
    credential: Option<&std::path::Path>,
) -> Result<zenoh::Session, LaunchError> {
    let mut config = crate::secure::base_config(credential)?;
    let set = |c: &mut zenoh::Config, k: &str, v: &str| {
        c.insert_json5(k, v).map_err(|e| LaunchError::ZenohConfig {
            key: k.to_string(),
            message: e.to_string(),
        })
    };
    match mesh {
        Mesh::Router => set(&mut config, "mode", "\"client\"")?,
        Mesh::Peer => {
            set(&mut config, "mode", "\"peer\"")?;
            set(&mut config, "listen/endpoints", "[\"tcp/127.0.0.1:0\"]")?;
        }
    }
    set(&mut config, "connect/endpoints", &format!("[\"{hub}\"]"))?;
    set(&mut config, "scouting/multicast/enabled", "false")?;
    zenoh::open(config)
        .await
        .map_err(|e| LaunchError::Session(e.to_string()))
}

/// Decodes a payload, counting what cannot be decoded instead of failing.
/// Logged like the nodes log bad input (the first of each message type,
/// then one line per window with the count held back): anyone on the
/// mesh can put garbage, and a line per message would flood the log.
pub(crate) fn decode_or_count<T: serde::de::DeserializeOwned>(
    stats: &mut RunStats,
    key: &str,
    payload: &[u8],
) -> Option<T> {
    match ickon_proto::decode(payload) {
        Ok(v) => Some(v),
        Err(e) => {
            let kind = std::any::type_name::<T>()
                .rsplit("::")
                .next()
                .unwrap_or("message");
            if let Some(held) = stats.bad_log.admit(kind, Instant::now()) {
                tracing::warn!(
                    "undecodable {kind} on {key}: {e} ({held} more undecodable {kind} since the last report)"
                );
            }
            stats.count_bad_message(key);
            None
        }
    }
}

/// Watches the running mesh until the duration is over, Ctrl-C or SIGTERM, or a node dies.
/// Returns what was measured and, if the run failed, why.
#[allow(clippy::too_many_arguments)]
pub(crate) async fn observe(
    args: &SimArgs,
    site: &Site,
    keys: &Keys,
    session: &zenoh::Session,
    hub: &str,
    alive: &Sub,
    sup: &mut supervisor::Supervisor,
    quiet: bool,
    credential: Option<&std::path::Path>,
    shutdown: &mut (impl std::future::Future<Output = ()> + Unpin),
) -> Result<(RunStats, Option<String>), LaunchError> {
    let subs = MeshSubs::declare(session, keys).await?;
    let mut probe = Probe::open(args, hub, credential, sup, session, keys).await?;
    let mut stats = new_stats(site, args.robots);
    let started = Instant::now();
    let end = tokio::time::Instant::now() + Duration::from_secs_f64(args.duration);
    let mut status_tick = tokio::time::interval(Duration::from_secs(1));
    let mut probe_tick = tokio::time::interval(Duration::from_millis(100));
    let mut last_burst: HashMap<String, Instant> = Default::default();
    // Faults of `--faults`, in time order, and the SIGCONTs they owe.
    let mut plan = fault_plan(args)?;
    let mut resume: Vec<(Instant, String)> = Vec::new();
    let mut fault_tick = tokio::time::interval(Duration::from_millis(20));
    let failure = loop {
        tokio::select! {
            _ = tokio::time::sleep_until(end) => break None,
            _ = &mut *shutdown => {
                if !quiet { eprintln!("\nickon sim: interrupted, stopping every node"); }
                break Some("interrupted (Ctrl-C or SIGTERM)".to_string());
            }
            Ok(s) = alive.recv_async() => {
                if s.kind() == SampleKind::Delete {
                    tracing::warn!("{} went away", s.key_expr());
                }
            }
            Ok(s) = subs.bursts.recv_async() => note_burst(&s, &mut stats, &mut last_burst),
            Ok(s) = subs.arrivals.recv_async() => note_arrivals(keys, &s, &mut stats),
            Ok(s) = subs.fixes.recv_async() => note_fix(keys, &s, &mut stats),
            Ok(s) = subs.poses.recv_async() => note_pose(keys, &s, &mut stats),
            Ok(s) = subs.triggers.recv_async() => note_trigger(&s, &mut stats),
            Ok(s) = subs.truth.recv_async() => note_truth(keys, &s, &mut stats),
            Ok(s) = subs.kits.recv_async() => note_kit(keys, &s, &mut stats),
            Ok(s) = probe.sub.recv_async() => probe.received(&s, &mut stats),
            _ = probe_tick.tick() => probe.send().await,
            _ = fault_tick.tick(), if args.restart || !plan.is_empty() || !resume.is_empty() => {
                inject_due(&mut plan, &mut resume, sup, args.restart, started, &mut stats);
                // A dead node is started again within a tick, as systemd would at once.
                if args.restart {
                    for dead in sup.restart_dead() {
                        tracing::info!("{} {}: restarted", dead.name, dead.status);
                        stats.restarts.push(dead.name);
                    }
                }
            }
            _ = status_tick.tick() => {
                // With --restart a dead node is started again on the fault tick.
                if let Some(dead) = sup.first_dead().filter(|_| !args.restart) {
                    break Some(format!("node {} {} while the simulation was running", dead.name, dead.status));
                }
                if !quiet {
                    print_status(&status_line(&stats, &last_burst, site.cells.len(), started), started);
                }
            }
        }
    };
    if !quiet {
        eprintln!();
    }
    // Undeclared before the sessions close, so that nothing arrives for a
    // subscriber a closing session no longer knows.
    subs.undeclare(probe.sub).await;
    let _ = probe.publisher.undeclare().await;
    let _ = probe.session.close().await;
    Ok((stats, failure))
}

/// A subscriber with its queue.
pub(crate) type Sub = zenoh::pubsub::Subscriber<FifoChannelHandler<Sample>>;

/// The observer's subscribers to what the mesh publishes.
struct MeshSubs {
    bursts: Sub,
    arrivals: Sub,
    fixes: Sub,
    poses: Sub,
    truth: Sub,
    kits: Sub,
    triggers: Sub,
}

impl MeshSubs {
    /// Subscribes to the bursts, arrivals, fixes, poses, truth and cycle
    /// triggers of the site named by `keys`.
    async fn declare(session: &zenoh::Session, keys: &Keys) -> Result<Self, LaunchError> {
        let z = LaunchError::declare;
        let bursts = session
            .declare_subscriber(keys.cell_burst_all())
            .await
            .map_err(z)?;
        let arrivals = session
            .declare_subscriber(keys.robot_all(RobotTopic::Ultrasound))
            .await
            .map_err(z)?;
        let fixes = session
            .declare_subscriber(keys.robot_all(RobotTopic::Fix))
            .await
            .map_err(z)?;
        let poses = session
            .declare_subscriber(keys.robot_all(RobotTopic::Pose))
            .await
            .map_err(z)?;
        let truth = session
            .declare_subscriber(keys.sim_truth_all())
            .await
            .map_err(z)?;
        let kits = session
            .declare_subscriber(keys.sim_kit_all())
            .await
            .map_err(z)?;
        let triggers = session
            .declare_subscriber(keys.central_cycle())
            .await
            .map_err(z)?;
        Ok(Self {
            bursts,
            arrivals,
            fixes,
            poses,
            truth,
            kits,
            triggers,
        })
    }

    /// Undeclares every subscriber, then `probe_sub`.
    async fn undeclare(self, probe_sub: Sub) {
        let Self {
            bursts,
            arrivals,
            fixes,
            poses,
            truth,
            kits,
            triggers,
        } = self;
        for s in [
            bursts, arrivals, fixes, poses, truth, kits, triggers, probe_sub,
        ] {
            let _ = s.undeclare().await;
        }
    }
}

/// The plain one-hop latency: a second session in this process subscribes
/// to probes the observer publishes; both share this process's clock.
struct Probe {
    session: zenoh::Session,
    sub: Sub,
    publisher: zenoh::pubsub::Publisher<'static>,
    /// When each probe still awaited was sent, by sequence number.
    sent: HashMap<u64, Instant>,
    seq: u64,
}

impl Probe {
    /// Opens the second session and declares the probe's subscriber on it
    /// and its publisher on `session`.
    async fn open(
        args: &SimArgs,
        hub: &str,
        credential: Option<&std::path::Path>,
        sup: &mut supervisor::Supervisor,
        session: &zenoh::Session,
        keys: &Keys,
    ) -> Result<Self, LaunchError> {
        let z = LaunchError::declare;
        let probe_session = match open_observer(hub, args.mesh, credential).await {
            Ok(s) => s,
            // The router died between the nodes' start and this session (a
            // test kills it as soon as the run is up): say which node, as the
            // run would have a moment later, not only that nothing connects.
            Err(e) => return Err(died_before_probe(sup, e).await),
        };
        let sub = probe_session
            .declare_subscriber(keys.sim_probe())
            .await
            .map_err(z)?;
        let publisher = session
            .declare_publisher(keys.sim_probe())
            .express(true)
            .await
            .map_err(z)?;
        Ok(Self {
            session: probe_session,
            sub,
            publisher,
            sent: Default::default(),
            seq: 0,
        })
    }

    /// Records the latency of a probe that came back.
    fn received(&mut self, s: &Sample, stats: &mut RunStats) {
        let at = Instant::now();
        if let Ok(seq) = ickon_proto::decode::<u64>(&s.payload().to_bytes())
            && let Some(sent) = self.sent.remove(&seq)
        {
            stats
                .hop_latencies_us
                .push(at.duration_since(sent).as_secs_f64() * 1e6);
        }
    }

    /// Sends the next probe and forgets those lost for five seconds.
    async fn send(&mut self) {
        self.seq += 1;
        self.sent.insert(self.seq, Instant::now());
        if let Ok(bytes) = ickon_proto::encode(&self.seq) {
            let _ = self.publisher.put(bytes).await;
        }
        self.sent
            .retain(|_, t| t.elapsed() < Duration::from_secs(5));
    }
}

/// Empty statistics for the site's transmitters and its first `robots`
/// robots: the only robots whose messages are counted (anyone on the mesh
/// can put under other ids).
fn new_stats(site: &Site, robots: usize) -> RunStats {
    let mut stats = RunStats {
        tx_cells: site
            .transmitters
            .iter()
            .map(|t| (t.id, t.cell.clone()))
            .collect(),
        tx_positions: site
            .transmitters
            .iter()
            .map(|t| (t.id, t.position_m))
            .collect(),
        msu_height_m: site.msu.height_m,
        ..RunStats::default()
    };
    for r in site.robots.iter().take(robots) {
        stats.robots.insert(r.id.clone(), Default::default());
    }
    stats
}

/// The faults of `--faults`, in time order (none without it).
fn fault_plan(args: &SimArgs) -> Result<VecDeque<crate::faults::Fault>, LaunchError> {
    Ok(args
        .faults
        .as_deref()
        .map(crate::faults::parse_plan)
        .transpose()?
        .unwrap_or_default()
        .into())
}

/// Prints the status line: in place on a terminal, every five seconds to
/// a log.
fn print_status(line: &str, started: Instant) {
    if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        eprint!("\r{line}");
    } else if started.elapsed().as_secs().is_multiple_of(5) {
        // A log, not a terminal: a line every five seconds.
        eprintln!("{}", line.trim_end());
    }
}

/// A cell's burst: when its cell last fired, and its statistics.
fn note_burst(s: &Sample, stats: &mut RunStats, last_burst: &mut HashMap<String, Instant>) {
    let key = s.key_expr().as_str().to_string();
    if let Some(b) = decode_or_count::<Burst>(stats, &key, &s.payload().to_bytes()) {
        // Only a transmitter of the site fired by its own cell: made-up
        // ids, however many, grow nothing.
        if stats.tx_cells.get(&b.tx_id) != Some(&b.cell_id) {
            return;
        }
        last_burst.insert(b.cell_id.clone(), Instant::now());
        stats
            .cells
            .entry(b.cell_id.clone())
            .or_default()
            .on_burst(&b);
    }
}

/// A robot's ultrasound arrivals.
fn note_arrivals(keys: &Keys, s: &Sample, stats: &mut RunStats) {
    let at = Instant::now();
    let key = s.key_expr().as_str().to_string();
    if let (Ok(Key::Robot(id, _)), Some(m)) = (
        keys.parse(&key),
        decode_or_count::<UltrasoundArrivals>(stats, &key, &s.payload().to_bytes()),
    ) && let Some(r) = stats.robots.get_mut(&id)
    {
        r.on_arrivals(m.seq, at);
    }
}

/// A robot's fix.
fn note_fix(keys: &Keys, s: &Sample, stats: &mut RunStats) {
    let at = Instant::now();
    let key = s.key_expr().as_str().to_string();
    if let Ok(Key::Robot(id, _)) = keys.parse(&key)
        && let Some(fix) =
            decode_or_count::<ickon_proto::msg::robot::Fix>(stats, &key, &s.payload().to_bytes())
    {
        let hdop = stats.fix_hdop(&fix);
        if let Some(robot) = stats.robots.get_mut(&id) {
            robot.on_fix(at);
            robot.on_fix_geometry(fix.used.len(), hdop);
        }
    }
}

/// A robot's pose.
fn note_pose(keys: &Keys, s: &Sample, stats: &mut RunStats) {
    let at = Instant::now();
    let key = s.key_expr().as_str().to_string();
    if let (Ok(Key::Robot(id, _)), Some(p)) = (
        keys.parse(&key),
        decode_or_count::<RobotPose>(stats, &key, &s.payload().to_bytes()),
    ) && let Some(r) = stats.robots.get_mut(&id)
    {
        r.on_pose(&p, at);
    }
}

/// A cycle trigger of the central unit.
fn note_trigger(s: &Sample, stats: &mut RunStats) {
    let key = s.key_expr().as_str().to_string();
    if let Some(t) = decode_or_count::<CycleTrigger>(stats, &key, &s.payload().to_bytes()) {
        stats.on_trigger(&t, Instant::now());
    }
}

/// A robot's true pose from the simulation.
fn note_truth(keys: &Keys, s: &Sample, stats: &mut RunStats) {
    let key = s.key_expr().as_str().to_string();
    if let (Ok(Key::SimTruth(id)), Some(t)) = (
        keys.parse(&key),
        decode_or_count::<Truth>(stats, &key, &s.payload().to_bytes()),
    ) && let Some(r) = stats.robots.get_mut(&id)
    {
        r.on_truth(t);
    }
}

/// A position a robot's emulated ranging kit reported.
fn note_kit(keys: &Keys, s: &Sample, stats: &mut RunStats) {
    let key = s.key_expr().as_str().to_string();
    if let (Ok(Key::SimKit(id)), Some(t)) = (
        keys.parse(&key),
        decode_or_count::<Truth>(stats, &key, &s.payload().to_bytes()),
    ) && let Some(r) = stats.robots.get_mut(&id)
    {
        r.on_kit_position(&t);
    }
}

/// Carries out every planned fault whose time has come (times from
/// `started`), and resumes the nodes whose stop is over.
fn inject_due(
    plan: &mut std::collections::VecDeque<crate::faults::Fault>,
    resume: &mut Vec<(Instant, String)>,
    sup: &mut supervisor::Supervisor,
    restart: bool,
    started: Instant,
    stats: &mut RunStats,
) {
    use crate::faults::FaultAction;
    use nix::sys::signal::Signal;
    let now = Instant::now();
    resume.retain(|(at, name)| {
        if now < *at {
            return true;
        }
        sup.signal(name, Signal::SIGCONT);
        false
    });
    while plan.front().is_some_and(|f| now >= started + f.at) {
        let Some(f) = plan.pop_front() else { break };
        let done = match f.action {
            FaultAction::Kill => sup.kill_planned(&f.node, restart),
            FaultAction::Stop(d) => {
                let stopped = sup.signal(&f.node, Signal::SIGSTOP);
                if stopped {
                    resume.push((now + d, f.node.clone()));
                }
                stopped
            }
            // The node takes the next step of its `--sim-clock-steps-us`.
            FaultAction::ClockStep(_) => sup.signal(&f.node, Signal::SIGUSR1),
        };
        if done {
            stats
                .faults_done
                .push((f.text.clone(), now.duration_since(started).as_secs_f64()));
        } else {
            tracing::warn!("fault {} not carried out: no such node running", f.text);
        }
    }
}

/// What to report when the probe session could not connect: the node that
/// died (a router killed as the run came up), if one did within
/// [`DEATH_GRACE`], else `why`. A killed process is seen dead a moment
/// after the connection it served fails, not always at once.
async fn died_before_probe(sup: &mut supervisor::Supervisor, why: LaunchError) -> LaunchError {
    let deadline = tokio::time::Instant::now() + DEATH_GRACE;
    loop {
        if let Some(dead) = sup.first_dead() {
            return LaunchError::DiedBeforeProbe {
                name: dead.name,
                status: dead.status,
                why: Box::new(why),
            };
        }
        if tokio::time::Instant::now() >= deadline {
            return why;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// How long a node whose death made a connection fail may take to be seen
/// dead.
const DEATH_GRACE: Duration = Duration::from_secs(1);
