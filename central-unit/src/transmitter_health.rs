//! Each transmitter's health, from what the fleet's fixes say of it: how
//! often it was heard when a robot was near it, what its residuals are,
//! when it was last heard. A transmitter that is dead (never heard while
//! its cell's others are), weak (heard far less often than its cell's
//! others from the same fixes) or moved (heard, but its arrivals mostly
//! rejected by the MSUs' gates, or its residuals off by centimetres) is
//! flagged with its evidence and left out of the fixes while it is bad
//! ([`ickon_proto::msg::control::TransmitterOffset::left_out`]).
//!
//! A transmitter is "due" in a fix when the fix puts the receiver within
//! [`HealthConfig::near_m`] of it with nothing in between. Whether its cell
//! fired in that cycle the central unit cannot tell from a fix (the fix is
//! stamped on the robot's clock), so a transmitter is judged against its
//! own cell's others due in the same fix, which fired or did not with it:
//! its expected share heard is theirs. Counts are forgotten with
//! [`HealthConfig::memory_s`], so that a repaired transmitter is healthy
//! again within about that long.
//!
//! The MSUs list a left-out transmitter's arrivals as rejected, so its
//! heard share keeps being measured: a dead or weak one that recovers is
//! taken back. A moved one stays left out (its arrivals stay off): the
//! residuals the fixes report of its unused arrivals place it again
//! ([`resurvey`], [`TransmitterHealth::resurveyed`]), and it is taken back
//! once fixes solved with the new position agree with it
//! ([`TransmitterHealth::mark_resurveyed`]), or when it is surveyed again
//! by hand and the site reloaded.

use std::collections::{BTreeMap, BTreeSet};

use ickon_proto::msg::robot::{Fix, FixQuality};
use ickon_proto::site::{Column, Site, Wall, line_of_sight};
use ickon_proto::time::Time;

pub mod resurvey;

use resurvey::{Resurvey, ResurveyConfig, Resurveyed};

/// What the health check assumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HealthConfig {
    /// A transmitter is due in a fix within this distance, metres: well
    /// inside any receiver's range, so that a healthy transmitter is heard
    /// about as often as its neighbours.
    pub near_m: f64,
    /// Counts are forgotten with this time constant, seconds.
    pub memory_s: f64,
    /// Fixes a transmitter must be due in (forgotten count) before it is
    /// judged dead.
    pub min_due_dead: f64,
    /// The same, to be judged weak or moved.
    pub min_due_weak: f64,
    /// Weak: heard less than this fraction of its cell's others' share.
    pub weak_ratio: f64,
    /// Dead: this many fixes in a row that heard none of it while they
    /// heard most of its cell's others.
    pub dead_misses_in_a_row: u32,
    /// Moved: more than this share of its heard arrivals rejected by the
    /// MSUs' gates.
    pub moved_rejected_share: f64,
    /// Moved: its used residuals' mean beyond this, metres.
    pub moved_residual_m: f64,
}

impl Default for HealthConfig {
    /// 6 m (the receivers hear to 10 m or more), a memory of 20 s, judged
    /// dead after 20 fixes in a row that missed it (a few seconds of one
    /// robot nearby; a healthy transmitter heard 90 % of the time misses
    /// 20 in a row with a probability of 1e-20, a weak one heard a quarter
    /// of the time with 0.3 %) or when its forgotten count of heard fixes
    /// falls under one half, and weak or moved after 25 fixes due. Weak
    /// below half its cell's share: a healthy transmitter is heard as often
    /// as its neighbours, within the few percent its drops and blocked
    /// paths take, and 25 draws at 90 % fall under 45 % with a probability
    /// under 1e-7. Moved when the mean of five or more of its residuals is
    /// beyond 5 cm (the MSUs' gate is about 10 cm, a healthy mean
    /// millimetres), when more than 60 % of its arrivals fail the MSUs'
    /// gates, or more than 30 % with a mean residual beyond 2 cm (a
    /// healthy one's fail when reflected or collided: 2 to 10 % in a hall,
    /// the `paper` and `harsh` profiles' physics, more near a wall or a
    /// failing neighbour, but with its residuals centred).
    fn default() -> Self {
        Self {
            near_m: 6.0,
            memory_s: 20.0,
            min_due_dead: 8.0,
            min_due_weak: 25.0,
            weak_ratio: 0.5,
            dead_misses_in_a_row: 20,
            moved_rejected_share: 0.3,
            moved_residual_m: 0.05,
        }
    }
}

/// What is wrong with a transmitter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Condition {
    /// Not enough fixes near it yet to say.
    Unknown,
    /// Heard as often as its neighbours, residuals small.
    Healthy,
    /// Never heard while its cell's others are.
    Dead,
    /// Heard far less often than its cell's others.
    Weak,
    /// Heard, but its arrivals fail the gates or its residuals are off.
    Moved,
}

impl Condition {
    /// The word for it.
    pub fn label(self) -> &'static str {
        match self {
            Self::Unknown => "unknown",
            Self::Healthy => "healthy",
            Self::Dead => "dead",
            Self::Weak => "weak",
            Self::Moved => "moved",
        }
    }

    /// Whether its arrivals are left out of the fixes.
    pub fn left_out(self) -> bool {
        matches!(self, Self::Dead | Self::Weak | Self::Moved)
    }
}

/// What the fleet saw of one transmitter.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TransmitterReport {
    /// Transmitter id.
    pub tx_id: u32,
    /// Its cell.
    #[serde(skip)]
    pub cell_index: usize,
    /// What is wrong with it.
    pub condition: Condition,
    /// Fixes it was due in (forgotten count).
    pub due: f64,
    /// Share of them it was heard in, percent (`None` before any).
    pub heard_pct: Option<f64>,
    /// Share its cell's others were heard in from the same fixes, percent.
    pub expected_pct: Option<f64>,
    /// Share of its heard arrivals rejected by the MSUs, percent.
    pub rejected_pct: Option<f64>,
    /// Mean of its used residuals, metres.
    pub residual_mean_m: Option<f64>,
    /// Standard deviation of its used residuals, metres.
    pub residual_std_m: Option<f64>,
    /// Seconds since it was last heard (`None`: never).
    pub last_heard_s_ago: Option<f64>,
    /// Master time the condition began, seconds.
    pub since_s: Option<f64>,
    /// Where the fleet surveyed a moved transmitter again and checks it
    /// (`None`: not surveyed again, or taken back).
    pub resurveyed_m: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Counts {
    due: f64,
    heard: f64,
    expected: f64,
    /// Arrivals heard in any fix (due or not), and of them rejected.
    heard_any: f64,
    rejected_any: f64,
    residual_n: f64,
    residual_sum: f64,
    residual_sq: f64,
}

impl Counts {
    fn scale(&mut self, k: f64) {
        for v in [
            &mut self.due,
            &mut self.heard,
            &mut self.expected,
            &mut self.heard_any,
            &mut self.rejected_any,
            &mut self.residual_n,
            &mut self.residual_sum,
            &mut self.residual_sq,
        ] {
            *v *= k;
        }
    }
}

#[derive(Debug, Clone)]
struct Entry {
    /// Fixes in a row that heard most of its cell's others but not it.
    misses_in_a_row: u32,
    tx_id: u32,
    position_m: [f64; 3],
    cell: usize,
    counts: Counts,
    last_heard: Option<Time>,
    condition: Condition,
    since: Option<Time>,
    /// Where the fleet surveyed it again while moved (published to the
    /// MSUs), and the residuals of its unused arrivals since, solved with
    /// that position: `(count, sum, sum of squares)`.
    resurveyed_at: Option<[f64; 3]>,
    agreement: (f64, f64, f64),
}

/// A re-surveyed transmitter is taken back into the fixes after this many
/// fixes solved with its new position measured it...
const AGREEMENT_FIXES: f64 = 20.0;
/// ... with their residuals' mean within this, metres (the MSU's gate is
/// about 10 cm, a healthy transmitter's mean millimetres; half the 5 cm
/// that flags one as moved)...
const AGREEMENT_MEAN_M: f64 = 0.025;
/// ... and their RMS within this, metres (the flag's 5 cm).
const AGREEMENT_RMS_M: f64 = 0.05;

/// A re-survey's estimate further than this (and three of its sigmas)
/// from where the transmitter was published is surveyed again rather than
/// taken back, metres: the calibration's step between re-surveys
/// ([`crate::survey_calibration`]'s, three range sigmas of its floor).
const SETTLED_STEP_M: f64 = 0.03;

/// What the fleet's fixes say of a re-surveyed transmitter's position.
enum Settled {
    /// Where it was published (or not pinned down by them).
    Yes,
    /// Somewhere else: surveyed again.
    Elsewhere,
}

/// The fleet's view of every transmitter's health.
#[derive(Debug, Clone)]
pub struct TransmitterHealth {
    config: HealthConfig,
    entries: Vec<Entry>,
    index: BTreeMap<u32, usize>,
    walls: Vec<Wall>,
    columns: Vec<Column>,
    last_at: Option<Time>,
    /// The fixes' measured ranges to each moved transmitter, by index.
    resurveys: BTreeMap<usize, Resurvey>,
}

impl TransmitterHealth {
    /// Nothing seen yet of `site`'s transmitters.
    pub fn new(site: &Site, config: HealthConfig) -> Self {
        let cells: BTreeMap<&str, usize> = site
            .cells
            .iter()
            .enumerate()
            .map(|(i, c)| (c.id.as_str(), i))
            .collect();
        let entries: Vec<Entry> = site
            .transmitters
            .iter()
            .map(|t| Entry {
                misses_in_a_row: 0,
                tx_id: t.id,
                position_m: t.position_m,
                cell: cells.get(t.cell.as_str()).copied().unwrap_or(usize::MAX),
                counts: Counts::default(),
                last_heard: None,
                condition: Condition::Unknown,
                since: None,
                resurveyed_at: None,
                agreement: (0.0, 0.0, 0.0),
            })
            .collect();
        let index = entries
            .iter()
            .enumerate()
            .map(|(i, e)| (e.tx_id, i))
            .collect();
        Self {
            config,
            entries,
            index,
            walls: site.walls.clone(),
            columns: site.columns.clone(),
            last_at: None,
            resurveys: BTreeMap::new(),
        }
    }

    /// Takes what one good fix of robot `robot` (of a robot the fleet's
    /// check trusts) says of the moved transmitters it heard and did not
    /// use: their residuals, against the positions it was solved with
    /// (`solved_with`: the calibration's offsets by id, absent: surveyed),
    /// taken at `now`.
    /// A fix that is not good, has fewer than four used signals (its own
    /// position and offset would be as much in doubt as the arrival), or
    /// whose unused lists do not pair up, says nothing.
    pub fn observe_unused(
        &mut self,
        robot: &str,
        fix: &Fix,
        solved_with: &BTreeMap<u32, [f64; 3]>,
        now: Time,
    ) {
        // A transmitter no longer moved needs no re-survey.
        let entries = &self.entries;
        self.resurveys
            .retain(|&i, _| entries[i].condition == Condition::Moved);
        if fix.quality != FixQuality::Good
            || fix.used.len() < 4
            || fix.unused.len() != fix.unused_residuals_m.len()
        {
            return;
        }
        let receiver = [fix.x_m, fix.y_m, fix.z_m];
        for (id, &residual_m) in fix.unused.iter().zip(&fix.unused_residuals_m) {
            let Some(&i) = self.index.get(id) else {
                continue;
            };
            let e = &self.entries[i];
            if e.condition != Condition::Moved {
                continue;
            }
            let offset = solved_with.get(id).copied().unwrap_or([0.0; 3]);
            let solved_at: [f64; 3] = std::array::from_fn(|a| e.position_m[a] + offset[a]);
            self.resurveys
                .entry(i)
                .or_insert_with(|| Resurvey::new(solved_at, ResurveyConfig::default()))
                .observe(robot, receiver, solved_at, residual_m);
            self.check_agreement(i, solved_at, residual_m, now);
        }
    }

    /// Whether moved transmitter `i`'s residual `residual_m`, solved with
    /// it at `solved_at`, adds to the agreement with where it was surveyed
    /// again; when enough of them agree and the fleet's fixes still place
    /// it there, it is healthy again, taken back into the fixes.
    fn check_agreement(&mut self, i: usize, solved_at: [f64; 3], residual_m: f64, now: Time) {
        let e = &mut self.entries[i];
        let Some(at) = e.resurveyed_at else {
            return;
        };
        // Solved with an older calibration: not a check of the new position.
        let moved_since = (0..3).map(|a| (at[a] - solved_at[a]).powi(2)).sum::<f64>();
        // Beyond the agreement's RMS bound twice over it is a reflection's
        // (the fixes' gates reject those of healthy transmitters too).
        let plausible = residual_m.is_finite() && residual_m.abs() <= 2.0 * AGREEMENT_RMS_M;
        if moved_since > 1e-4 || !plausible {
            return;
        }
        let (n, sum, sq) = &mut e.agreement;
        *n += 1.0;
        *sum += residual_m;
        *sq += residual_m * residual_m;
        if *n < AGREEMENT_FIXES {
            return;
        }
        let mean = *sum / *n;
        let rms = (*sq / *n).sqrt();
        e.agreement = (0.0, 0.0, 0.0);
        if !(mean.abs() <= AGREEMENT_MEAN_M && rms <= AGREEMENT_RMS_M) {
            // The new position does not explain the arrivals: it may be
            // surveyed again from what the fixes say now.
            e.resurveyed_at = None;
            return;
        }
        match self.settled(i, at) {
            Settled::Yes => self.take_back(i, now),
            Settled::Elsewhere => self.entries[i].resurveyed_at = None,
        }
    }

    /// Whether the fleet's fixes now place moved transmitter `i` where it
    /// was published, `at` (within three of their sigmas and
    /// [`SETTLED_STEP_M`]): taken back then, surveyed again where they place
    /// it now otherwise. Fixes that do not pin it down (robots that
    /// disagree, places along a line) leave the agreement alone to decide.
    fn settled(&self, i: usize, at: [f64; 3]) -> Settled {
        let Some(r) = self.resurveys.get(&i).and_then(Resurvey::estimate) else {
            return Settled::Yes;
        };
        let sigma = r.sigma_m.iter().fold(0.0_f64, |m, s| m.max(*s));
        let apart = (0..3)
            .map(|a| (r.position_m[a] - at[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        if apart > (3.0 * sigma).max(SETTLED_STEP_M) {
            Settled::Elsewhere
        } else {
            Settled::Yes
        }
    }

    /// Moved transmitter `i` is healthy again at `now`, back in the fixes.
    fn take_back(&mut self, i: usize, now: Time) {
        let e = &mut self.entries[i];
        e.condition = Condition::Healthy;
        e.since = Some(now);
        e.resurveyed_at = None;
        // What was measured of it at its old position is no evidence
        // of the new one.
        let c = &mut e.counts;
        (c.heard_any, c.rejected_any) = (0.0, 0.0);
        (c.residual_n, c.residual_sum, c.residual_sq) = (0.0, 0.0, 0.0);
        self.resurveys.remove(&i);
    }

    /// Moved transmitter `tx_id` was surveyed again at `position_m` and
    /// published there: the residuals of fixes solved with it there decide
    /// when it is taken back. Ignored for a transmitter not moved.
    pub fn mark_resurveyed(&mut self, tx_id: u32, position_m: [f64; 3]) {
        if let Some(&i) = self.index.get(&tx_id) {
            let e = &mut self.entries[i];
            if e.condition == Condition::Moved {
                e.resurveyed_at = Some(position_m);
                e.agreement = (0.0, 0.0, 0.0);
            }
        }
    }

    /// Where moved transmitter `tx_id` was surveyed again and is being
    /// checked (`None`: not surveyed again, or its check failed).
    pub fn resurveyed_at(&self, tx_id: u32) -> Option<[f64; 3]> {
        self.entries[*self.index.get(&tx_id)?].resurveyed_at
    }

    /// The moved transmitters, by id.
    pub fn moved(&self) -> Vec<u32> {
        self.entries
            .iter()
            .filter(|e| e.condition == Condition::Moved)
            .map(|e| e.tx_id)
            .collect()
    }

    /// Where the fleet's fixes place moved transmitter `tx_id` now, if they
    /// pin it down and the robots agree ([`resurvey`]).
    pub fn resurveyed(&self, tx_id: u32) -> Option<Resurveyed> {
        let i = *self.index.get(&tx_id)?;
        if self.entries[i].condition != Condition::Moved {
            return None;
        }
        self.resurveys.get(&i)?.estimate()
    }

    /// Takes what one fix (of a robot the fleet's check trusts) says,
    /// taken at `now`, solved with a calibration that left none out. A fix
    /// with fewer than three used signals, or whose numbers are not numbers,
    /// places nothing and is ignored.
    pub fn observe(&mut self, fix: &Fix, now: Time) {
        self.observe_solved(fix, &BTreeSet::new(), now);
    }

    /// As [`Self::observe`], for a fix solved with a calibration that left
    /// the transmitters `left_out` out: their arrivals were rejected for
    /// that, not by the fix's gates, and say nothing of a move. A
    /// transmitter taken back into the fixes is heard in fixes solved with
    /// the calibration before for a second or two (one is published a
    /// second): counting those as rejected would flag it moved again at
    /// once.
    pub fn observe_solved(&mut self, fix: &Fix, left_out: &BTreeSet<u32>, now: Time) {
        self.forget(now);
        let p = [fix.x_m, fix.y_m, fix.z_m];
        if fix.used.len() < 3
            || !p.iter().all(|v| v.is_finite())
            || fix.residuals_m.len() != fix.used.len()
        {
            return;
        }
        let heard: BTreeSet<u32> = fix.used.iter().chain(&fix.rejected).copied().collect();
        for id in &heard {
            if let Some(&i) = self.index.get(id) {
                let e = &mut self.entries[i];
                e.last_heard = Some(now);
                if left_out.contains(id) {
                    continue;
                }
                e.counts.heard_any += 1.0;
                if !fix.used.contains(id) {
                    e.counts.rejected_any += 1.0;
                }
            }
        }
        for (id, r) in fix.used.iter().zip(&fix.residuals_m) {
            if let (Some(&i), true) = (self.index.get(id), r.is_finite()) {
                let c = &mut self.entries[i].counts;
                c.residual_n += 1.0;
                c.residual_sum += r;
                c.residual_sq += r * r;
            }
        }
        let near = self.config.near_m;
        let due: Vec<usize> = (0..self.entries.len())
            .filter(|&i| {
                let t = self.entries[i].position_m;
                let d =
                    ((t[0] - p[0]).powi(2) + (t[1] - p[1]).powi(2) + (t[2] - p[2]).powi(2)).sqrt();
                d <= near && line_of_sight(&self.walls, &self.columns, t, p)
            })
            .collect();
        for &i in &due {
            let cell = self.entries[i].cell;
            let others: Vec<usize> = due
                .iter()
                .copied()
                .filter(|&k| k != i && self.entries[k].cell == cell)
                .collect();
            if others.is_empty() {
                continue;
            }
            let heard_others = others
                .iter()
                .filter(|&&k| heard.contains(&self.entries[k].tx_id))
                .count();
            let was_heard = heard.contains(&self.entries[i].tx_id);
            let expected = heard_others as f64 / others.len() as f64;
            let e = &mut self.entries[i];
            if was_heard {
                e.misses_in_a_row = 0;
            } else if expected >= 0.5 {
                e.misses_in_a_row = e.misses_in_a_row.saturating_add(1);
            }
            let c = &mut e.counts;
            c.due += 1.0;
            c.expected += heard_others as f64 / others.len() as f64;
            if was_heard {
                c.heard += 1.0;
            }
        }
        for i in 0..self.entries.len() {
            let e = &self.entries[i];
            let judged = if e.misses_in_a_row >= self.config.dead_misses_in_a_row
                && e.condition != Condition::Moved
            {
                Condition::Dead
            } else {
                self.judge(&e.counts, e.condition)
            };
            let e = &mut self.entries[i];
            // Unknown never replaces a judgement: a transmitter nobody is
            // near keeps what was last seen of it.
            if judged != Condition::Unknown && judged != e.condition {
                if e.condition.left_out() {
                    // Its arrivals were rejected because it was left out:
                    // not evidence of a move.
                    e.counts.heard_any = 0.0;
                    e.counts.rejected_any = 0.0;
                }
                e.condition = judged;
                e.since = Some(now);
            }
        }
    }

    /// Forgets counts up to `now` (see [`HealthConfig::memory_s`]).
    fn forget(&mut self, now: Time) {
        let Some(last) = self.last_at.replace(now) else {
            return;
        };
        let dt_s = (now - last).as_secs_f64();
        if dt_s > 0.0 && self.config.memory_s > 0.0 {
            let k = (-dt_s / self.config.memory_s).exp();
            for e in &mut self.entries {
                e.counts.scale(k);
            }
        }
    }

    /// The condition the counts `c` say, for a transmitter now `current`.
    /// A moved transmitter stays moved (its arrivals are left out, so
    /// nothing can show it back in place); a left-out dead or weak one is
    /// judged by how often it is heard only (its arrivals are all rejected
    /// while it is left out).
    fn judge(&self, c: &Counts, current: Condition) -> Condition {
        if current == Condition::Moved {
            return current;
        }
        let cfg = &self.config;
        if c.due < cfg.min_due_dead {
            return Condition::Unknown;
        }
        let expected = c.expected / c.due;
        let heard = c.heard / c.due;
        if c.heard < 0.5 && expected >= 0.5 {
            return Condition::Dead;
        }
        if c.due < cfg.min_due_weak {
            return Condition::Unknown;
        }
        if heard < cfg.weak_ratio * expected {
            return Condition::Weak;
        }
        if current.left_out() {
            return Condition::Healthy;
        }
        let rejected = if c.heard_any > 0.0 {
            c.rejected_any / c.heard_any
        } else {
            0.0
        };
        let residual_mean = if c.residual_n >= 5.0 {
            (c.residual_sum / c.residual_n).abs()
        } else {
            0.0
        };
        // Rejections alone can be a wall's reflections, made worse by a
        // neighbour that bends the fixes: a moved transmitter also pulls
        // its own residuals off, unless nearly all its arrivals are
        // rejected.
        let displaced = residual_mean > cfg.moved_residual_m
            || rejected > 2.0 * cfg.moved_rejected_share
            || (rejected > cfg.moved_rejected_share && residual_mean > 0.4 * cfg.moved_residual_m);
        if displaced {
            return Condition::Moved;
        }
        Condition::Healthy
    }

    /// The transmitters to leave out of the fixes, by id.
    pub fn left_out(&self) -> BTreeSet<u32> {
        self.entries
            .iter()
            .filter(|e| e.condition.left_out())
            .map(|e| e.tx_id)
            .collect()
    }

    /// What the fleet saw of every transmitter, in the site's order, at `now`.
    pub fn report(&self, now: Time) -> Vec<TransmitterReport> {
        self.entries
            .iter()
            .map(|e| {
                let c = &e.counts;
                let share = |a: f64, b: f64| (b > 1e-9).then(|| 100.0 * a / b);
                let mean = (c.residual_n > 1e-9).then(|| c.residual_sum / c.residual_n);
                TransmitterReport {
                    tx_id: e.tx_id,
                    cell_index: e.cell,
                    condition: e.condition,
                    due: c.due,
                    heard_pct: share(c.heard, c.due),
                    expected_pct: share(c.expected, c.due),
                    rejected_pct: share(c.rejected_any, c.heard_any),
                    residual_mean_m: mean,
                    residual_std_m: mean
                        .map(|m| (c.residual_sq / c.residual_n - m * m).max(0.0).sqrt()),
                    last_heard_s_ago: e.last_heard.map(|t| (now - t).as_secs_f64().max(0.0)),
                    since_s: e.since.map(Time::as_secs_f64),
                    resurveyed_m: e.resurveyed_at,
                }
            })
            .collect()
    }

    /// The evidence behind a condition, in words.
    pub fn evidence(r: &TransmitterReport) -> String {
        let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0} %"));
        match r.condition {
            Condition::Unknown => "no robot has been near it long enough".into(),
            Condition::Dead => format!(
                "not heard in the last fixes near it, heard in {} of the recent ones, its cell's others in {}",
                pct(r.heard_pct),
                pct(r.expected_pct)
            ),
            Condition::Weak => format!(
                "heard in {} of the fixes near it, its cell's others in {}",
                pct(r.heard_pct),
                pct(r.expected_pct)
            ),
            Condition::Moved => format!(
                "{} of its arrivals rejected by the robots' gates, residuals {} mm on average{}",
                pct(r.rejected_pct),
                r.residual_mean_m
                    .map_or("-".into(), |m| format!("{:.0}", m * 1e3)),
                r.resurveyed_m.map_or(String::new(), |[x, y, z]| format!(
                    "; surveyed again by the fleet at ({x:.3}, {y:.3}, {z:.3}) m, taken back once fixes agree there"
                ))
            ),
            Condition::Healthy => format!(
                "heard in {} of the fixes near it (its cell's others {})",
                pct(r.heard_pct),
                pct(r.expected_pct)
            ),
        }
    }
}

#[cfg(test)]
mod tests;
