//! The MSU's fix solver: one cycle's arrivals -> assembled signals -> a raw
//! fix (the ICKON paper, eq. 1-3 with refinement and reflection rejection,
//! [`tdoa::solve`]), its quality gate and the receiver-id heading (eq. 4-6).
//! Each arrival is related to the receiver's position at its own arrival
//! time, from the wheels' motion between arrivals ([`crate::motion`],
//! [`tdoa::solve_moving`]); the fix is the position at the cycle's stamp.
//! It knows nothing of the estimators: a position hint is passed in only to
//! choose between two roots that fit equally, so every valid fix is the
//! same whatever fuses it.
//!
//! A cycle that gives no fix, or a suspect one, gets a second attempt
//! (kept when it is not suspect) without the
//! transmitters the site's walls and columns hide from everywhere the
//! receiver may be (by the solver's own last good fix and the odometry
//! since): those can only have been heard by a reflection. Behind racks
//! a cycle can carry as many reflections as direct signals, and the
//! consensus then (rightly) finds no majority. Those transmitters'
//! arrivals never reach the tightly coupled filter at all: a reflection a
//! few centimetres long passes its gate and bends the track (on
//! `warehouse`'s `rack-2`, seed 2, 39.3 mm mean with them, 25.7 without).

use ickon_fusion::estimator::{Input, RangeDifferenceSample, TransmitterClock};
use ickon_fusion::tdoa;
use ickon_proto::epoch::{ScheduleBook, ScheduleRefused};
use ickon_proto::msg::control::{CycleTrigger, Emission, Schedule, SurveyCalibration};
use ickon_proto::msg::robot::{Fix, FixQuality, UltrasoundArrivals};
use ickon_proto::site::line_of_sight;
use ickon_proto::time::{Duration, Time};
use nalgebra::{Vector2, Vector3};

use crate::assembly::{Signal, assemble, clock_of_cell};
use crate::config::MsuConfig;
use crate::control_timing::PendingControl;
use crate::cycle_match::{Clarity, Matched, RecentTriggers, cycle_start_ns};
use crate::error::MsuError;
use crate::fusion_clock::FusionClock;
use crate::motion::CycleMotion;

/// The solver's own last fix serves as the root hint for this long.
const OWN_HINT_MAX_AGE: Duration = Duration::from_millis(2_000);
/// The last good fix places the receiver for the second attempt this long,
/// seconds (a few cycles).
const HIDDEN_CHECK_MAX_AGE_S: f64 = 1.0;
/// Added to the region the receiver may be in for the second attempt,
/// metres: the odometry's own error over a second, and the receivers'
/// spread on the robot.
const HIDDEN_CHECK_MARGIN_M: f64 = 0.1;
/// A region wider than this says too little to hide anything, metres.
const HIDDEN_CHECK_MAX_RADIUS_M: f64 = 1.0;

/// What one cycle gave.
#[derive(Debug, Clone, PartialEq)]
pub struct SolvedCycle {
    /// The raw fix (what the estimators consume) and its wire encoding,
    /// `None` when the cycle gave none (too few or inconsistent signals,
    /// degenerate geometry, off the floor, too uncertain).
    pub fix: Option<(tdoa::Fix, Fix)>,
    /// The cycle's range differences, for tightly coupled estimators,
    /// whether or not a fix was solved.
    pub range_differences: Vec<RangeDifferenceSample>,
}

/// Solves cycles against the schedule in force.
#[derive(Debug, Clone)]
pub struct FixSolver {
    config: MsuConfig,
    schedules: ScheduleBook,
    /// The triggers heard from the central unit, when the MSU follows them.
    recent_triggers: RecentTriggers,
    last_fix: Option<(Time, Vector2<f64>)>,
    /// The last fix whose every signal was checked (`Quality::Good`): its
    /// fusion time, position and one-sigma uncertainty, metres.
    last_good: Option<(f64, [f64; 2], f64)>,
    motion: CycleMotion,
    /// The sync sigma each cell last reported, seconds, by clock id (see
    /// [`crate::assembly::Signal::clock`]).
    cell_sync_sigma_s: std::collections::BTreeMap<u32, f64>,
    /// The surveyed positions of the table, metres, by transmitter id (the
    /// table's own positions carry the fleet's calibration when one applies).
    surveyed_m: std::collections::BTreeMap<u32, [f64; 3]>,
    /// How late each transmitter's bursts arrive, metres of path, by id
    /// (the calibration's `late_m`; absent: on time).
    late_m: std::collections::BTreeMap<u32, f64>,
    /// Transmitters the calibration leaves out (dead, weak or moved):
    /// their arrivals are dropped before any fix.
    left_out: std::collections::BTreeSet<u32>,
    /// The site's speed of sound, m/s: what is solved with when no
    /// calibration says otherwise.
    site_speed_of_sound_m_s: f64,
    /// The relative sigma of the learnt speed of sound solved with, when
    /// the calibration published one (`None`: the site's, whose sigma the
    /// estimators take from their own sheet).
    speed_rel_sigma: Option<f64>,
    /// `(epoch, version)` of the survey calibration the table carries.
    survey: Option<(u64, u32)>,
    /// A calibration and sync sigmas taken while triggers are followed,
    /// waiting for the cycle they name ([`crate::control_timing`]).
    pending: PendingControl,
}

impl FixSolver {
    /// A solver for an MSU configured as `config`, with no schedule yet.
    pub fn new(config: MsuConfig) -> Self {
        let surveyed_m = config
            .transmitters
            .iter()
            .map(|t| (t.tx_id, [t.x_m, t.y_m, t.z_m]))
            .collect();
        Self {
            surveyed_m,
            late_m: std::collections::BTreeMap::new(),
            left_out: std::collections::BTreeSet::new(),
            site_speed_of_sound_m_s: config.speed_of_sound_m_s,
            speed_rel_sigma: None,
            survey: None,
            pending: PendingControl::default(),
            config,
            schedules: ScheduleBook::new(),
            recent_triggers: RecentTriggers::default(),
            last_fix: None,
            last_good: None,
            motion: CycleMotion::new(),
            cell_sync_sigma_s: std::collections::BTreeMap::new(),
        }
    }

    /// The clock of cell `cell_id` ([`Signal::clock`]), `None` when the
    /// cell is not one of this site's.
    pub fn clock_of_cell(&self, cell_id: &str) -> Option<u32> {
        clock_of_cell(&self.config.transmitters, cell_id)
    }

    /// Takes the sync sigma the cell of `clock` reports in a status made
    /// at `stamp` (master time), seconds (clocks come from
    /// [`Self::clock_of_cell`], so the table never grows beyond the site's
    /// cells): while triggers are followed, from the first cycle that
    /// starts after the status ([`crate::control_timing`]); else at once.
    pub fn take_clock_sync_sigma(&mut self, clock: u32, stamp: Time, sigma_s: f64) {
        if self.recent_triggers.is_empty() {
            // An older report held for a cycle must not come after it.
            self.pending.forget_sync_sigma(clock);
            self.cell_sync_sigma_s.insert(clock, sigma_s);
        } else {
            self.pending.hold_sync_sigma(clock, stamp, sigma_s);
        }
    }

    /// The clock of signal `s` as the filters take it: its cell and the
    /// sync sigma that cell reported (0 before any report), metres of path.
    fn transmitter_clock(&self, s: &Signal) -> TransmitterClock {
        let sigma_s = self.cell_sync_sigma_s.get(&s.clock).copied().unwrap_or(0.0);
        TransmitterClock {
            id: s.clock,
            sync_sigma_m: sigma_s * self.config.speed_of_sound_m_s,
        }
    }

    /// Takes the robot's odometry (encoder ticks or odometry poses, in
    /// fusion time), which moves the receiver between the arrivals of a
    /// cycle.
    pub fn odometry(&mut self, input: &Input) {
        self.motion.odometry(input);
    }

    /// Solves from now on with each transmitter at its surveyed position
    /// plus its offset in `calibration`, its pseudo-ranges shortened by its
    /// lateness (a transmitter it does not name: the surveyed position, on
    /// time), the transmitters it leaves out left out, and its speed of
    /// sound; `None`: the surveyed positions, on time, every transmitter,
    /// the site's speed of sound. The caller checks the calibration
    /// ([`crate::MsuCore::on_survey_calibration`]).
    pub fn set_survey_calibration(&mut self, calibration: Option<&SurveyCalibration>) {
        let offsets: std::collections::BTreeMap<u32, [f64; 3]> = calibration
            .map(|c| c.offsets.iter().map(|o| (o.tx_id, o.offset_m)).collect())
            .unwrap_or_default();
        for t in &mut self.config.transmitters {
            if let Some(&[x, y, z]) = self.surveyed_m.get(&t.tx_id) {
                let [dx, dy, dz] = offsets.get(&t.tx_id).copied().unwrap_or([0.0; 3]);
                (t.x_m, t.y_m, t.z_m) = (x + dx, y + dy, z + dz);
            }
        }
        self.late_m = calibration
            .map(|c| c.offsets.iter().map(|o| (o.tx_id, o.late_m)).collect())
            .unwrap_or_default();
        self.left_out = calibration
            .map(|c| {
                c.offsets
                    .iter()
                    .filter(|o| o.left_out)
                    .map(|o| o.tx_id)
                    .collect()
            })
            .unwrap_or_default();
        self.config.speed_of_sound_m_s = calibration.map_or(self.site_speed_of_sound_m_s, |c| {
            c.speed_of_sound_or(self.site_speed_of_sound_m_s)
        });
        self.speed_rel_sigma = calibration
            .filter(|c| c.speed_of_sound_m_s > 0.0 && c.speed_of_sound_sigma_m_s > 0.0)
            .map(|c| c.speed_of_sound_sigma_m_s / c.speed_of_sound_m_s);
        self.survey = calibration.map(|c| (c.epoch, c.version));
    }

    /// Takes a checked calibration ([`crate::MsuCore::on_survey_calibration`]):
    /// while the MSU follows the central unit's triggers, from the first
    /// cycle whose trigger came after it ([`crate::control_timing`]); else
    /// at once.
    pub fn take_survey_calibration(&mut self, calibration: &SurveyCalibration) {
        match self.recent_triggers.newest() {
            Some(heard) => self.pending.hold_survey(calibration, heard),
            None => {
                self.pending.forget_survey();
                self.set_survey_calibration(Some(calibration));
            }
        }
    }

    /// Takes what was held for the cycle being solved (its trigger
    /// `matched`; `None` while triggers are followed: no trigger explains
    /// the arrivals, so they name no cycle, and nothing is due).
    fn apply_due_control(&mut self, matched: Option<&CycleTrigger>) {
        if matched.is_none() && !self.recent_triggers.is_empty() {
            return;
        }
        let due = self.pending.due(matched);
        if let Some(c) = due.survey {
            self.set_survey_calibration(Some(&c));
        }
        self.cell_sync_sigma_s.extend(due.sync_sigma_s);
    }

    /// `(epoch, version)` of the survey calibration solved with, `None`:
    /// the surveyed positions.
    pub fn survey_calibration(&self) -> Option<(u64, u32)> {
        self.survey
    }

    /// `(epoch, version)` of the newest calibration taken, applied or
    /// waiting for its first cycle.
    pub fn newest_survey_calibration(&self) -> Option<(u64, u32)> {
        self.pending.survey_held().or(self.survey)
    }

    /// The epoch of the schedules followed.
    pub fn schedule_epoch(&self) -> Option<u64> {
        self.schedules.epoch()
    }

    /// The site's speed of sound, m/s (the configuration's is the one
    /// solved with, the calibration's when one applies).
    pub fn site_speed_of_sound_m_s(&self) -> f64 {
        self.site_speed_of_sound_m_s
    }

    /// The configuration.
    pub fn config(&self) -> &MsuConfig {
        &self.config
    }

    /// How far the robot drove between two fusion times, by its odometry
    /// ([`CycleMotion::travelled_m`]).
    pub fn travelled_m(&self, from_s: f64, to_s: f64) -> Option<f64> {
        self.motion.travelled_m(from_s, to_s)
    }

    /// Takes the schedule the arrivals are matched against (the newest
    /// the rules of [`ickon_proto::epoch`] allow; a refused one changes nothing).
    pub fn set_schedule(&mut self, schedule: Schedule) -> Result<(), ScheduleRefused> {
        self.schedules.offer(schedule)?;
        // A calibration is its central unit's: a new one starts from the
        // survey (its fixes' versions would otherwise name the old one's).
        if let Some((epoch, _)) = self.survey
            && self.schedules.epoch() != Some(epoch)
        {
            self.set_survey_calibration(None);
        }
        self.pending.keep_survey_of(self.schedules.epoch());
        Ok(())
    }

    /// A cycle trigger heard from the central unit: later arrivals are
    /// matched to the recent trigger that explains them best
    /// ([`crate::cycle_match`]), whose firings and offsets they are solved
    /// with.
    pub fn note_trigger(&mut self, trigger: CycleTrigger) {
        self.recent_triggers.note(trigger, &self.schedules);
    }

    /// Forgets the schedules (tests; a site that changed).
    pub fn clear_schedule(&mut self) {
        self.schedules.clear();
    }

    /// The solver set-up: 2D with the MSU height known, the timing noise as
    /// range noise, the reflection gate, and the floor as the allowed area.
    fn solver_config(&self) -> tdoa::SolverConfig {
        let height_m = self.config.height_m;
        tdoa::SolverConfig {
            mode: tdoa::Mode::TwoD { height_m },
            sigma_range_m: (self.config.speed_of_sound_m_s * self.config.timing_sigma_s).max(1e-6),
            gate: tdoa::Gate::Metres(self.config.residual_gate_m),
            allowed_area_m: self.config.floor_bounds_m.map(|[lo, hi]| tdoa::Aabb {
                min_m: Vector3::new(lo[0], lo[1], height_m),
                max_m: Vector3::new(hi[0], hi[1], height_m),
            }),
            ..tdoa::SolverConfig::default()
        }
    }

    /// Solves one cycle. When two roots fit, the one nearer the solver's own
    /// fix of the last two seconds is kept, else the one nearer `hint`
    /// (where the robot is believed to be), else the solver's first choice.
    pub fn solve(
        &mut self,
        msg: &UltrasoundArrivals,
        hint: Option<[f64; 2]>,
        clock: &mut FusionClock,
    ) -> Result<SolvedCycle, MsuError> {
        let mut matching = self.match_trigger(msg, hint);
        self.apply_due_control(matching.matched.as_ref().map(|m| &m.trigger));
        let trigger = matching.matched.as_ref().map(|m| &m.trigger);
        let published = match trigger {
            Some(t) => self.schedules.get(t.schedule_version),
            None => self.schedules.latest(),
        }
        .ok_or(MsuError::NoSchedule)?;
        let of_cycle = trigger.map(|t| t.schedule_of_cycle(published));
        let schedule = of_cycle.as_ref().unwrap_or(published);
        let c = self.config.speed_of_sound_m_s;
        let mut cycle = assemble(msg, schedule, &self.config.transmitters, c)?;
        for s in &mut cycle.signals {
            s.pseudo_range_m -= self.late_m.get(&s.tx_id).copied().unwrap_or(0.0);
        }
        // The signals left out stay at hand: with the others, every signal
        // heard, to measure the unused ones against the fix.
        let left_out = leave_out(&mut cycle, &self.left_out);
        let reference_s = clock.to_fusion(cycle.stamp);
        let hidden = self.hidden(&cycle.signals, reference_s);
        let range_differences = self.range_differences(&cycle.signals, &hidden, clock);
        let signals: Vec<tdoa::Signal> = cycle
            .signals
            .iter()
            .map(|s| tdoa::Signal {
                tx_id: s.tx_id,
                tx_m: Vector3::from(s.tx_m),
                pseudo_range_m: s.pseudo_range_m,
                t_s: clock.to_fusion(s.t_arrival),
            })
            .collect();
        let no_fix = |range_differences| {
            Ok(SolvedCycle {
                fix: None,
                range_differences,
            })
        };
        let arrival_times_s: Vec<f64> = cycle
            .signals
            .iter()
            .map(|s| clock.to_fusion(s.t_arrival))
            .collect();
        // Without a trusted motion the receiver counts as still (zero
        // displacements: exactly the static solve).
        let displacements = self
            .motion
            .displacements(&arrival_times_s, reference_s)
            .unwrap_or_else(|| vec![Vector3::zeros(); signals.len()]);
        let own = self
            .last_fix
            .filter(|(t, _)| cycle.stamp.since(*t) <= OWN_HINT_MAX_AGE)
            .map(|(_, p)| p);
        let hint = own.or(hint.map(Vector2::from));
        let mut unmatched = cycle.rejected.clone();
        let mut sol = match self.attempt_both(&signals, &displacements, hint, hidden)? {
            Attempts::WithoutHidden(sol, hidden) => {
                unmatched.extend(hidden.iter().map(|&k| cycle.signals[k].tx_id));
                sol
            }
            Attempts::All(sol) => sol,
            Attempts::NoFix => return no_fix(range_differences),
        };
        let sigma_m = sol.covariance_xy_m2().trace().max(0.0).sqrt();
        // The fix is stamped with the cycle's mean arrival time over every
        // arrival (exact in nanoseconds); its fusion time is that instant's
        // exact image, so the wire stamp and the estimators agree.
        sol.t_s = reference_s;
        sol.heading_rad = self.heading_of(&sol, &cycle.signals);
        if sol.quality != tdoa::Quality::Ambiguous {
            self.last_fix = Some((cycle.stamp, sol.position_m.xy()));
        }
        if sol.quality == tdoa::Quality::Good {
            // Only redundant fixes with every residual checked align the
            // odometry: a wrong root would turn the motion the wrong way.
            self.motion
                .fix(reference_s, [sol.position_m[0], sol.position_m[1]], sigma_m);
            self.last_good = Some((reference_s, [sol.position_m[0], sol.position_m[1]], sigma_m));
            // The clock offset serves the matching of later cycles.
            if matching.matched.is_some() {
                let from_fix = self.flights_from(Some([sol.position_m[0], sol.position_m[1]]));
                matching.teach_clock(
                    &mut self.recent_triggers,
                    msg,
                    &schedule.emissions,
                    &from_fix,
                );
            }
        }
        let mut wire = wire_fix(&sol, cycle.stamp, msg.seq, self.config.height_m, &unmatched);
        wire.survey_version = self.survey.map_or(0, |(_, version)| version);
        (wire.unused, wire.unused_residuals_m) =
            crate::unused_residuals::measured(&sol, &[&cycle.signals, &left_out], &wire.rejected);
        Ok(SolvedCycle {
            fix: Some((sol, wire)),
            range_differences,
        })
    }

    /// The recent trigger that explains `msg` best (`None` when no trigger
    /// was heard: the whole schedule fires), with the flight times the
    /// choice was made with when it awaits the next trigger. A matched
    /// trigger's firings and period replace the schedule's emissions for
    /// that cycle (the schedule itself, under the rules of
    /// [`ickon_proto::epoch`], stays as published).
    fn match_trigger(&mut self, msg: &UltrasoundArrivals, hint: Option<[f64; 2]>) -> TriggerMatch {
        // The flight times a choice awaiting the next trigger was made with.
        let mut flights_ns = Vec::new();
        let matched = if self.recent_triggers.is_empty() {
            // The whole schedule fires: nothing to match, no flight to work out.
            None
        } else {
            let flight_ns = self.expected_flights(msg, hint);
            let matched = self
                .recent_triggers
                .best_for(msg, &self.schedules, &flight_ns);
            if matched
                .as_ref()
                .is_some_and(|m| m.clarity == Clarity::AwaitingNext)
            {
                flights_ns = msg
                    .arrivals
                    .iter()
                    .filter_map(|a| Some((a.tx_id, flight_ns(a.tx_id)?)))
                    .collect();
            }
            matched
        };
        TriggerMatch {
            matched,
            flights_ns,
        }
    }

    /// The fix of a cycle: a solve of every signal and, when it gives none
    /// or a suspect one and some transmitters are `hidden`, a second solve
    /// without them, kept when it is not suspect (with the indices it left
    /// out).
    fn attempt_both(
        &self,
        signals: &[tdoa::Signal],
        displacements: &[Vector3<f64>],
        hint: Option<Vector2<f64>>,
        hidden: Vec<usize>,
    ) -> Result<Attempts, MsuError> {
        let first = self.attempt(signals, displacements, hint)?;
        let retry = first
            .as_ref()
            .is_none_or(|s| s.quality == tdoa::Quality::Suspect);
        let second = if !retry || hidden.is_empty() {
            None
        } else {
            let (signals, displacements): (Vec<_>, Vec<_>) = (0..signals.len())
                .filter(|k| !hidden.contains(k))
                .map(|k| (signals[k], displacements[k]))
                .unzip();
            self.attempt(&signals, &displacements, hint)?
                .filter(|s| s.quality != tdoa::Quality::Suspect)
                .map(|s| (s, hidden))
        };
        Ok(match (first, second) {
            (_, Some((sol, hidden))) => Attempts::WithoutHidden(sol, hidden),
            (Some(sol), None) => Attempts::All(sol),
            (None, None) => Attempts::NoFix,
        })
    }

    /// The robot's heading from the first emitted signal `sol` used
    /// (the ICKON paper, s3.1.3, eq. 4-6); `None` when its receiver gives none.
    fn heading_of(&self, sol: &tdoa::Fix, signals: &[Signal]) -> Option<f64> {
        sol.used_tx_ids.first().and_then(|id| {
            let s = signals.iter().find(|s| s.tx_id == *id)?;
            tdoa::heading_from_first_receiver(
                Vector2::new(s.tx_m[0], s.tx_m[1]),
                sol.position_m.xy(),
                usize::from(s.receiver_id),
                &self.config.receiver_angles_rad,
            )
            .ok()
        })
    }

    /// The flight time of each transmitter's burst to where the receiver
    /// probably is when `msg` was heard (its own fix of the last
    /// [`OWN_HINT_MAX_AGE`], else `hint`), nanoseconds; `None` when neither
    /// is known, or for a transmitter not in the site.
    fn expected_flights(
        &self,
        msg: &UltrasoundArrivals,
        hint: Option<[f64; 2]>,
    ) -> impl Fn(u32) -> Option<i64> + use<> {
        let heard_at = msg.arrivals.iter().map(|a| a.t_arrival).min();
        let own = self
            .last_fix
            .filter(|(t, _)| heard_at.is_some_and(|h| h.since(*t) <= OWN_HINT_MAX_AGE))
            .map(|(_, p)| [p.x, p.y]);
        self.flights_from(own.or(hint))
    }

    /// The flight time of each transmitter's burst to the receiver at
    /// `at` (metres; at the MSU's height), nanoseconds; `None` for every
    /// transmitter when `at` is `None` or not finite, or for one not in the site.
    fn flights_from(&self, at: Option<[f64; 2]>) -> impl Fn(u32) -> Option<i64> + use<> {
        let at = at.filter(|p| p[0].is_finite() && p[1].is_finite());
        let c = self.config.speed_of_sound_m_s;
        let flights: Vec<(u32, i64)> = match at {
            Some([x, y]) if c > 0.0 => self
                .config
                .transmitters
                .iter()
                .map(|t| {
                    let d = ((t.x_m - x).powi(2)
                        + (t.y_m - y).powi(2)
                        + (t.z_m - self.config.height_m).powi(2))
                    .sqrt();
                    // Bounded: a site file's coordinates are untrusted.
                    (t.tx_id, (d / c * 1e9).clamp(0.0, 1e9) as i64)
                })
                .collect(),
            _ => Vec::new(),
        };
        move |tx_id| {
            flights
                .iter()
                .find(|(id, _)| *id == tx_id)
                .map(|&(_, ns)| ns)
        }
    }

    /// One solve of `signals`: the fix when it is valid (a root chosen by
    /// `hint` when two fit, uncertainty within the configured bound),
    /// `None` when it is not; `Err` for input no solve can use.
    fn attempt(
        &self,
        signals: &[tdoa::Signal],
        displacements: &[Vector3<f64>],
        hint: Option<Vector2<f64>>,
    ) -> Result<Option<tdoa::Fix>, MsuError> {
        let mut sol = match tdoa::solve_moving(signals, displacements, &self.solver_config()) {
            Ok(sol) => sol,
            Err(e) if e.is_bad_input() => return Err(MsuError::Solve(e)),
            Err(_) => return Ok(None),
        };
        if let (tdoa::Quality::Ambiguous, Some(other), Some(h)) =
            (sol.quality, sol.alternative_m, hint)
        {
            let here = Vector3::new(h[0], h[1], self.config.height_m);
            if (other - here).norm() < (sol.position_m - here).norm() {
                sol.alternative_m = Some(sol.position_m);
                sol.position_m = other;
            }
        }
        let sigma_m = sol.covariance_xy_m2().trace().max(0.0).sqrt();
        Ok((sigma_m.is_finite() && sigma_m <= self.config.max_fix_sigma_m).then_some(sol))
    }

    /// Indices of `signals` whose transmitter the site's walls and columns
    /// hide from every place the receiver may be at fusion time `now_s`:
    /// within three sigma of the last good fix plus the odometry's
    /// displacement since (and [`HIDDEN_CHECK_MARGIN_M`]), tried at its
    /// centre and four points on its rim. Empty when that place is not
    /// known well enough (no good fix for [`HIDDEN_CHECK_MAX_AGE_S`], no
    /// odometry, a region over [`HIDDEN_CHECK_MAX_RADIUS_M`]).
    fn hidden(&self, signals: &[Signal], now_s: f64) -> Vec<usize> {
        let c = &self.config;
        if c.walls.is_empty() && c.columns.is_empty() {
            return Vec::new();
        }
        let Some((t_s, xy, sigma_m)) = self.last_good else {
            return Vec::new();
        };
        if !(now_s >= t_s && now_s - t_s <= HIDDEN_CHECK_MAX_AGE_S) {
            return Vec::new();
        }
        let Some(driven_m) = self.motion.travelled_m(t_s, now_s) else {
            return Vec::new();
        };
        let r = 3.0 * sigma_m + 1.1 * driven_m + HIDDEN_CHECK_MARGIN_M;
        if !(r.is_finite() && r <= HIDDEN_CHECK_MAX_RADIUS_M) {
            return Vec::new();
        }
        let places = [[0.0, 0.0], [r, 0.0], [-r, 0.0], [0.0, r], [0.0, -r]]
            .map(|d| [xy[0] + d[0], xy[1] + d[1], c.height_m]);
        (0..signals.len())
            .filter(|&k| {
                !places
                    .iter()
                    .any(|&at| line_of_sight(&c.walls, &c.columns, signals[k].tx_m, at))
            })
            .collect()
    }

    /// The cycle's arrivals as time differences, for tightly coupled
    /// filters such as `tdoa-ekf`, without the arrivals of `hidden`
    /// transmitters (heard only by a reflection, see [`Self::hidden`]).
    /// Pairs are consecutive in emission order:
    /// the robot moves only during one slot between the two arrivals of a
    /// pair (about 1 cm at 0.3 m/s), where a common reference would span the
    /// whole cycle. Each pair is stamped at its later arrival; its sigma is
    /// that of two arrivals.
    fn range_differences(
        &self,
        signals: &[Signal],
        hidden: &[usize],
        clock: &mut FusionClock,
    ) -> Vec<RangeDifferenceSample> {
        let sigma_m =
            std::f64::consts::SQRT_2 * self.config.speed_of_sound_m_s * self.config.timing_sigma_s;
        let heard: Vec<&Signal> = (0..signals.len())
            .filter(|k| !hidden.contains(k))
            .map(|k| &signals[k])
            .collect();
        heard
            .windows(2)
            .map(|pair| RangeDifferenceSample {
                a_t_s: Some(clock.to_fusion(pair[0].t_arrival)),
                t_s: clock.to_fusion(pair[1].t_arrival),
                a_m: pair[0].tx_m,
                b_m: pair[1].tx_m,
                d_m: pair[1].pseudo_range_m - pair[0].pseudo_range_m,
                sigma_m,
                clocks: Some([
                    self.transmitter_clock(pair[0]),
                    self.transmitter_clock(pair[1]),
                ]),
                speed_rel_sigma: self.speed_rel_sigma,
            })
            .collect()
    }
}

/// What the solves of one cycle gave.
enum Attempts {
    /// A fix from every signal.
    All(tdoa::Fix),
    /// A fix without the signals of these indices (hidden transmitters).
    WithoutHidden(tdoa::Fix, Vec<usize>),
    /// No fix.
    NoFix,
}

/// The trigger a cycle's arrivals were matched to, if any, and the flight
/// times the choice was made with when it awaits the next trigger.
struct TriggerMatch {
    matched: Option<Matched>,
    flights_ns: Vec<(u32, i64)>,
}

impl TriggerMatch {
    /// After a good fix: teaches `triggers` the clock offset of the cycle's
    /// start (`from_fix`: the flight times from the fix), at once when the
    /// choice was clear, or once the next trigger confirms it.
    fn teach_clock(
        &mut self,
        triggers: &mut RecentTriggers,
        msg: &UltrasoundArrivals,
        emissions: &[Emission],
        from_fix: &dyn Fn(u32) -> Option<i64>,
    ) {
        if let Some(Matched { trigger, clarity }) = &self.matched {
            match (clarity, cycle_start_ns(msg, emissions, from_fix)) {
                (Clarity::Clear, Some(start_ns)) => triggers.learn_clock(trigger, start_ns),
                (Clarity::AwaitingNext, Some(start_ns)) => triggers.defer_learning(
                    trigger,
                    start_ns,
                    msg,
                    std::mem::take(&mut self.flights_ns),
                ),
                _ => {}
            }
        }
    }
}

/// The wire encoding of a fix (`robot/<id>/fix`): the solver's fix as it is,
/// with the cycle's exact stamp, the arrivals it came from, the MSU height
/// for `z`, and the arrivals that never reached the solver (unknown or
/// repeated transmitter ids) listed as rejected with the solver's own.
pub fn wire_fix(
    fix: &tdoa::Fix,
    stamp: Time,
    arrivals_seq: u64,
    height_m: f64,
    unmatched: &[u32],
) -> Fix {
    let cov = fix.covariance_xy_m2();
    let mut rejected = unmatched.to_vec();
    rejected.extend(fix.rejected.iter().map(|r| r.tx_id));
    Fix {
        stamp,
        arrivals_seq,
        x_m: fix.position_m.x,
        y_m: fix.position_m.y,
        z_m: height_m,
        covariance: [
            cov[(0, 0)],
            cov[(0, 1)],
            0.0,
            cov[(1, 0)],
            cov[(1, 1)],
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        heading_rad: fix.heading_rad.unwrap_or(0.0),
        heading_valid: fix.heading_rad.is_some(),
        used: fix.used_tx_ids.clone(),
        rejected,
        residuals_m: fix.residuals_m.clone(),
        survey_version: 0,
        unused: Vec::new(),
        unused_residuals_m: Vec::new(),
        quality: match fix.quality {
            tdoa::Quality::Good => FixQuality::Good,
            tdoa::Quality::Minimal => FixQuality::Minimal,
            tdoa::Quality::Ambiguous => FixQuality::Ambiguous,
            tdoa::Quality::Suspect => FixQuality::Suspect,
        },
    }
}

/// Takes the left-out transmitters' signals out of `cycle` and returns
/// them (in their order): heard, but not solved with. They are listed as
/// rejected, so that the central unit sees when a left-out transmitter is
/// heard again.
fn leave_out(
    cycle: &mut crate::assembly::CycleSignals,
    left_out: &std::collections::BTreeSet<u32>,
) -> Vec<crate::assembly::Signal> {
    if left_out.is_empty() {
        return Vec::new();
    }
    let left: Vec<_> = cycle
        .signals
        .extract_if(.., |s| left_out.contains(&s.tx_id))
        .collect();
    cycle.rejected.extend(left.iter().map(|s| s.tx_id));
    left
}
