//! What feeds the web map and the Foxglove server: the central unit's loop
//! hands each a [`ViewSink`] what it received (the robots' summaries, the
//! bursts, in a simulation the truth), so that the viewers draw from what
//! the central unit takes and never subscribe to a robot's poses on their
//! own; a ticker turns the [`LiveView`] and the latest status the node
//! published into one JSON snapshot per tick for every client. A process
//! that is not the central unit (a recorder drawing the Foxglove view)
//! fills the view from subscribers of its own ([`Feed`]).

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use ickon_proto::keys::{Key, Keys, RobotTopic};
use ickon_proto::msg::admin::StatusReport;
use ickon_proto::msg::control::Burst;
use ickon_proto::msg::robot::{Fix, RobotPose, RobotSummary, Truth};
use ickon_proto::time::Time;
use ickon_proto::{DecodeError, decode};
use serde::de::DeserializeOwned;
use tokio::sync::watch;
use zenoh::Session;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

use super::fanout::Hub;
use super::view::LiveView;

/// How often a snapshot goes out: 20 Hz, twice the 10 Hz the map needs,
/// so that a late tick never drops it below.
pub const SNAPSHOT_PERIOD: std::time::Duration = std::time::Duration::from_millis(50);

/// The web map's clock: time since it started (only differences are shown).
#[derive(Debug, Clone, Copy)]
pub struct Stopwatch(Instant);

impl Stopwatch {
    /// Starts now.
    pub fn start() -> Self {
        Self(Instant::now())
    }

    /// Now, as nanoseconds since the start.
    pub fn now(&self) -> Time {
        Time(i64::try_from(self.0.elapsed().as_nanos()).unwrap_or(i64::MAX))
    }
}

/// The shared view, locked briefly by the subscribers and the ticker.
#[derive(Debug, Clone)]
pub struct SharedView(Arc<Mutex<LiveView>>);

impl SharedView {
    /// Shares `view`.
    pub fn new(view: LiveView) -> Self {
        Self(Arc::new(Mutex::new(view)))
    }

    /// The view (a panic elsewhere leaves it consistent: every update is one assignment).
    pub fn lock(&self) -> MutexGuard<'_, LiveView> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Where the central unit's loop hands a viewer what it draws: its view
/// and its clock. Each call locks the view briefly and never waits on
/// anything else.
#[derive(Debug, Clone)]
pub struct ViewSink {
    view: SharedView,
    clock: Stopwatch,
}

impl ViewSink {
    /// Feeds `view`, timed by `clock`.
    pub fn new(view: SharedView, clock: Stopwatch) -> Self {
        Self { view, clock }
    }

    /// A robot's summary the central unit took: its pose and its newest fix.
    pub fn summary(&self, robot: &str, summary: &RobotSummary) {
        let now = self.clock.now();
        let mut view = self.view.lock();
        view.on_pose(robot, summary.pose(), now);
        if let Some(fix) = summary.fixes.last() {
            view.on_fix(robot, fix.clone(), now);
        }
    }

    /// A burst report.
    pub fn burst(&self, burst: &Burst) {
        self.view.lock().on_burst(burst, self.clock.now());
    }

    /// A robot's truth (simulation only).
    pub fn truth(&self, robot: &str, truth: Truth) {
        self.view.lock().on_truth(robot, truth);
    }
}

/// The subscribers feeding the view of a process other than the central
/// unit; dropping this undeclares them.
pub struct Feed {
    _subscribers: Vec<Subscriber<()>>,
}

/// Decodes a per-robot sample: its robot id and message.
fn robot_message<T: DeserializeOwned>(keys: &Keys, s: &Sample) -> Option<(String, T)> {
    let robot = match keys.parse(s.key_expr().as_str()) {
        Ok(Key::Robot(robot, _) | Key::SimTruth(robot)) => robot,
        _ => return None,
    };
    let message: Result<T, DecodeError> = decode(&s.payload().to_bytes());
    Some((robot, message.ok()?))
}

/// A robot's fix, of the current layout or an older MSU's
/// ([`Fix::decode`]).
fn fix_message(keys: &Keys, s: &Sample) -> Option<(String, Fix)> {
    let robot = match keys.parse(s.key_expr().as_str()) {
        Ok(Key::Robot(robot, _)) => robot,
        _ => return None,
    };
    Some((robot, Fix::decode(&s.payload().to_bytes()).ok()?))
}

impl Feed {
    /// Subscribes on `session` to what the map shows.
    pub async fn start(
        session: &Session,
        keys: &Keys,
        view: &SharedView,
        clock: Stopwatch,
    ) -> zenoh::Result<Self> {
        let mut subscribers = Vec::new();
        let (k, v) = (keys.clone(), view.clone());
        subscribers.push(
            session
                .declare_subscriber(keys.robot_all(RobotTopic::Pose))
                .callback(move |s| match robot_message::<RobotPose>(&k, &s) {
                    Some((id, pose)) => v.lock().on_pose(&id, pose, clock.now()),
                    None => v.lock().ignore(),
                })
                .await?,
        );
        let (k, v) = (keys.clone(), view.clone());
        subscribers.push(
            session
                .declare_subscriber(keys.robot_all(RobotTopic::Fix))
                .callback(move |s| match fix_message(&k, &s) {
                    Some((id, fix)) => v.lock().on_fix(&id, fix, clock.now()),
                    None => v.lock().ignore(),
                })
                .await?,
        );
        let (k, v) = (keys.clone(), view.clone());
        subscribers.push(
            session
                .declare_subscriber(keys.sim_truth_all())
                .callback(move |s| match robot_message::<Truth>(&k, &s) {
                    Some((id, truth)) => v.lock().on_truth(&id, truth),
                    None => v.lock().ignore(),
                })
                .await?,
        );
        let v = view.clone();
        subscribers.push(
            session
                .declare_subscriber(keys.cell_burst_all())
                .callback(move |s| match decode::<Burst>(&s.payload().to_bytes()) {
                    Ok(b) => v.lock().on_burst(&b, clock.now()),
                    Err(_) => v.lock().ignore(),
                })
                .await?,
        );
        Ok(Self {
            _subscribers: subscribers,
        })
    }
}

/// Makes and sends a snapshot every [`SNAPSHOT_PERIOD`] until the status
/// channel closes; `latest` keeps the newest for new clients and `/api/live`.
pub async fn tick(
    view: SharedView,
    hub: Hub,
    mut status: watch::Receiver<Option<StatusReport>>,
    latest: watch::Sender<Option<Arc<str>>>,
    clock: Stopwatch,
) {
    let mut ticks = tokio::time::interval(SNAPSHOT_PERIOD);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        ticks.tick().await;
        if status.has_changed().is_err() {
            return;
        }
        let Some(report) = status.borrow_and_update().clone() else {
            continue;
        };
        let (clients, dropped) = hub.counts();
        let snapshot = view.lock().snapshot(&report, clock.now(), clients, dropped);
        match serde_json::to_string(&snapshot) {
            Ok(text) => {
                let text: Arc<str> = text.into();
                latest.send_replace(Some(Arc::clone(&text)));
                hub.broadcast(&text);
            }
            Err(e) => tracing::warn!("snapshot not serialised: {e}"),
        }
    }
}
