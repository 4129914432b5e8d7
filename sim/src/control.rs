//! The site's control plane in virtual time: the central unit's core and
//! one cell controller core per cell, each cell on its own drifting clock,
//! joined by a simulated network (one-way delay, queueing jitter, a path
//! asymmetry per cell that no clock exchange can see). The same cores run
//! in the Zenoh nodes; here every message is an event on one queue, so a
//! run is deterministic and a minute of site takes milliseconds.
//!
//! Faults can be injected between two calls to [`ControlPlane::advance_to`]:
//! a cell killed and restarted, a cell's clock stepped.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use ickon_cell::core::{
    CellConfig, CellCore, CellCounters, Event as CellEvent, Output as CellOutput,
};
use ickon_cell::sync::ClockSample;
use ickon_central::core::{
    CentralConfig, CentralCore, Event as CentralEvent, Output as CentralOutput,
};
use ickon_proto::msg::control::{Burst, CycleTrigger, Schedule};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};
use rand_chacha::ChaCha8Rng;

use crate::clock::DeviceClock;
use crate::profile::ClockNoise;
use crate::rng;

/// How long a cell waits for a clock reply or a schedule before giving up.
const REQUEST_TIMEOUT: Duration = Duration::from_millis(500);
/// How long the central unit takes to notice a liveliness token come or go.
const LIVELINESS_DELAY: Duration = Duration::from_millis(2);

/// A burst a cell fired.
#[derive(Debug, Clone, PartialEq)]
pub struct FiredBurst {
    /// The cell.
    pub cell_id: String,
    /// The transmitter.
    pub tx_id: u32,
    /// The cycle.
    pub cycle: u64,
    /// When it should have been emitted, master (= true) time.
    pub scheduled: Time,
    /// When it was emitted, true time.
    pub actual: Time,
}

impl FiredBurst {
    /// Actual minus scheduled emission time, nanoseconds.
    pub fn sync_error_ns(&self) -> i64 {
        self.actual.since(self.scheduled).as_nanos()
    }
}

/// One cell's synchronisation over a run, from its own bursts.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct CellSyncReport {
    /// The cell.
    pub cell_id: String,
    /// Bursts fired.
    pub bursts: u64,
    /// Largest |actual - scheduled| emission time, microseconds.
    pub sync_error_max_us: f64,
    /// RMS of actual - scheduled, microseconds.
    pub sync_error_rms_us: f64,
    /// What the cell's core counted.
    pub counters: CellCounters,
}

/// What happens at a time on the queue.
#[derive(Debug, Clone)]
enum Pending {
    CentralWake,
    CellWake(usize),
    /// An event for incarnation `.1` of cell `.0`; dropped if it was killed since.
    ToCell(usize, u32, CellEvent),
    CellAlive(usize, bool),
    ScheduleQuery(usize, u32),
    ToCentralBurst(Burst),
    ToCentralStatus(ickon_proto::msg::control::CellStatus),
    /// A robot's message (pose, liveliness) reaching the central unit.
    ToCentral(CentralEvent),
}

/// An entry of the queue, ordered by (time, sequence).
#[derive(Debug, Clone)]
struct Entry {
    t_ns: i64,
    seq: u64,
    what: Pending,
}

impl PartialEq for Entry {
    fn eq(&self, o: &Self) -> bool {
        (self.t_ns, self.seq) == (o.t_ns, o.seq)
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.t_ns, self.seq).cmp(&(o.t_ns, o.seq))
    }
}

/// A cell's sync errors over a run, summed as they come (a run of hours
/// keeps three numbers, not every burst).
#[derive(Debug, Clone, Copy, Default)]
struct SyncErrorSum {
    bursts: u64,
    max_abs_ns: u64,
    sum_sq_ns2: f64,
}

impl SyncErrorSum {
    fn add(&mut self, error_ns: i64) {
        self.bursts += 1;
        self.max_abs_ns = self.max_abs_ns.max(error_ns.unsigned_abs());
        self.sum_sq_ns2 += (error_ns as f64) * (error_ns as f64);
    }
}

/// One simulated cell: its clock, its core while it runs, its path.
struct SimCell {
    id: String,
    clock: DeviceClock,
    core: Option<CellCore>,
    /// Outward minus return delay, nanoseconds.
    asymmetry_ns: f64,
    /// The true time of the wake-up on the queue.
    wake_ns: Option<i64>,
    /// Stopped (SIGSTOP): alive to the central unit, but it hears and does nothing.
    hung: bool,
    /// Counts restarts, so that a message to a killed incarnation is dropped.
    incarnation: u32,
    sync: SyncErrorSum,
    counters_before: CellCounters,
}

impl SimCell {
    fn local(&self, t_ns: i64) -> Time {
        Time::from_nanos((self.clock.local_s(t_ns as f64 * 1e-9) * 1e9).round() as i64)
    }
    fn true_ns(&self, local: Time) -> i64 {
        (self.clock.true_s(local.as_nanos() as f64 * 1e-9) * 1e9).round() as i64
    }
}

/// The central unit and the cells on one virtual-time queue.
pub struct ControlPlane {
    central: CentralCore,
    central_wake_ns: Option<i64>,
    cells: Vec<SimCell>,
    queue: BinaryHeap<Reverse<Entry>>,
    seq: u64,
    now_ns: i64,
    net: ClockNoise,
    net_rng: ChaCha8Rng,
    fired: Vec<FiredBurst>,
    triggers: Vec<CycleTrigger>,
    statuses: Vec<ickon_proto::msg::control::CellStatus>,
    surveys: Vec<ickon_proto::msg::control::SurveyCalibration>,
}

impl ControlPlane {
    /// A control plane for `site`, clocks and network drawn from `clocks`
    /// with `seed`; every cell starts at true time 0.
    pub fn new(
        site: &Site,
        clocks: &ClockNoise,
        seed: u64,
    ) -> Result<Self, ickon_central::ScheduleError> {
        Self::with_config(site, clocks, seed, CentralConfig::default())
    }

    /// As [`new`](Self::new), the central unit tuned by `config` (which
    /// schedule, which transmitters fire).
    pub fn with_config(
        site: &Site,
        clocks: &ClockNoise,
        seed: u64,
        config: CentralConfig,
    ) -> Result<Self, ickon_central::ScheduleError> {
        let central = CentralCore::new(site.clone(), String::new(), config, Time(0))?;
        let cells = site
            .cells
            .iter()
            .map(|c| {
                let mut r = rng::stream(seed, &format!("cell/{}/clock", c.id));
                SimCell {
                    id: c.id.clone(),
                    clock: DeviceClock {
                        offset_s: rng::normal(&mut r, clocks.cell_offset_sigma_ms) * 1e-3,
                        drift: rng::normal(&mut r, clocks.cell_drift_sigma_ppm) * 1e-6,
                    },
                    core: None,
                    asymmetry_ns: rng::normal(&mut r, clocks.net_asymmetry_sigma_us) * 1e3,
                    wake_ns: None,
                    hung: false,
                    incarnation: 0,
                    sync: SyncErrorSum::default(),
                    counters_before: CellCounters::default(),
                }
            })
            .collect();
        let mut cp = Self {
            central,
            central_wake_ns: None,
            cells,
            queue: BinaryHeap::new(),
            seq: 0,
            now_ns: 0,
            net: *clocks,
            net_rng: rng::stream(seed, "network"),
            fired: Vec::new(),
            triggers: Vec::new(),
            statuses: Vec::new(),
            surveys: Vec::new(),
        };
        for i in 0..cp.cells.len() {
            cp.start_cell(i);
        }
        cp.schedule_central_wake();
        Ok(cp)
    }

    /// The central unit's core.
    pub fn central(&self) -> &CentralCore {
        &self.central
    }

    /// The current true time, nanoseconds.
    pub fn now(&self) -> Time {
        Time::from_nanos(self.now_ns)
    }

    /// Bursts fired since the last call.
    pub fn take_fired(&mut self) -> Vec<FiredBurst> {
        std::mem::take(&mut self.fired)
    }

    /// Cycle triggers the central unit published since the last call.
    pub fn take_triggers(&mut self) -> Vec<CycleTrigger> {
        std::mem::take(&mut self.triggers)
    }

    /// Cell statuses published since the last call (the MSUs hear them as
    /// the central unit does).
    pub fn take_statuses(&mut self) -> Vec<ickon_proto::msg::control::CellStatus> {
        std::mem::take(&mut self.statuses)
    }

    /// Survey calibrations the central unit published since the last call
    /// (for the MSUs; the cells do not hear them).
    pub fn take_surveys(&mut self) -> Vec<ickon_proto::msg::control::SurveyCalibration> {
        std::mem::take(&mut self.surveys)
    }

    /// What each cell's core counted and how well it kept time.
    pub fn sync_reports(&self) -> Vec<CellSyncReport> {
        self.cells
            .iter()
            .map(|c| {
                let s = c.sync;
                let ms = s.sum_sq_ns2 / s.bursts.max(1) as f64;
                let now = c.core.as_ref().map(CellCore::counters).unwrap_or_default();
                CellSyncReport {
                    cell_id: c.id.clone(),
                    bursts: s.bursts,
                    sync_error_max_us: s.max_abs_ns as f64 * 1e-3,
                    sync_error_rms_us: ms.sqrt() * 1e-3,
                    counters: c.counters_before.then(now),
                }
            })
            .collect()
    }

    fn cell_index(&self, id: &str) -> Option<usize> {
        self.cells.iter().position(|c| c.id == id)
    }

    /// Kills cell `id` now (its process ends; its token goes). `false` if
    /// there is no such cell or it is not running.
    pub fn kill_cell(&mut self, id: &str) -> bool {
        let Some(i) = self.cell_index(id) else {
            return false;
        };
        let Some(core) = self.cells[i].core.take() else {
            return false;
        };
        self.cells[i].counters_before = self.cells[i].counters_before.then(core.counters());
        self.cells[i].incarnation += 1;
        self.cells[i].wake_ns = None;
        self.push(LIVELINESS_DELAY, Pending::CellAlive(i, false));
        true
    }

    /// Starts cell `id` again (a new process on the same hardware clock).
    /// `false` if there is no such cell or it is running.
    pub fn restart_cell(&mut self, id: &str) -> bool {
        match self.cell_index(id) {
            Some(i) if self.cells[i].core.is_none() => {
                self.start_cell(i);
                true
            }
            _ => false,
        }
    }

    /// Stops cell `id` as SIGSTOP would: its token stays, it fires, answers
    /// and hears nothing until [`resume_cell`](Self::resume_cell) (what it
    /// missed meanwhile is lost). `false` for an unknown cell.
    pub fn hang_cell(&mut self, id: &str) -> bool {
        let Some(i) = self.cell_index(id) else {
            return false;
        };
        self.cells[i].hung = true;
        self.cells[i].wake_ns = None;
        true
    }

    /// Lets a hung cell go on. `false` for an unknown cell.
    pub fn resume_cell(&mut self, id: &str) -> bool {
        let Some(i) = self.cell_index(id) else {
            return false;
        };
        self.cells[i].hung = false;
        self.deliver_to_cell(i, CellEvent::Tick);
        true
    }

    /// Steps cell `id`'s clock by `step` (a clock that jumped: a bad
    /// oscillator, an operator setting the time). `false` for an unknown cell.
    pub fn step_cell_clock(&mut self, id: &str, step: Duration) -> bool {
        let Some(i) = self.cell_index(id) else {
            return false;
        };
        self.cells[i].clock.offset_s += step.as_secs_f64();
        self.reschedule_cell(i);
        true
    }

    fn start_cell(&mut self, i: usize) {
        let local = self.cells[i].local(self.now_ns);
        self.cells[i].core = Some(CellCore::new(
            &self.cells[i].id,
            CellConfig::default(),
            local,
        ));
        self.push(LIVELINESS_DELAY, Pending::CellAlive(i, true));
        self.deliver_to_cell(i, CellEvent::Tick);
    }

    /// One message's network delay, nanoseconds; `direction` +1 outward
    /// (cell to central), -1 back, 0 for a message without a fixed path.
    fn net_delay(&mut self, asymmetry_ns: f64, direction: f64) -> Duration {
        let jitter = if self.net.net_jitter_us > 0.0 {
            let u = rng::uniform(&mut self.net_rng, 0.0, 1.0);
            -self.net.net_jitter_us * 1e3 * (1.0 - u).ln()
        } else {
            0.0
        };
        let d = self.net.net_delay_us * 1e3 + direction * asymmetry_ns / 2.0 + jitter;
        Duration::from_nanos(d.max(0.0).round() as i64)
    }

    fn push(&mut self, after: Duration, what: Pending) {
        self.push_at(self.now_ns + after.as_nanos(), what);
    }

    fn push_at(&mut self, t_ns: i64, what: Pending) {
        self.seq += 1;
        self.queue.push(Reverse(Entry {
            t_ns,
            seq: self.seq,
            what,
        }));
    }

    fn schedule_central_wake(&mut self) {
        let t = self.central.next_wake().as_nanos().max(self.now_ns);
        if self.central_wake_ns != Some(t) {
            self.central_wake_ns = Some(t);
            self.push_at(t, Pending::CentralWake);
        }
    }

    fn reschedule_cell(&mut self, i: usize) {
        let Some(core) = &self.cells[i].core else {
            return;
        };
        // Strictly after now: the cell has just done what was due at now,
        // and a wake-up rounded back to now (local and true clocks differ
        // by a fraction of a nanosecond) would wake it at now for ever.
        let t = self.cells[i].true_ns(core.next_wake()).max(self.now_ns + 1);
        if self.cells[i].wake_ns != Some(t) {
            self.cells[i].wake_ns = Some(t);
            self.push_at(t, Pending::CellWake(i));
        }
    }

    /// Processes every event up to true time `t` (inclusive).
    pub fn advance_to(&mut self, t: Time) {
        while let Some(Reverse(e)) = self.queue.peek() {
            if e.t_ns > t.as_nanos() {
                break;
            }
            let Some(Reverse(e)) = self.queue.pop() else {
                break;
            };
            self.now_ns = self.now_ns.max(e.t_ns);
            self.dispatch(e.t_ns, e.what);
        }
        self.now_ns = self.now_ns.max(t.as_nanos());
    }

    fn dispatch(&mut self, t_ns: i64, what: Pending) {
        match what {
            Pending::CentralWake => {
                if self.central_wake_ns == Some(t_ns) {
                    self.central_wake_ns = None;
                    let out = self
                        .central
                        .handle(Time::from_nanos(t_ns), CentralEvent::Tick);
                    self.publish_central(out);
                }
                self.schedule_central_wake();
            }
            Pending::CellWake(i) => {
                if self.cells[i].wake_ns == Some(t_ns) {
                    self.cells[i].wake_ns = None;
                    self.deliver_to_cell(i, CellEvent::Tick);
                }
            }
            Pending::ToCell(i, inc, ev) => {
                if self.cells[i].incarnation == inc {
                    self.deliver_to_cell(i, ev);
                }
            }
            Pending::CellAlive(i, up) => {
                let id = self.cells[i].id.clone();
                let out = self
                    .central
                    .handle(Time::from_nanos(t_ns), CentralEvent::CellAlive { id, up });
                self.publish_central(out);
                self.schedule_central_wake();
            }
            Pending::ScheduleQuery(i, inc) => {
                let s = self.central.latest_schedule().clone();
                let back = self.net_delay(self.cells[i].asymmetry_ns, -1.0);
                self.push(back, Pending::ToCell(i, inc, CellEvent::Schedule(s)));
            }
            Pending::ToCentralBurst(b) => {
                let out = self
                    .central
                    .handle(Time::from_nanos(t_ns), CentralEvent::Burst(b));
                self.publish_central(out);
            }
            Pending::ToCentral(event) => {
                let out = self.central.handle(Time::from_nanos(t_ns), event);
                self.publish_central(out);
                self.schedule_central_wake();
            }
            Pending::ToCentralStatus(s) => {
                self.statuses.push(s.clone());
                let out = self
                    .central
                    .handle(Time::from_nanos(t_ns), CentralEvent::CellStatus(s));
                self.publish_central(out);
            }
        }
    }

    /// Sends the central unit's outputs to every running cell.
    fn publish_central(&mut self, out: Vec<CentralOutput>) {
        for o in out {
            let event = match o {
                CentralOutput::Trigger(t) => {
                    self.triggers.push(t.clone());
                    CellEvent::Trigger(t)
                }
                CentralOutput::Schedule(s) => CellEvent::Schedule(s),
                CentralOutput::Survey(s) => {
                    self.surveys.push(s);
                    continue;
                }
            };
            for i in 0..self.cells.len() {
                if self.cells[i].core.is_some() {
                    let d = self.net_delay(0.0, 0.0);
                    let inc = self.cells[i].incarnation;
                    self.push(d, Pending::ToCell(i, inc, event.clone()));
                }
            }
        }
    }

    /// Gives cell `i` an event at the current true time and carries out
    /// what it asks for; a dead cell hears nothing.
    fn deliver_to_cell(&mut self, i: usize, event: CellEvent) {
        let local = self.cells[i].local(self.now_ns);
        if self.cells[i].hung {
            return;
        }
        let Some(core) = self.cells[i].core.as_mut() else {
            return;
        };
        let outputs = core.handle(local, event);
        for o in outputs {
            match o {
                CellOutput::Fire(b) => {
                    let cell = &mut self.cells[i];
                    let actual = Time::from_nanos(cell.true_ns(b.local));
                    let fired = FiredBurst {
                        cell_id: cell.id.clone(),
                        tx_id: b.tx_id,
                        cycle: b.cycle,
                        scheduled: b.master,
                        actual,
                    };
                    cell.sync.add(fired.sync_error_ns());
                    let report = Burst {
                        cell_id: cell.id.clone(),
                        tx_id: b.tx_id,
                        cycle: b.cycle,
                        scheduled: b.master,
                        actual,
                        epoch: b.epoch,
                    };
                    self.fired.push(fired);
                    let d = self.net_delay(self.cells[i].asymmetry_ns, 1.0);
                    self.push(d, Pending::ToCentralBurst(report));
                }
                CellOutput::Status(s) => {
                    let d = self.net_delay(self.cells[i].asymmetry_ns, 1.0);
                    self.push(d, Pending::ToCentralStatus(s));
                }
                CellOutput::RequestClock => self.clock_exchange(i, local),
                CellOutput::RequestSchedule => {
                    let d = self.net_delay(self.cells[i].asymmetry_ns, 1.0);
                    let inc = self.cells[i].incarnation;
                    self.push(d, Pending::ScheduleQuery(i, inc));
                }
            }
        }
        self.reschedule_cell(i);
    }

    /// One four-timestamp exchange: the master answers at once on its
    /// (true) time base; the reply reaches the cell after the return leg.
    fn clock_exchange(&mut self, i: usize, t1: Time) {
        let asym = self.cells[i].asymmetry_ns;
        let out = self.net_delay(asym, 1.0);
        let back = self.net_delay(asym, -1.0);
        let t2 = Time::from_nanos(self.now_ns) + out;
        let arrive_ns = t2.as_nanos() + back.as_nanos();
        let sample = ClockSample {
            t1,
            t2,
            t3: t2,
            t4: self.cells[i].local(arrive_ns),
            epoch: self.central.epoch(),
            queued_ns: 0,
        };
        let reply = if back + out > REQUEST_TIMEOUT {
            None
        } else {
            Some(sample)
        };
        let inc = self.cells[i].incarnation;
        self.push_at(
            arrive_ns,
            Pending::ToCell(i, inc, CellEvent::ClockExchange(reply)),
        );
    }

    /// A robot's message to the central unit (a pose, its liveliness),
    /// sent now; it arrives after the network's delay.
    pub fn send_to_central(&mut self, event: CentralEvent) {
        let d = self.net_delay(0.0, 0.0);
        self.push(d, Pending::ToCentral(event));
    }

    /// Air temperature readings of the cells' boards, (cell, true seconds
    /// measured, degrees Celsius): each forwarded by its cell to the
    /// central unit, arriving after the network's delay.
    pub fn send_air_temperatures(&mut self, readings: Vec<(String, f64, f64)>) {
        for (cell_id, at_s, temperature_c) in readings {
            self.send_to_central(CentralEvent::AirTemperature(
                ickon_proto::msg::control::AirTemperature {
                    cell_id,
                    stamp: Time::from_secs_f64(at_s),
                    temperature_c,
                },
            ));
        }
    }

    /// The schedule the central unit has in force for `cycle`.
    pub fn schedule_for(&self, cycle: u64) -> &Schedule {
        self.central.schedule_for(cycle)
    }
}

#[cfg(test)]
mod tests;
