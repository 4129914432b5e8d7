//! The central unit's queryables, publishers and subscribers: declared
//! once at start, the clock answered in Zenoh's receive path, the core's
//! outputs published.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use ickon_proto::keys::Keys;
use ickon_proto::msg::control::ClockRequest;
use ickon_proto::{decode, encode};
use ickon_runtime::{NodeError, SimulatedClock, put_counted, zerr};
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::query::{Query, Queryable};
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use super::latest_inbox::LatestInbox;
use crate::core::{CentralCore, Output};

/// A subscriber or queryable with its queue.
pub(super) type Queue<T> = FifoChannelHandler<T>;

/// The central unit's queryables, publishers and subscribers.
pub(super) struct Endpoints {
    pub(super) site_q: Queryable<Queue<Query>>,
    pub(super) schedule_q: Queryable<Queue<Query>>,
    /// Answers in Zenoh's receive path; kept only to stay declared.
    pub(super) _clock_q: Queryable<()>,
    pub(super) admin_q: Queryable<Queue<Query>>,
    pub(super) cycle_pub: Publisher<'static>,
    pub(super) schedule_pub: Publisher<'static>,
    pub(super) survey_pub: Publisher<'static>,
    pub(super) alive: Subscriber<Queue<Sample>>,
    pub(super) status_sub: Subscriber<Queue<Sample>>,
    pub(super) burst_sub: Subscriber<Queue<Sample>>,
    pub(super) air_sub: Subscriber<Queue<Sample>>,
    /// The robots' summaries: all the central unit hears of a robot but
    /// its token and status (never its poses and fixes, which come at the
    /// odometry and cycle rates). Kept newest per robot: see
    /// [`LatestInbox`].
    pub(super) summaries: LatestInbox,
    pub(super) _summary_sub: Subscriber<()>,
    /// The robots' agents' statuses, newest per robot likewise.
    pub(super) robot_statuses: LatestInbox,
    pub(super) _robot_status_sub: Subscriber<()>,
    /// Each node's link to its router, as the node reports it.
    pub(super) cell_link_sub: Subscriber<Queue<Sample>>,
    pub(super) robot_link_sub: Subscriber<Queue<Sample>>,
    /// The simulation's truth, for the viewers only (declared when there
    /// are viewers).
    pub(super) truth_sub: Option<Subscriber<Queue<Sample>>>,
    /// Its own keys, to notice what it did not send (its own puts come
    /// back too).
    pub(super) cycle_sub: Subscriber<Queue<Sample>>,
    pub(super) schedule_sub: Subscriber<Queue<Sample>>,
}

impl Endpoints {
    /// Declares everything but the liveliness token. Clock requests are
    /// answered with `clock` and the epoch in `epoch` (0: not at all); the
    /// truth is subscribed to only `for_viewers`.
    pub(super) async fn declare(
        session: &Session,
        keys: &Keys,
        clock: SimulatedClock,
        epoch: Arc<AtomicU64>,
        for_viewers: bool,
    ) -> Result<Self, NodeError> {
        let site_q = session
            .declare_queryable(keys.central_site())
            .await
            .map_err(zerr)?;
        let schedule_q = session
            .declare_queryable(keys.central_schedule())
            .await
            .map_err(zerr)?;
        // Clock requests are answered in Zenoh's receive path, not in the
        // node's loop: t2 must not wait for the loop to get round to the
        // query. The answer names the epoch, which the loop may change.
        let _clock_q = session
            .declare_queryable(keys.central_clock())
            .callback(move |q| answer_clock(&q, &clock, epoch.load(Ordering::Relaxed)))
            .await
            .map_err(zerr)?;
        let admin_q = session
            .declare_queryable(keys.central_admin_all())
            .await
            .map_err(zerr)?;
        let cycle_pub = realtime_publisher(session, keys.central_cycle()).await?;
        // Like the triggers (see the survey's below): a subscriber hears a
        // schedule before the triggers that name it.
        let schedule_pub = realtime_publisher(session, keys.central_schedule()).await?;
        // With the triggers' priority and, like them, sent at once: a
        // subscriber then hears a calibration and the triggers in the order
        // they were sent (one priority's queue keeps its order; another's may
        // overtake it when a link is busy), and an MSU takes a calibration
        // from the first cycle triggered after it, so that a recorder and the
        // MSU agree on which cycle that is (`ickon_msu::control_timing`).
        let survey_pub = realtime_publisher(session, keys.central_survey()).await?;
        let alive = session
            .liveliness()
            .declare_subscriber(keys.alive_all())
            .history(true)
            .await
            .map_err(zerr)?;
        let (summaries, _summary_sub) =
            latest_subscriber(session, keys.robot_summary_all()).await?;
        let (robot_statuses, _robot_status_sub) =
            latest_subscriber(session, keys.robot_status_all()).await?;
        Ok(Self {
            site_q,
            schedule_q,
            _clock_q,
            admin_q,
            cycle_pub,
            schedule_pub,
            survey_pub,
            alive,
            status_sub: subscriber(session, keys.cell_status_all()).await?,
            burst_sub: subscriber(session, keys.cell_burst_all()).await?,
            air_sub: subscriber(session, keys.cell_air_all()).await?,
            summaries,
            _summary_sub,
            robot_statuses,
            _robot_status_sub,
            cell_link_sub: subscriber(session, keys.cell_link_all()).await?,
            robot_link_sub: subscriber(session, keys.robot_link_all()).await?,
            truth_sub: if for_viewers {
                Some(subscriber(session, keys.sim_truth_all()).await?)
            } else {
                None
            },
            cycle_sub: subscriber(session, keys.central_cycle()).await?,
            schedule_sub: subscriber(session, keys.central_schedule()).await?,
        })
    }

    /// Publishes the core's outputs; returns how many puts failed.
    pub(super) async fn publish(&self, outputs: Vec<Output>) -> u64 {
        publish(
            [&self.cycle_pub, &self.schedule_pub, &self.survey_pub],
            outputs,
        )
        .await
    }
}

/// A publisher sent at once with real-time priority, blocking rather than
/// dropping when a link is busy.
async fn realtime_publisher(
    session: &Session,
    key: String,
) -> Result<Publisher<'static>, NodeError> {
    session
        .declare_publisher(key)
        .express(true)
        .priority(Priority::RealTime)
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(zerr)
}

/// A subscriber on `key` with the default queue.
async fn subscriber(
    session: &Session,
    key: String,
) -> Result<Subscriber<Queue<Sample>>, NodeError> {
    session.declare_subscriber(key).await.map_err(zerr)
}

/// A subscriber on `key` whose samples wait in a [`LatestInbox`], newest
/// per key: the receive path never waits for the loop.
async fn latest_subscriber(
    session: &Session,
    key: String,
) -> Result<(LatestInbox, Subscriber<()>), NodeError> {
    let inbox = LatestInbox::new();
    let put = inbox.clone();
    let sub = session
        .declare_subscriber(key)
        .callback(move |s| put.put(s))
        .await
        .map_err(zerr)?;
    Ok((inbox, sub))
}

/// The next sample of `sub`; never, without one.
pub(super) async fn next_sample(sub: &Option<Subscriber<Queue<Sample>>>) -> Option<Sample> {
    match sub {
        Some(sub) => sub.recv_async().await.ok(),
        None => std::future::pending().await,
    }
}

/// Publishes the core's outputs; returns how many puts failed.
async fn publish(
    [cycle_pub, schedule_pub, survey_pub]: [&Publisher<'_>; 3],
    outputs: Vec<Output>,
) -> u64 {
    let mut failed = 0;
    for o in outputs {
        let sent = match o {
            Output::Trigger(t) => put_counted(cycle_pub, &t).await,
            Output::Schedule(s) => put_counted(schedule_pub, &s).await,
            Output::Survey(s) => put_counted(survey_pub, &s).await,
        };
        failed += u64::from(!sent);
    }
    failed
}

/// Answers a clock request at once: t2 on arrival, t3 just before the
/// reply; not at all with epoch 0 (a standby).
fn answer_clock(q: &Query, clock: &SimulatedClock, epoch: u64) {
    if epoch == 0 {
        return;
    }
    let t2 = clock.now();
    let Some(Ok(req)) = q.payload().map(|p| decode::<ClockRequest>(&p.to_bytes())) else {
        tracing::warn!("clock query without a valid request");
        return;
    };
    let sent = encode(&CentralCore::clock_reply(epoch, req.t1, t2, clock.now()))
        .map_err(NodeError::from)
        .and_then(|bytes| {
            q.reply(q.key_expr().clone(), bytes)
                .express(true)
                .wait()
                .map_err(zerr)
        });
    if let Err(e) = sent {
        tracing::warn!("clock reply failed: {e}");
    }
}
