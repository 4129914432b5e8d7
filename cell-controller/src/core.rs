//! The cell controller as a sans-IO state machine ([`CellCore`]): fed with
//! [`Event`]s and the local clock's `now`, it returns [`Output`]s (bursts to
//! program, status to publish, requests to make) and says when it must be
//! woken next. It never reads a clock and never waits: a clock exchange or a
//! schedule query is an [`Output`] the harness carries out beside its loop,
//! and its answer comes back as an [`Event`]. The Zenoh node
//! ([`crate::node`]) and the virtual-time engine (crate `ickon-sim`) drive
//! the same core.
//!
//! Bursts are planned when a trigger arrives and programmed into the
//! transmitter [`PROGRAM_AHEAD`] before they fire, with the clock estimate
//! of that moment ([`crate::timer`]). When the central unit goes away the
//! cell keeps its schedules and waits for triggers. A restarted central
//! unit is recognised by its epoch at its first trigger or schedule
//! ([`crate::trigger_gate`], [`ickon_proto::epoch`]): the cell takes its
//! cycle 0 at once, asks for its schedule, and keeps its clock estimate (a
//! master clock that changed shows as a clock step at the next exchange).
//! Clock answers of any other central unit than the one whose triggers it
//! follows are refused, and so is a single exchange that disagrees with the
//! estimate: only [`CONFIRMING_EXCHANGES`] agreeing ones make a clock step.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use ickon_proto::msg::control::{CellStatus, CycleTrigger, Schedule};
use ickon_proto::time::{Duration, Time};

use crate::sync::{ClockSample, SyncConfig, SyncSlave};
use crate::timer::{BurstTimer, PROGRAM_AHEAD, PlannedBurst};
use crate::trigger_gate::{TriggerGate, TriggerRefused};

/// Timing of the cell's own activities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellConfig {
    /// Clock exchanges at start-up (and after the central unit returns) come this often...
    pub fast_sync: Duration,
    /// ...for this many exchanges (the drift is fitted after 1.5 s, from the
    /// best of many), then every [`CellConfig::slow_sync`].
    pub fast_sync_count: u32,
    /// Steady-state clock exchange period (a window of 100 spans 25 s).
    pub slow_sync: Duration,
    /// Status reports this often.
    pub status_every: Duration,
    /// A schedule query that got no answer is repeated after this long.
    pub schedule_retry: Duration,
    /// A burst must be programmed at least this long before it fires.
    pub program_margin: Duration,
    /// The synchronisation filter.
    pub sync: SyncConfig,
}

impl Default for CellConfig {
    fn default() -> Self {
        Self {
            fast_sync: Duration::from_millis(20),
            fast_sync_count: 100,
            slow_sync: Duration::from_millis(250),
            status_every: Duration::from_millis(1_000),
            schedule_retry: Duration::from_millis(1_000),
            program_margin: Duration::from_millis(1),
            sync: SyncConfig::default(),
        }
    }
}

/// What the cell is told.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// Nothing but time passed: do what is due (the answer to
    /// [`CellCore::next_wake`]).
    Tick,
    /// A cycle trigger from the central unit.
    Trigger(CycleTrigger),
    /// A schedule, published or in answer to [`Output::RequestSchedule`].
    Schedule(Schedule),
    /// The answer to [`Output::RequestSchedule`] did not come.
    ScheduleUnanswered,
    /// The result of the clock exchange asked for by
    /// [`Output::RequestClock`]: `None` when the master did not answer.
    ClockExchange(Option<ClockSample>),
    /// The central unit's liveliness token appeared (`true`) or went (`false`).
    CentralAlive(bool),
    /// The process is stopping: bursts not yet handed to the driver are
    /// dropped (a cell that is going away must not fire half a cycle
    /// later), one last status says so, and every later event is ignored.
    Shutdown,
}

/// What the harness must do.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Program a transmitter to fire (through the transmitter driver).
    Fire(PlannedBurst),
    /// Publish the cell's status.
    Status(CellStatus),
    /// Make one clock exchange with the master and report it as
    /// [`Event::ClockExchange`]. No second one is asked for before then.
    RequestClock,
    /// Query the central unit's schedule and report it as [`Event::Schedule`]
    /// or [`Event::ScheduleUnanswered`].
    RequestSchedule,
}

/// What the cell has done, for its status and for tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CellCounters {
    /// Cycles in which at least one burst was programmed.
    pub cycles_fired: u64,
    /// The last such cycle.
    pub last_cycle_fired: u64,
    /// Slots not fired because their time had passed when planned or programmed.
    pub slots_skipped: u64,
    /// Triggers that could not be planned (no schedule, no clock estimate).
    pub triggers_unplanned: u64,
    /// Clock exchanges made, answered or not.
    pub clock_exchanges: u64,
    /// Clock steps detected (an exchange far outside what the estimate allows).
    pub clock_steps: u64,
    /// Triggers refused: too far from now, of a replaced central unit,
    /// repeated, or off the cycle count (see [`crate::trigger_gate`]).
    pub triggers_refused: u64,
    /// Schedules refused (altered, backwards, of an old epoch, invalid).
    pub schedules_refused: u64,
    /// Clock answers refused: from another central unit than the one
    /// followed, or far off the estimate without others agreeing.
    pub clock_answers_refused: u64,
}

impl CellCounters {
    /// These counts followed by `later`'s (a restarted core counts from zero).
    pub fn then(self, later: CellCounters) -> CellCounters {
        CellCounters {
            cycles_fired: self.cycles_fired + later.cycles_fired,
            last_cycle_fired: self.last_cycle_fired.max(later.last_cycle_fired),
            slots_skipped: self.slots_skipped + later.slots_skipped,
            triggers_unplanned: self.triggers_unplanned + later.triggers_unplanned,
            clock_exchanges: self.clock_exchanges + later.clock_exchanges,
            clock_steps: self.clock_steps + later.clock_steps,
            triggers_refused: self.triggers_refused + later.triggers_refused,
            schedules_refused: self.schedules_refused + later.schedules_refused,
            clock_answers_refused: self.clock_answers_refused + later.clock_answers_refused,
        }
    }

    /// Every control message refused.
    pub fn refused(&self) -> u64 {
        self.triggers_refused + self.schedules_refused + self.clock_answers_refused
    }
}

/// Whether a count going from `before` to `after` passed a power of two:
/// skipped slots are logged at the 1st, 2nd, 4th, 8th, ... so that a loaded
/// machine costs a few lines, not one per slot (the status carries the count).
fn crosses_power_of_two(before: u64, after: u64) -> bool {
    after > before && (before == 0 || before.ilog2() != after.ilog2())
}

/// Consecutive exchanges that disagree with the estimate in the same way
/// before the cell takes it as a clock step: one stray answer (a rogue
/// replier, a reply delayed in a queue) is dropped instead of throwing away
/// the synchronisation.
pub const CONFIRMING_EXCHANGES: u32 = 3;

/// An exchange whose offset differs from the estimate by more than half its
/// own delay, four sigmas of the estimate and this much is a clock step, not
/// noise: the cell synchronises afresh instead of firing on a stale line.
const STEP_TOLERANCE: Duration = Duration::from_micros(100);

/// A local clock going back further than this between two calls has been
/// stepped (calls come in order; a clock that is slewed never goes back).
const STEP_BACK_NOTICED: Duration = Duration::from_millis(1);

/// A planned burst waiting to be programmed, ordered by its master time:
/// (master, tx, cycle, local, epoch).
type PendingBurst = Reverse<(Time, u32, u64, Time, u64)>;

/// The cell controller's state.
#[derive(Debug, Clone)]
pub struct CellCore {
    cell_id: String,
    config: CellConfig,
    sync: SyncSlave,
    timer: BurstTimer,
    pending: BinaryHeap<PendingBurst>,
    gate: TriggerGate,
    /// Exchanges in a row that disagreed with the estimate, and the offset
    /// the last one gave (ns).
    step_candidates: (u32, f64),
    /// A trigger that named a schedule this cell does not have yet.
    waiting: Option<CycleTrigger>,
    exchanges_since_reset: u32,
    next_sync: Time,
    clock_in_flight: bool,
    next_status: Time,
    schedule_in_flight: bool,
    next_schedule_query: Option<Time>,
    central_lost: bool,
    counters: CellCounters,
    faults: Vec<String>,
    stopped: bool,
    /// The latest local `now` seen, to notice the local clock stepping back.
    latest_now: Time,
}

impl CellCore {
    /// A cell `cell_id` starting at local time `now`: it asks for the
    /// schedule and starts synchronising on the first call to [`handle`](Self::handle).
    pub fn new(cell_id: &str, config: CellConfig, now: Time) -> Self {
        Self {
            cell_id: cell_id.to_string(),
            config,
            sync: SyncSlave::new(config.sync),
            timer: BurstTimer::new(cell_id, config.program_margin),
            pending: BinaryHeap::new(),
            gate: TriggerGate::new(),
            step_candidates: (0, 0.0),
            waiting: None,
            exchanges_since_reset: 0,
            next_sync: now,
            clock_in_flight: false,
            next_status: now + config.status_every,
            schedule_in_flight: false,
            next_schedule_query: Some(now),
            central_lost: false,
            counters: CellCounters::default(),
            faults: Vec::new(),
            stopped: false,
            latest_now: now,
        }
    }

    /// The cell's id.
    pub fn cell_id(&self) -> &str {
        &self.cell_id
    }

    /// What the cell has done so far.
    pub fn counters(&self) -> CellCounters {
        self.counters
    }

    /// The epoch of the central unit followed, once one was seen.
    pub fn epoch(&self) -> Option<u64> {
        self.gate.epoch()
    }

    /// The synchronisation filter (for status and tests).
    pub fn sync(&self) -> &SyncSlave {
        &self.sync
    }

    /// The local time at which the cell must be given [`Event::Tick`] next.
    pub fn next_wake(&self) -> Time {
        if self.stopped {
            return Time::from_nanos(i64::MAX);
        }
        let mut wake = self.next_status;
        if !self.clock_in_flight {
            wake = wake.min(self.next_sync);
        }
        if let Some(t) = self
            .next_schedule_query
            .filter(|_| !self.schedule_in_flight)
        {
            wake = wake.min(t);
        }
        if let Some(t) = self.next_program_time() {
            wake = wake.min(t);
        }
        wake
    }

    /// When the earliest pending burst must be programmed, local time.
    fn next_program_time(&self) -> Option<Time> {
        let Reverse((master, ..)) = self.pending.peek()?;
        let estimate = self.sync.estimate()?;
        Some(estimate.to_local(*master) - PROGRAM_AHEAD)
    }

    /// Takes `event` at local time `now`, then does whatever is due.
    pub fn handle(&mut self, now: Time, event: Event) -> Vec<Output> {
        let mut out = Vec::new();
        if self.stopped {
            return out;
        }
        self.notice_clock_step_back(now);
        match event {
            Event::Shutdown => {
                let dropped = self.pending.len();
                self.pending.clear();
                self.waiting = None;
                self.stopped = true;
                self.faults = vec![format!("stopping: {dropped} planned bursts dropped")];
                out.push(Output::Status(self.status(now)));
                return out;
            }
            Event::Tick => {}
            Event::Trigger(t) => self.on_trigger(t, now),
            Event::Schedule(s) => {
                self.schedule_in_flight = false;
                self.on_schedule(s, now);
                if let Some(t) = self.waiting.take() {
                    self.plan_trigger(t, now);
                }
            }
            Event::ScheduleUnanswered => {
                self.schedule_in_flight = false;
                if self.next_schedule_query.is_some() || self.waiting.is_some() {
                    self.next_schedule_query = Some(now + self.config.schedule_retry);
                }
            }
            Event::ClockExchange(sample) => {
                self.clock_in_flight = false;
                self.counters.clock_exchanges += 1;
                match sample {
                    Some(s) if self.gate.epoch().is_some_and(|e| e != s.epoch) => {
                        self.counters.clock_answers_refused += 1;
                        tracing::debug!(
                            "cell {}: clock answer of epoch {} refused",
                            self.cell_id,
                            s.epoch
                        );
                    }
                    Some(s) => {
                        if self.detect_step(&s) && !self.sync.add(s) {
                            tracing::debug!("cell {}: clock exchange discarded", self.cell_id);
                        }
                    }
                    None => tracing::debug!("cell {}: no clock reply", self.cell_id),
                }
                self.exchanges_since_reset = self.exchanges_since_reset.saturating_add(1);
                // A suspected step is confirmed or cleared at the fast pace.
                let period = if self.exchanges_since_reset < self.config.fast_sync_count
                    || self.step_candidates.0 > 0
                {
                    self.config.fast_sync
                } else {
                    self.config.slow_sync
                };
                self.next_sync = now + period;
            }
            Event::CentralAlive(false) => {
                if !self.central_lost {
                    tracing::info!(
                        "cell {}: central unit gone; keeping the schedule, waiting for triggers",
                        self.cell_id
                    );
                }
                self.central_lost = true;
            }
            Event::CentralAlive(true) => {
                if self.central_lost {
                    // The clock estimate stays: the same master clock needs
                    // nothing new, another one shows as a clock step at the
                    // exchange made at once. Its schedule comes with its
                    // epoch, which replaces the old ones.
                    tracing::info!(
                        "cell {}: central unit back; checking the clock",
                        self.cell_id
                    );
                    self.central_lost = false;
                    self.exchanges_since_reset = 0;
                    self.next_sync = now;
                    self.next_schedule_query = Some(now);
                }
            }
        }
        self.poll(now, &mut out);
        out
    }

    /// When the local clock stepped back, every deadline kept in it (the
    /// next exchange, status and schedule query) lies that far ahead: a cell
    /// stepped back 5 s made no exchange, so noticed nothing and fired
    /// nothing, for 5 s. They are brought forward, the exchange to now: it
    /// shows the step ([`Self::detect_step`]).
    fn notice_clock_step_back(&mut self, now: Time) {
        if self.latest_now.since(now) <= STEP_BACK_NOTICED {
            self.latest_now = self.latest_now.max(now);
            return;
        }
        self.latest_now = now;
        self.next_sync = self.next_sync.min(now);
        self.next_status = self.next_status.min(now + self.config.status_every);
        self.next_schedule_query = self.next_schedule_query.map(|t| t.min(now));
    }

    /// Whether `s` may be added to the synchronisation. An exchange that
    /// no offset the estimate allows can explain is held back, and no burst
    /// is programmed until the next exchanges (at the fast pace) clear or
    /// confirm it; when [`CONFIRMING_EXCHANGES`] in a row agree with each
    /// other the clock stepped, and the synchronisation starts afresh from
    /// the last.
    fn detect_step(&mut self, s: &ClockSample) -> bool {
        let Some(est) = self.sync.estimate() else {
            return true;
        };
        if s.delay_ns() < 0.0 {
            return true;
        }
        // Compared as the estimate sees it: sent when requests typically leave.
        let s = &self.sync.adjusted(s);
        let mid = s.local_mid();
        let predicted_ns = est.to_master(mid).since(mid).as_nanos() as f64;
        let slack_ns = s.delay_ns() / 2.0 + 4.0 * est.sigma_ns + STEP_TOLERANCE.as_nanos() as f64;
        let off_by_ns = s.offset_ns() - predicted_ns;
        if off_by_ns.abs() <= slack_ns {
            self.step_candidates = (0, 0.0);
            return true;
        }
        let (n, last_off_ns) = self.step_candidates;
        let agrees = n > 0 && (off_by_ns - last_off_ns).abs() <= slack_ns;
        self.step_candidates = (if agrees { n + 1 } else { 1 }, off_by_ns);
        if self.step_candidates.0 < CONFIRMING_EXCHANGES {
            self.counters.clock_answers_refused += 1;
            return false;
        }
        tracing::warn!(
            "cell {}: clock stepped by about {:.0} us; synchronising afresh",
            self.cell_id,
            off_by_ns * 1e-3
        );
        self.step_candidates = (0, 0.0);
        self.counters.clock_steps += 1;
        self.sync = SyncSlave::new(self.config.sync);
        self.exchanges_since_reset = 0;
        self.faults = vec![format!("clock step of {:.0} us", off_by_ns * 1e-3)];
        true
    }

    /// Takes a schedule if the rules of [`ickon_proto::epoch`] allow it, and
    /// follows its epoch if that is newer.
    fn on_schedule(&mut self, s: Schedule, now: Time) {
        // Checked before its epoch is noted: a schedule no cell could fire,
        // of a newer epoch, would otherwise fence the real central unit off.
        if let Err(e) = ickon_proto::epoch::check_schedule(&s) {
            self.counters.schedules_refused += 1;
            tracing::debug!("cell {}: {e}", self.cell_id);
            return;
        }
        let before = self.gate.epoch();
        // An epoch is a central unit's start: one in the future is forged.
        let future = self
            .sync
            .estimate()
            .is_some_and(|e| !ickon_proto::epoch::plausible_epoch(s.epoch, e.to_master(now)));
        if future || !self.gate.note_epoch(s.epoch) {
            self.counters.schedules_refused += 1;
            tracing::debug!(
                "cell {}: schedule of replaced or future epoch {} refused",
                self.cell_id,
                s.epoch
            );
            return;
        }
        if before.is_some_and(|e| e < s.epoch) {
            self.drop_older_epochs(s.epoch);
        }
        match self.timer.add_schedule(s) {
            Ok(_) => self.next_schedule_query = None,
            Err(e) => {
                self.counters.schedules_refused += 1;
                tracing::debug!("cell {}: {e}", self.cell_id);
            }
        }
    }

    /// Takes a trigger through the gate, then plans it.
    fn on_trigger(&mut self, trigger: CycleTrigger, now: Time) {
        match self.admit(&trigger, now) {
            Err(e) => {
                self.counters.triggers_refused += 1;
                tracing::debug!("cell {}: trigger refused: {e}", self.cell_id);
            }
            Ok(new_epoch) => {
                if new_epoch {
                    self.drop_older_epochs(trigger.epoch);
                }
                self.plan_trigger(trigger, now);
            }
        }
    }

    /// A newer central unit took over: bursts planned for the replaced
    /// one's cycles would fire into the new one's.
    fn drop_older_epochs(&mut self, epoch: u64) {
        tracing::info!(
            "cell {}: following central unit epoch {epoch}",
            self.cell_id
        );
        self.pending.retain(|Reverse(p)| p.4 >= epoch);
        if self.waiting.as_ref().is_some_and(|t| t.epoch < epoch) {
            self.waiting = None;
        }
    }

    /// The gate's verdict on `trigger` at local time `now`.
    fn admit(&mut self, trigger: &CycleTrigger, now: Time) -> Result<bool, TriggerRefused> {
        let master_now = self.sync.estimate().map(|e| e.to_master(now));
        let period = self
            .timer
            .cycle_period(trigger.epoch, trigger.schedule_version);
        self.gate.admit(trigger, master_now, period)
    }

    /// Plans an admitted trigger, or keeps it until its schedule arrives.
    fn plan_trigger(&mut self, trigger: CycleTrigger, now: Time) {
        if !self
            .timer
            .has_schedule(trigger.epoch, trigger.schedule_version)
        {
            // A cell that started late (or missed a put) asks for the schedule;
            // the trigger is planned when it comes, its past slots skipped.
            self.waiting = Some(trigger);
            if !self.schedule_in_flight && self.next_schedule_query.is_none_or(|t| t > now) {
                self.next_schedule_query = Some(now);
            }
            return;
        }
        match self
            .timer
            .plan(&trigger, self.sync.estimate().as_ref(), now)
        {
            Ok(plan) => {
                let before = self.counters.slots_skipped;
                self.counters.slots_skipped += plan.skipped;
                if plan.skipped > 0 && crosses_power_of_two(before, self.counters.slots_skipped) {
                    tracing::warn!(
                        "cell {}: cycle {}: {} slots skipped (trigger too late); {} skipped so far",
                        self.cell_id,
                        trigger.cycle,
                        plan.skipped,
                        self.counters.slots_skipped
                    );
                }
                for b in plan.bursts {
                    self.pending
                        .push(Reverse((b.master, b.tx_id, b.cycle, b.local, b.epoch)));
                }
                self.faults.clear();
            }
            Err(e) => {
                tracing::debug!(
                    "cell {}: cycle {} not fired: {e}",
                    self.cell_id,
                    trigger.cycle
                );
                self.counters.triggers_unplanned += 1;
                self.faults = vec![e.to_string()];
            }
        }
    }

    /// Everything due at `now`: bursts to program, a clock exchange, a
    /// schedule query, a status report.
    fn poll(&mut self, now: Time, out: &mut Vec<Output>) {
        self.program_due(now, out);
        if !self.clock_in_flight && now >= self.next_sync {
            self.clock_in_flight = true;
            out.push(Output::RequestClock);
        }
        if !self.schedule_in_flight && self.next_schedule_query.is_some_and(|t| now >= t) {
            self.schedule_in_flight = true;
            out.push(Output::RequestSchedule);
        }
        if now >= self.next_status {
            out.push(Output::Status(self.status(now)));
            self.next_status = now + self.config.status_every;
        }
    }

    /// Programs every burst whose programming time has come, with the
    /// newest clock estimate; a burst too close to program is skipped.
    fn program_due(&mut self, now: Time, out: &mut Vec<Output>) {
        let Some(estimate) = self.sync.estimate() else {
            return;
        };
        while let Some(&Reverse((master, tx_id, cycle, planned, epoch))) = self.pending.peek() {
            if estimate.to_local(master) - PROGRAM_AHEAD > now {
                break;
            }
            self.pending.pop();
            if self.step_candidates.0 > 0 {
                // The clock may have stepped: a burst at a wrong time is
                // heard by every robot as a wrong time difference; none is better.
                tracing::debug!(
                    "cell {}: cycle {cycle}: tx {tx_id} skipped (clock step suspected)",
                    self.cell_id
                );
                self.counters.slots_skipped += 1;
                continue;
            }
            let burst = PlannedBurst {
                tx_id,
                cycle,
                epoch,
                master,
                local: planned,
            };
            match self.timer.program(&burst, &estimate, now) {
                Some(b) => {
                    if b.cycle != self.counters.last_cycle_fired || self.counters.cycles_fired == 0
                    {
                        self.counters.cycles_fired += 1;
                        self.counters.last_cycle_fired = b.cycle;
                    }
                    out.push(Output::Fire(b));
                }
                None => {
                    self.counters.slots_skipped += 1;
                    if self.counters.slots_skipped.is_power_of_two() {
                        tracing::warn!(
                            "cell {}: cycle {cycle}: tx {tx_id} skipped (woken too late to program it); {} skipped so far",
                            self.cell_id,
                            self.counters.slots_skipped
                        );
                    }
                }
            }
        }
    }

    /// The status report at local time `now`.
    pub fn status(&self, now: Time) -> CellStatus {
        let est = self.sync.estimate();
        CellStatus {
            cell_id: self.cell_id.clone(),
            stamp: est.map_or(now, |e| e.to_master(now)),
            offset_ns: est.map_or(0, |e| e.offset_ns.round() as i64),
            drift_ppb: est.map_or(0, |e| (e.drift * 1e9).round() as i64),
            offset_sigma_ns: est.map_or(0, |e| e.sigma_ns.round() as i64),
            sync_samples: u32::try_from(self.sync.len()).unwrap_or(u32::MAX),
            last_cycle_fired: self.counters.last_cycle_fired,
            cycles_fired: self.counters.cycles_fired,
            slots_skipped: self.counters.slots_skipped,
            faults: self.faults.clone(),
            inputs_refused: self.counters.refused(),
            device: String::new(),
        }
    }
}

#[cfg(test)]
mod forged_tests;
#[cfg(test)]
mod tests;
