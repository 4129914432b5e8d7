//! The cell controller as a Zenoh node: keeps its clock synchronised over
//! `central/clock`, plans the bursts of every `central/cycle` trigger, fires
//! them through a [`TransmitterDriver`], and reports bursts and status.
//!
//! The simulation driver stands in for the transmitter hardware, which fires
//! on its own clock with microsecond precision once programmed (a little
//! ahead of time, see [`crate::timer`]): the burst report carries the true
//! time at which the cell's clock reads the programmed local time, and goes
//! out when the burst is programmed, before the sound could arrive. So the
//! operating system's timer jitter does not enter the measurement; the
//! synchronisation error does.
//!
//! When the central unit goes away the cell keeps its schedules and waits
//! for triggers; when it comes back (its liveliness token reappears) the cell
//! starts its clock synchronisation afresh and takes the schedule from the
//! new central unit, which numbers its versions anew.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::future::Future;
use std::process::ExitCode;
use std::time::Duration as StdDuration;

use clap::Args;
use ickon_proto::keys::Keys;
use ickon_proto::msg::control::{
    Burst, CellStatus, ClockReply, ClockRequest, CycleTrigger, Schedule,
};
use ickon_proto::time::{Duration, Time};
use ickon_proto::{decode, encode};
use ickon_runtime::{NodeArgs, SimulatedClock, Stamped, query_once, query_stamped, zerr};
use zenoh::Session;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::SampleKind;

use crate::sync::{ClockSample, SyncConfig, SyncSlave};
use crate::timer::{BurstTimer, PROGRAM_AHEAD, PlannedBurst, TransmitterDriver};

/// Arguments of `ickon-cell` (and `ickon node cell`).
#[derive(Debug, Clone, Args)]
pub struct CellArgs {
    /// Connection and simulation flags.
    #[command(flatten)]
    pub node: NodeArgs,
    /// The cell this controller drives.
    #[arg(long)]
    pub cell: String,
}

/// Clock exchanges at start-up come this often...
const FAST_SYNC: StdDuration = StdDuration::from_millis(20);
/// ...for this many exchanges (2 s: the drift is fitted after 1.5 s, from
/// the best of many), then every [`SLOW_SYNC`].
const FAST_SYNC_COUNT: u32 = 100;
/// Steady-state clock exchange period (the window of 100 spans 25 s).
const SLOW_SYNC: StdDuration = StdDuration::from_millis(250);
/// Status reports this often.
const STATUS_EVERY: StdDuration = StdDuration::from_secs(1);

/// The simulation's transmitter driver: records each burst with its true
/// emission time (see the module documentation).
struct SimulatedDriver {
    cell_id: String,
    clock: SimulatedClock,
    fired: Vec<Burst>,
}

impl TransmitterDriver for SimulatedDriver {
    fn fire(&mut self, b: &PlannedBurst) {
        self.fired.push(Burst {
            cell_id: self.cell_id.clone(),
            tx_id: b.tx_id,
            cycle: b.cycle,
            scheduled: b.master,
            actual: self.clock.true_time(b.local),
        });
    }
}

/// Runs the cell controller as a process until Ctrl-C/SIGTERM.
pub fn main_with(args: CellArgs) -> ExitCode {
    if let Err(e) = ickon_proto::keys::validate_id(&args.cell) {
        eprintln!("error: --cell: {e}");
        return ExitCode::from(2);
    }
    ickon_runtime::run_node(1, async {
        let session = args.node.open().await?;
        let r = run(&session, &args, args.node.shutdown()).await;
        let _ = session.close().await;
        r
    })
}

/// One four-timestamp exchange with the master; `None` if it did not answer.
/// `t4` is read in Zenoh's receive path (see [`query_stamped`]); `t1` is the
/// middle of the time Zenoh took to send the request.
async fn exchange(
    session: &Session,
    keys: &Keys,
    cell: &str,
    clock: &SimulatedClock,
) -> anyhow::Result<Option<ClockSample>> {
    let t1 = clock.now();
    let request = encode(&ClockRequest {
        cell_id: cell.to_string(),
        t1,
    })?;
    let stamp_clock = *clock;
    let reply: Option<Stamped<ClockReply>> = query_stamped(
        session,
        &keys.central_clock(),
        request,
        StdDuration::from_millis(500),
        move || stamp_clock.now(),
    )
    .await?;
    // The request left some time between the call and Zenoh having queued
    // it; that takes a few hundred microseconds on a busy machine, which
    // counted whole would make the outward leg look longer than it is.
    Ok(reply.filter(|r| r.value.t1 == t1).map(|r| ClockSample {
        t1: Time::from_nanos(t1.as_nanos() + r.sent.since(t1).as_nanos() / 2),
        t2: r.value.t2,
        t3: r.value.t3,
        t4: r.received,
    }))
}

/// Drives cell `args.cell` until `shutdown` completes.
pub async fn run(
    session: &Session,
    args: &CellArgs,
    shutdown: impl Future<Output = ()>,
) -> anyhow::Result<()> {
    let mut shutdown = Box::pin(shutdown);
    let keys = Keys::new(&args.node.site_name)?;
    let cell = args.cell.as_str();
    let clock = args.node.clock();
    let mut driver = SimulatedDriver {
        cell_id: cell.to_string(),
        clock,
        fired: Vec::new(),
    };
    let mut sync = SyncSlave::new(SyncConfig::default());
    let mut timer = BurstTimer::new(cell, Duration::from_millis(1));
    let triggers = session
        .declare_subscriber(keys.central_cycle())
        .await
        .map_err(zerr)?;
    let schedules = session
        .declare_subscriber(keys.central_schedule())
        .await
        .map_err(zerr)?;
    let central_alive = session
        .liveliness()
        .declare_subscriber(keys.alive_central())
        .history(true)
        .await
        .map_err(zerr)?;
    let mut central_lost = false;
    let burst_pub = session
        .declare_publisher(keys.cell_burst(cell)?)
        .express(true)
        .priority(Priority::RealTime)
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(zerr)?;
    let status_pub = session
        .declare_publisher(keys.cell_status(cell)?)
        .await
        .map_err(zerr)?;
    // The schedule in force now (a new one, made when the central unit sees
    // the token below, arrives on the subscriber declared above).
    if let Ok(Some(s)) = query_once::<Schedule>(
        session,
        &keys.central_schedule(),
        None,
        StdDuration::from_millis(200),
    )
    .await
    {
        timer.add_schedule(s);
    }
    // Declared last: the central unit schedules this cell when it sees the
    // token, and by then the cell hears schedules and triggers.
    let _token = session
        .liveliness()
        .declare_token(keys.alive_cell(cell)?)
        .await
        .map_err(zerr)?;

    // Planned bursts by master time: each is programmed PROGRAM_AHEAD
    // before its time with the estimate of that moment.
    let mut pending: BinaryHeap<Reverse<(Time, u32, u64, Time)>> = BinaryHeap::new();
    let mut exchanges = 0u32;
    let mut next_sync = tokio::time::Instant::now();
    let mut status_tick = tokio::time::interval(STATUS_EVERY);
    let (mut cycles_fired, mut last_cycle_fired, mut skipped) = (0u64, 0u64, 0u64);
    let mut faults: Vec<String> = Vec::new();
    tracing::info!(
        "cell {cell}: up, clock offset {} us, drift {} ppm",
        args.node.clock_offset_us,
        args.node.clock_drift_ppm
    );

    loop {
        let estimate = sync.estimate();
        let next_program =
            pending
                .peek()
                .zip(estimate.as_ref())
                .map(|(Reverse((master, ..)), e)| {
                    (e.to_local(*master) - PROGRAM_AHEAD)
                        .since(clock.now())
                        .to_std()
                });
        tokio::select! {
            _ = &mut shutdown => break,
            _ = tokio::time::sleep(next_program.unwrap_or(StdDuration::from_secs(3600))), if next_program.is_some() => {
                let now = clock.now();
                let mut fired_cycles = Vec::new();
                while let (Some(Reverse((master, tx_id, cycle, planned))), Some(e)) = (pending.peek().copied(), estimate.as_ref()) {
                    if e.to_local(master) - PROGRAM_AHEAD > now {
                        break;
                    }
                    pending.pop();
                    let burst = PlannedBurst { tx_id, cycle, master, local: planned };
                    match timer.program(&burst, e, now) {
                        Some(b) => {
                            driver.fire(&b);
                            fired_cycles.push(cycle);
                        }
                        None => {
                            tracing::warn!("cell {cell}: cycle {cycle}: tx {tx_id} skipped (woken too late to program it)");
                            skipped += 1;
                        }
                    }
                }
                for b in driver.fired.drain(..) {
                    burst_pub.put(encode(&b)?).await.map_err(zerr)?;
                }
                for c in fired_cycles {
                    if c != last_cycle_fired || cycles_fired == 0 {
                        cycles_fired += 1;
                        last_cycle_fired = c;
                    }
                }
            }
            _ = tokio::time::sleep_until(next_sync) => {
                match exchange(session, &keys, cell, &clock).await {
                    Ok(Some(sample)) => { sync.add(sample); }
                    Ok(None) => tracing::debug!("cell {cell}: no clock reply"),
                    Err(e) => tracing::debug!("cell {cell}: clock exchange failed: {e}"),
                }
                exchanges += 1;
                next_sync = tokio::time::Instant::now() + if exchanges < FAST_SYNC_COUNT { FAST_SYNC } else { SLOW_SYNC };
            }
            Ok(s) = central_alive.recv_async() => {
                if s.kind() == SampleKind::Delete {
                    tracing::warn!("cell {cell}: central unit gone; keeping the schedule, waiting for triggers");
                    central_lost = true;
                } else if central_lost {
                    tracing::info!("cell {cell}: central unit back; synchronising afresh");
                    central_lost = false;
                    sync = SyncSlave::new(SyncConfig::default());
                    exchanges = 0;
                    next_sync = tokio::time::Instant::now();
                    timer.forget_schedules();
                    if let Ok(Some(s)) = query_once::<Schedule>(session, &keys.central_schedule(), None, StdDuration::from_millis(500)).await {
                        timer.add_schedule(s);
                    }
                }
            }
            Ok(s) = schedules.recv_async() => {
                match decode::<Schedule>(&s.payload().to_bytes()) {
                    Ok(schedule) => timer.add_schedule(schedule),
                    Err(e) => tracing::warn!("cell {cell}: undecodable schedule: {e}"),
                }
            }
            Ok(s) = triggers.recv_async() => {
                let trigger = match decode::<CycleTrigger>(&s.payload().to_bytes()) {
                    Ok(t) => t,
                    Err(e) => { tracing::warn!("cell {cell}: undecodable trigger: {e}"); continue; }
                };
                if !timer.has_schedule(trigger.schedule_version) {
                    // A cell that started late (or missed a put) asks for the schedule.
                    if let Ok(Some(s)) = query_once::<Schedule>(session, &keys.central_schedule(), None, StdDuration::from_millis(200)).await {
                        timer.add_schedule(s);
                    }
                }
                match timer.plan(&trigger, sync.estimate().as_ref(), clock.now()) {
                    Ok(plan) => {
                        if plan.skipped > 0 {
                            tracing::warn!("cell {cell}: cycle {}: {} slots skipped (trigger too late)", trigger.cycle, plan.skipped);
                        }
                        skipped += plan.skipped;
                        for b in plan.bursts {
                            pending.push(Reverse((b.master, b.tx_id, b.cycle, b.local)));
                        }
                        faults.clear();
                    }
                    Err(e) => {
                        tracing::debug!("cell {cell}: cycle {} not fired: {e}", trigger.cycle);
                        faults = vec![e.to_string()];
                    }
                }
            }
            _ = status_tick.tick() => {
                let est = sync.estimate();
                let status = CellStatus {
                    cell_id: cell.to_string(),
                    stamp: est.map_or(clock.now(), |e| e.to_master(clock.now())),
                    offset_ns: est.map_or(0, |e| e.offset_ns.round() as i64),
                    drift_ppb: est.map_or(0, |e| (e.drift * 1e9).round() as i64),
                    offset_sigma_ns: est.map_or(0, |e| e.sigma_ns.round() as i64),
                    sync_samples: u32::try_from(sync.len()).unwrap_or(u32::MAX),
                    last_cycle_fired,
                    cycles_fired,
                    slots_skipped: skipped,
                    faults: faults.clone(),
                };
                status_pub.put(encode(&status)?).await.map_err(zerr)?;
            }
        }
    }
    Ok(())
}
