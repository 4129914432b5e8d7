//! The central unit's loop, once its endpoints are declared: each input
//! as it arrives ([`Input`]), then what it means, most of it an [`Event`]
//! for the core, whose outputs are published. Waiting and handling are
//! apart so that an input is always handled whole: only the wait is
//! cancelled when the node shuts down.

use std::sync::Arc;
use std::sync::atomic::AtomicU64;

use ickon_proto::keys::{Key, Keys};
use ickon_proto::msg::control::{CycleTrigger, Schedule};
use ickon_runtime::{LogLimiter, SimulatedClock};
use zenoh::Session;
use zenoh::liveliness::LivelinessToken;
use zenoh::query::Query;
use zenoh::sample::Sample;

use super::admin::{answer_admin, reply};
use super::endpoints::{Endpoints, next_sample};
use super::reload;
use super::samples::{
    air_event, alive_event, burst_event, decode_counted, link_report, robot_status_event,
    status_event, summary_event, truth_of,
};
use super::{SurveyFile, Viewers, follow_role};
use crate::core::{CentralCore, Event, Output};

/// One input of the loop, as it arrived.
pub(super) enum Input {
    /// The core's next wake-up is due.
    Wake,
    /// Time to write the survey calibration to its file.
    SaveSurvey,
    /// Time to hand the viewers the status.
    WebTick,
    SiteQuery(Query),
    ScheduleQuery(Query),
    AdminQuery(Query),
    /// A site reload's file, read and checked off the loop.
    Reloaded(Box<reload::Checked>),
    Alive(Sample),
    Status(Sample),
    Air(Sample),
    Burst(Sample),
    /// Robots' summaries, newest per robot, a few at a time.
    Summaries(Vec<Sample>),
    Truth(Sample),
    /// Robots' agents' statuses, likewise.
    RobotStatuses(Vec<Sample>),
    /// A node's report of its router link.
    Link(Sample),
    /// Its own trigger or schedule, come back (or another's).
    TriggerSeen(Sample),
    ScheduleSeen(Sample),
}

/// Most samples of one kind the loop takes from an inbox at once: a
/// wait among the loop's many inputs costs more than handling a summary,
/// and a batch is handled in well under a millisecond, so the core's
/// wake-up is never held back by more than that (the core triggers a due
/// cycle from any event anyway).
const BATCH: usize = 64;

/// The runtime's timer counts whole milliseconds and rounds a wait up to
/// the next: the core's wake-up is waited for by the timer until one such
/// grain before it, the rest on the thread.
const TIMER_GRAIN: std::time::Duration = std::time::Duration::from_millis(1);

/// What the loop holds between two inputs.
pub(super) struct NodeLoop<'a> {
    pub session: &'a Session,
    pub keys: Keys,
    pub clock: SimulatedClock,
    pub viewers: &'a Viewers,
    pub core: CentralCore,
    pub ends: Endpoints,
    pub survey_file: SurveyFile,
    /// The epoch the clock answers name (0: standing by).
    pub epoch: Arc<AtomicU64>,
    /// The `alive/central` token, held while active.
    pub token: Option<LivelinessToken>,
    pub reloads: reload::Reloads,
    pub unknown_admin: LogLimiter<()>,
    /// Each node's link to its router, for the admin's `links`.
    pub links: crate::router_links::RouterLinks,
    pub survey_saves: tokio::time::Interval,
    pub web_ticks: tokio::time::Interval,
    /// Triggers or schedules that could not be put.
    pub failed_puts: u64,
    /// Reports that did not decode, or said what no honest node says.
    pub undecodable: u64,
}

impl NodeLoop<'_> {
    /// Waits for the next input. Cancel-safe: every branch is. The core's
    /// wake-up (the next trigger) comes first whenever it is due: a loop
    /// with inputs queued would otherwise pick it among them at random and
    /// send the trigger late by the handling of the others.
    pub async fn next_input(&mut self) -> Input {
        let wake = if self.core.tick_pending() {
            std::time::Duration::ZERO
        } else {
            // The last grain is waited in `Input::Wake`'s handling.
            self.core
                .next_wake()
                .since(self.clock.now())
                .to_std()
                .saturating_sub(TIMER_GRAIN)
        };
        tokio::select! {
            biased;
            _ = tokio::time::sleep(wake) => Input::Wake,
            input = self.next_other() => input,
        }
    }

    /// Waits for the next input other than the core's wake-up, taking the
    /// ready ones in turn at random so that none starves another.
    async fn next_other(&mut self) -> Input {
        let ends = &self.ends;
        tokio::select! {
            _ = self.survey_saves.tick(), if self.survey_file.path.is_some() => Input::SaveSurvey,
            _ = self.web_ticks.tick(), if self.viewers.any() => Input::WebTick,
            Ok(q) = ends.site_q.recv_async() => Input::SiteQuery(q),
            Ok(q) = ends.schedule_q.recv_async() => Input::ScheduleQuery(q),
            Ok(q) = ends.admin_q.recv_async() => Input::AdminQuery(q),
            Some(checked) = self.reloads.done.recv() => Input::Reloaded(Box::new(checked)),
            Ok(s) = ends.alive.recv_async() => Input::Alive(s),
            Ok(s) = ends.status_sub.recv_async() => Input::Status(s),
            Ok(s) = ends.air_sub.recv_async() => Input::Air(s),
            Ok(s) = ends.burst_sub.recv_async() => Input::Burst(s),
            batch = ends.summaries.next_batch(BATCH) => Input::Summaries(batch),
            Some(s) = next_sample(&ends.truth_sub) => Input::Truth(s),
            batch = ends.robot_statuses.next_batch(BATCH) => Input::RobotStatuses(batch),
            Ok(s) = ends.cell_link_sub.recv_async() => Input::Link(s),
            Ok(s) = ends.robot_link_sub.recv_async() => Input::Link(s),
            Ok(s) = ends.cycle_sub.recv_async() => Input::TriggerSeen(s),
            Ok(s) = ends.schedule_sub.recv_async() => Input::ScheduleSeen(s),
            // Every channel closed: only the wake-up is left to wait for.
            else => std::future::pending().await,
        }
    }

    /// Handles one input whole: answers it, or hands the core its events.
    pub async fn take(&mut self, input: Input) {
        match input {
            Input::Summaries(batch) => {
                for s in batch {
                    if let Some(event) = summary_event(&self.keys, &s, &mut self.undecodable) {
                        self.handle(event).await;
                    }
                }
            }
            Input::RobotStatuses(batch) => {
                for s in batch {
                    if let Some(event) = robot_status_event(&self.keys, &s, &mut self.undecodable) {
                        self.handle(event).await;
                    }
                }
            }
            input => self.take_one(input).await,
        }
    }

    /// Handles one input that is not a batch.
    async fn take_one(&mut self, input: Input) {
        if let Some(event) = self.event_of(input).await {
            // A cell coming or going changes what the viewers draw at once:
            // it is not left to the next status tick (half a second, more
            // than two cycles of a tight schedule). Cells come and go
            // rarely, so this costs nothing at any fleet size.
            let cell_changed = matches!(event, Event::CellAlive { .. });
            self.handle(event).await;
            if cell_changed && self.viewers.any() {
                self.hand_viewers_status();
            }
        }
    }

    /// Hands the viewers the status and the transmitters' health.
    fn hand_viewers_status(&self) {
        let now = self.clock.now();
        self.viewers.publish(self.core.status(now));
        self.viewers
            .publish_transmitters(|| self.core.transmitters(now));
    }

    /// The core's event for `input`, or `None` when the loop answered it
    /// itself (queries, saves, the viewers' ticks) or it did not decode.
    async fn event_of(&mut self, input: Input) -> Option<Event> {
        let (keys, bad) = (&self.keys, &mut self.undecodable);
        match input {
            Input::Wake => {
                self.wait_last_grain();
                Some(Event::Tick)
            }
            Input::SaveSurvey => {
                self.survey_file.save(&self.core);
                None
            }
            Input::WebTick => {
                self.hand_viewers_status();
                None
            }
            Input::SiteQuery(q) => {
                reply(&q, &self.core.site_info()).await;
                None
            }
            Input::ScheduleQuery(q) => {
                if self.core.is_active() {
                    reply(&q, self.core.latest_schedule()).await;
                }
                None
            }
            Input::AdminQuery(q) => {
                self.admin(q).await;
                None
            }
            Input::Reloaded(checked) => {
                self.reloaded(*checked).await;
                None
            }
            Input::Alive(s) => alive_event(keys, &s, self.core.is_active()),
            Input::Status(s) => status_event(&s, bad),
            Input::Air(s) => air_event(keys, &s, bad),
            Input::Burst(s) => {
                let e = burst_event(&s, &self.clock, bad);
                if let Some(Event::Burst(b)) = &e {
                    self.viewers.burst(b);
                }
                e
            }
            Input::Truth(s) => {
                if let Some((robot, truth)) = truth_of(keys, &s) {
                    self.viewers.truth(&robot, truth);
                }
                None
            }
            // Taken apart in `take`.
            Input::Summaries(_) | Input::RobotStatuses(_) => None,
            Input::Link(s) => {
                if let Some((kind, id, link)) = link_report(keys, &s, bad)
                    && !self.links.observe(kind, id, link)
                {
                    *bad += 1;
                }
                None
            }
            Input::TriggerSeen(s) => {
                decode_counted::<CycleTrigger>(&s, bad).map(Event::TriggerSeen)
            }
            Input::ScheduleSeen(s) => decode_counted::<Schedule>(&s, bad).map(Event::ScheduleSeen),
        }
    }

    /// Waits on the thread until the core's wake-up is due, when it is at
    /// most [`TIMER_GRAIN`] away: the trigger then leaves within the
    /// operating system's timer slack of its time (tens of microseconds)
    /// instead of up to the timer's whole millisecond late. It blocks the
    /// loop's thread, which has nothing else to do that is due sooner
    /// than a trigger, for at most a millisecond a cycle.
    fn wait_last_grain(&self) {
        let left = self.core.next_wake().since(self.clock.now()).to_std();
        if !self.core.tick_pending() && left <= TIMER_GRAIN {
            std::thread::sleep(left);
        }
    }

    /// An admin query: a reload is read off the loop (one at a time), the
    /// others are answered at once.
    async fn admin(&mut self, q: Query) {
        let command = match self.keys.parse(q.key_expr().as_str()) {
            Ok(Key::CentralAdmin(c)) => c,
            _ => String::new(),
        };
        if command == "links" {
            reply(&q, &self.links.report()).await;
        } else if command != "reload" {
            let now = self.clock.now();
            answer_admin(&self.keys, &mut self.core, &q, now, &mut self.unknown_admin).await;
        } else if self.reloads.in_flight() {
            reply(&q, &reload::busy()).await;
        } else {
            self.reloads.start(q);
        }
    }

    /// A reload's file came back checked: the core takes the site or the
    /// refusal is the answer.
    async fn reloaded(&mut self, checked: reload::Checked) {
        self.reloads.finished();
        let ack = match checked.result {
            Ok((site, toml, file_name)) => {
                let (ack, out) = self
                    .core
                    .reload_site(site, &toml, &file_name, self.clock.now());
                self.failed_puts += self.ends.publish(out.into_iter().collect()).await;
                ack
            }
            Err(refused) => refused,
        };
        reply(&checked.query, &ack).await;
    }

    /// The core takes `event`; its outputs are published and the node
    /// follows the role it leaves it in.
    async fn handle(&mut self, event: Event) {
        // The viewers draw a summary once the core took it (a flood or a
        // forgery the gate dropped is not drawn either).
        let shown = match &event {
            Event::Summary { robot, summary } if self.viewers.any() => {
                Some((robot.clone(), summary.clone()))
            }
            _ => None,
        };
        let handling = std::time::Instant::now();
        let outputs = self.core.handle(self.clock.now(), event);
        if let Some((robot, summary)) = shown
            && self.core.last_pose_stamp(&robot) == Some(summary.stamp)
        {
            self.viewers.summary(&robot, &summary);
        }
        if outputs.iter().any(|o| matches!(o, Output::Survey(_))) {
            self.core.note_survey_cost(handling.elapsed());
        }
        follow_role(
            self.session,
            &self.keys,
            &self.core,
            &self.epoch,
            &mut self.token,
        )
        .await;
        self.failed_puts += self.ends.publish(outputs).await;
    }
}
