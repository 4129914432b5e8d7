//! Watching the mesh of `ickon sim` with the launcher's own Zenoh session:
//! liveliness, bursts, arrivals, fixes, poses and the truth, into [`RunStats`].

use std::time::{Duration, Instant};

use ickon_proto::keys::{Key, Keys, RobotTopic};
use ickon_proto::msg::control::{Burst, CycleTrigger};
use ickon_proto::msg::robot::{RobotPose, Truth, UltrasoundArrivals};
use ickon_proto::site::Site;
use zenoh::sample::SampleKind;

use crate::args::Mesh;
use crate::args::SimArgs;
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
) -> anyhow::Result<zenoh::Session> {
    let mut config = crate::secure::base_config(credential)?;
    let set = |c: &mut zenoh::Config, k: &str, v: &str| {
        c.insert_json5(k, v)
            .map_err(|e| anyhow::anyhow!("zenoh config {k}: {e}"))
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
        .map_err(|e| anyhow::anyhow!("cannot open the observer's Zenoh session: {e}"))
}

/// Decodes a payload, counting what cannot be decoded instead of failing.
pub(crate) fn decode_or_count<T: serde::de::DeserializeOwned>(
    stats: &mut RunStats,
    key: &str,
    payload: &[u8],
) -> Option<T> {
    match ickon_proto::decode(payload) {
        Ok(v) => Some(v),
        Err(e) => {
            tracing::warn!("undecodable message on {key}: {e}");
            *stats.bad_messages.entry(key.to_string()).or_default() += 1;
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
    alive: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    sup: &mut supervisor::Supervisor,
    quiet: bool,
    credential: Option<&std::path::Path>,
    shutdown: &mut (impl std::future::Future<Output = ()> + Unpin),
) -> anyhow::Result<(RunStats, Option<String>)> {
    let z = |e: zenoh::Error| anyhow::anyhow!("{e}");
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
    let triggers = session
        .declare_subscriber(keys.central_cycle())
        .await
        .map_err(z)?;

    // The plain one-hop latency: a second session in this process subscribes
    // to probes the observer publishes; both share this process's clock.
    let probe_session = match open_observer(hub, args.mesh, credential).await {
        Ok(s) => s,
        // The router died between the nodes' start and this session (a
        // test kills it as soon as the run is up): say which node, as the
        // run would have a moment later, not only that nothing connects.
        Err(e) => match sup.first_dead() {
            Some(dead) => anyhow::bail!(
                "node {} {} while the simulation was starting ({e})",
                dead.name,
                dead.status
            ),
            None => return Err(e),
        },
    };
    let probe_sub = probe_session
        .declare_subscriber(keys.sim_probe())
        .await
        .map_err(z)?;
    let probe_pub = session
        .declare_publisher(keys.sim_probe())
        .express(true)
        .await
        .map_err(z)?;
    let mut probes_sent: std::collections::HashMap<u64, Instant> = Default::default();
    let mut probe_seq = 0u64;

    let mut stats = RunStats {
        tx_cells: site
            .transmitters
            .iter()
            .map(|t| (t.id, t.cell.clone()))
            .collect(),
        ..RunStats::default()
    };
    for r in site.robots.iter().take(args.robots) {
        stats.robots.insert(r.id.clone(), Default::default());
    }
    let started = Instant::now();
    let end = tokio::time::Instant::now() + Duration::from_secs_f64(args.duration);
    let mut status_tick = tokio::time::interval(Duration::from_secs(1));
    let mut probe_tick = tokio::time::interval(Duration::from_millis(100));
    let mut last_burst: std::collections::HashMap<String, Instant> = Default::default();
    // Faults of `--faults`, in time order, and the SIGCONTs they owe.
    let mut plan: std::collections::VecDeque<crate::faults::Fault> = args
        .faults
        .as_deref()
        .map(crate::faults::parse_plan)
        .transpose()?
        .unwrap_or_default()
        .into();
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
            Ok(s) = bursts.recv_async() => {
                let key = s.key_expr().as_str().to_string();
                if let Some(b) = decode_or_count::<Burst>(&mut stats, &key, &s.payload().to_bytes()) {
                    last_burst.insert(b.cell_id.clone(), Instant::now());
                    stats.cells.entry(b.cell_id.clone()).or_default().on_burst(&b);
                }
            }
            Ok(s) = arrivals.recv_async() => {
                let at = Instant::now();
                let key = s.key_expr().as_str().to_string();
                if let (Ok(Key::Robot(id, _)), Some(m)) = (keys.parse(&key), decode_or_count::<UltrasoundArrivals>(&mut stats, &key, &s.payload().to_bytes())) {
                    stats.robots.entry(id).or_default().on_arrivals(m.seq, at);
                }
            }
            Ok(s) = fixes.recv_async() => {
                let at = Instant::now();
                let key = s.key_expr().as_str().to_string();
                if let Ok(Key::Robot(id, _)) = keys.parse(&key) {
                    if decode_or_count::<ickon_proto::msg::robot::Fix>(&mut stats, &key, &s.payload().to_bytes()).is_some() {
                        stats.robots.entry(id).or_default().on_fix(at);
                    }
                }
            }
            Ok(s) = poses.recv_async() => {
                let at = Instant::now();
                let key = s.key_expr().as_str().to_string();
                if let (Ok(Key::Robot(id, _)), Some(p)) = (keys.parse(&key), decode_or_count::<RobotPose>(&mut stats, &key, &s.payload().to_bytes())) {
                    stats.robots.entry(id).or_default().on_pose(&p, at);
                }
            }
            Ok(s) = triggers.recv_async() => {
                let key = s.key_expr().as_str().to_string();
                if let Some(t) = decode_or_count::<CycleTrigger>(&mut stats, &key, &s.payload().to_bytes()) {
                    stats.on_trigger(&t, Instant::now());
                }
            }
            Ok(s) = truth.recv_async() => {
                let key = s.key_expr().as_str().to_string();
                if let (Ok(Key::SimTruth(id)), Some(t)) = (keys.parse(&key), decode_or_count::<Truth>(&mut stats, &key, &s.payload().to_bytes())) {
                    stats.robots.entry(id).or_default().on_truth(t);
                }
            }
            Ok(s) = probe_sub.recv_async() => {
                let at = Instant::now();
                if let Ok(seq) = ickon_proto::decode::<u64>(&s.payload().to_bytes()) {
                    if let Some(sent) = probes_sent.remove(&seq) {
                        stats.hop_latencies_us.push(at.duration_since(sent).as_secs_f64() * 1e6);
                    }
                }
            }
            _ = probe_tick.tick() => {
                probe_seq += 1;
                probes_sent.insert(probe_seq, Instant::now());
                if let Ok(bytes) = ickon_proto::encode(&probe_seq) {
                    let _ = probe_pub.put(bytes).await;
                }
                probes_sent.retain(|_, t| t.elapsed() < Duration::from_secs(5));
            }
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
                    let line = status_line(&stats, &last_burst, site.cells.len(), started);
                    if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
                        eprint!("\r{line}");
                    } else if started.elapsed().as_secs() % 5 == 0 {
                        // A log, not a terminal: a line every five seconds.
                        eprintln!("{}", line.trim_end());
                    }
                }
            }
        }
    };
    if !quiet {
        eprintln!();
    }
    // Undeclared before the sessions close, so that nothing arrives for a
    // subscriber a closing session no longer knows.
    for s in [bursts, arrivals, fixes, poses, truth, triggers, probe_sub] {
        let _ = s.undeclare().await;
    }
    let _ = probe_pub.undeclare().await;
    let _ = probe_session.close().await;
    Ok((stats, failure))
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
