//! The fleet checks each robot before its fixes teach the survey
//! calibration: one robot's credential, stolen or its MSU broken, must not
//! move the transmitters for everyone (the rate bound of [`super::fix_rate`]
//! limits how much a robot says, not whether it is true).
//!
//! Every fix is read against the fleet's calibration and held back for a
//! window of [`WINDOW_FIXES`] of its robot's fixes. Its misfit
//! ([`super::ReadFix::misfit_m`]) is what is left of its residuals once the
//! calibration's prediction is taken out, per degree of freedom: an honest
//! robot leaves its timing noise, a robot that places the transmitters
//! elsewhere leaves that displacement. A robot's misfit is the median over
//! its window; the reference is the median of the other robots' recent
//! misfits (the fixes they hold, not older than [`REFERENCE_AGE_S`]), and
//! its spread their median absolute deviation (times 1.4826, a sigma for
//! normal misfits), never less than the spread the fix noise alone gives
//! ([`spread_floor_m`]). Every robot is measured against the same
//! calibration, so what the calibration has not learnt yet (a survey's
//! centimetre) is in every robot's misfit alike and cancels.
//!
//! A robot whose misfit is more than [`QUARANTINE_SPREADS`] spreads above
//! the reference is quarantined: the fixes it holds and every later one
//! are kept out of the calibration (counted). It is released when the
//! median of a whole window of fixes since is within [`RELEASE_SPREADS`]
//! spreads. A robot whose window agrees lets its oldest fix into the
//! calibration as each new one arrives.
//!
//! Only the other robots' misfits tell the fleet's noise from a forgery:
//! with fewer than a window of them (a fleet of one, or the others silent
//! for [`REFERENCE_AGE_S`]) a robot is [`Check::Unchecked`], said so in
//! `ickon admin`, and its fixes are taken as before the check existed.
//! The check is by majority: robots that forge alike and outnumber the
//! honest ones make the reference theirs.
//!
//! The other robots' misfits are gathered and sorted once for many fixes,
//! not for each ([`reference`]): the check costs a fix time logarithmic in
//! the fleet, not the whole fleet's windows.

use std::collections::{BTreeMap, VecDeque};

use ickon_proto::time::Time;

use super::ReadFix;
use reference::{Reference, Spread, sort_share};

mod reference;

/// Fixes of one robot held and weighed together: about two seconds of
/// fixes at the fleet's usual 10 cycles a second. Its median ignores up
/// to 9 bad fixes (reflections that passed the MSU's gate), and a forger
/// is judged on its first 20 fixes, before any of them is learnt from.
pub const WINDOW_FIXES: usize = 20;

/// A robot is quarantined beyond the reference plus this many spreads.
/// For an honest robot to cross it, half of its window would have to lie
/// beyond three sigmas of the fleet's fixes (each with odds of 0.13 %):
/// never, in practice; a robot that places transmitters a few centimetres
/// off crosses it at once.
pub const QUARANTINE_SPREADS: f64 = 3.0;

/// A quarantined robot is released within the reference plus this many
/// spreads: a sigma below the quarantine's bound, so that a robot whose
/// misfit sits at the bound is not let in and out with every fix.
pub const RELEASE_SPREADS: f64 = 2.0;

/// Other robots' misfits older than this, seconds, are no reference: the
/// calibration they were read against has moved on, and a robot that
/// stopped an hour ago says nothing of the fleet now.
pub const REFERENCE_AGE_S: f64 = 60.0;

/// Normal deviations per median absolute deviation.
const MAD_TO_SIGMA: f64 = 1.4826;

/// The spread of an honest fix's misfit from its timing noise alone, of
/// one-sigma `range_sigma_m`, metres: the misfit is `sigma sqrt(chi2_k /
/// k)` over the fix's `k = n - 3` degrees of freedom, whose spread is about
/// `sigma / sqrt(2 k)`; with four signals (`k = 1`, the least a fix the
/// calibration takes has) `sigma / sqrt(2)`. The reference's spread is
/// never taken below it: robots whose misfits happen to be alike must not
/// turn a fraction of the noise into a quarantine.
pub fn spread_floor_m(range_sigma_m: f64) -> f64 {
    range_sigma_m / std::f64::consts::SQRT_2
}

/// Where a robot stands with the fleet's check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Check {
    /// Fewer than a window of its fixes seen yet.
    Checking,
    /// Its fixes agree with the other robots'; they feed the calibration.
    Agrees,
    /// Its fixes disagree; they are kept out of the calibration.
    Quarantined,
    /// No other robot has a window of recent fixes to compare with: its
    /// fixes feed the calibration unchecked.
    Unchecked,
}

impl Check {
    /// How `ickon admin` and the web map name it.
    pub fn label(self) -> &'static str {
        match self {
            Self::Checking => "checking",
            Self::Agrees => "agrees",
            Self::Quarantined => "quarantined",
            Self::Unchecked => "unchecked: no other robot to compare",
        }
    }
}

/// What the check says of one robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotCheck {
    /// Where it stands.
    pub check: Check,
    /// Its fixes kept out of the calibration while quarantined.
    pub fixes_quarantined: u64,
    /// The median misfit of its window at its last check, metres (`None`:
    /// not checked yet).
    pub misfit_m: Option<f64>,
    /// The misfit beyond which it is quarantined (while quarantined: within
    /// which it is released) at its last check, metres.
    pub bound_m: Option<f64>,
}

/// One fix held back.
#[derive(Debug, Clone)]
struct Held {
    /// When it arrived.
    at: Time,
    misfit_m: f64,
    read: ReadFix,
}

/// One robot's window and standing.
#[derive(Debug, Clone)]
struct RobotWindow {
    held: VecDeque<Held>,
    check: Check,
    fixes_quarantined: u64,
    misfit_m: Option<f64>,
    bound_m: Option<f64>,
    /// Its misfits in the reference as last gathered, sorted.
    share: Vec<f64>,
}

impl Default for RobotWindow {
    fn default() -> Self {
        Self {
            held: VecDeque::with_capacity(WINDOW_FIXES + 1),
            check: Check::Checking,
            fixes_quarantined: 0,
            misfit_m: None,
            bound_m: None,
            share: Vec::new(),
        }
    }
}

/// The fleet's check, by robot (the keys of [`super::fix_rate::FixRate`]:
/// the site's robots, and one for every id the site does not list).
#[derive(Debug, Clone)]
pub struct Consensus {
    robots: BTreeMap<String, RobotWindow>,
    floor_m: f64,
    reference: Reference,
}

impl Consensus {
    /// A check with nothing seen, for fixes of one-sigma timing noise
    /// `range_sigma_m` (the calibration's own).
    pub fn new(range_sigma_m: f64) -> Self {
        Self {
            robots: BTreeMap::new(),
            floor_m: spread_floor_m(range_sigma_m),
            reference: Reference::default(),
        }
    }

    /// Holds the fix `read` of robot `key`, arrived at `now` with misfit
    /// `misfit_m`, checks the robot, and returns the fix (its oldest held)
    /// that may now teach the calibration, if any.
    pub fn offer(&mut self, key: &str, read: ReadFix, misfit_m: f64, now: Time) -> Option<ReadFix> {
        if self.reference.is_due(now) {
            self.gather_reference(now);
        }
        self.reference.offered();
        let floor_m = self.floor_m;
        if !self.robots.contains_key(key) {
            self.robots.insert(key.to_string(), RobotWindow::default());
        }
        let robot = self.robots.get_mut(key)?;
        robot.held.push_back(Held {
            at: now,
            misfit_m,
            read,
        });
        if robot.held.len() >= WINDOW_FIXES {
            let was_out = robot.check == Check::Quarantined;
            robot.judge(self.reference.without(&robot.share), floor_m);
            if was_out != (robot.check == Check::Quarantined) {
                self.reference.mark_stale();
            }
        }
        if robot.held.len() <= WINDOW_FIXES {
            return None;
        }
        let oldest = robot.held.pop_front()?;
        if robot.check == Check::Quarantined {
            robot.fixes_quarantined += 1;
            None
        } else {
            Some(oldest.read)
        }
    }

    /// Gathers the reference at `now`: every fix held by a robot not
    /// quarantined, arrived within [`REFERENCE_AGE_S`], each robot's share
    /// remembered so that its own is left out when it is judged.
    fn gather_reference(&mut self, now: Time) {
        for robot in self.robots.values_mut() {
            robot.share.clear();
            if robot.check != Check::Quarantined {
                robot.share.extend(
                    robot
                        .held
                        .iter()
                        .filter(|h| (now - h.at).as_secs_f64() <= REFERENCE_AGE_S)
                        .map(|h| h.misfit_m),
                );
                sort_share(&mut robot.share);
            }
        }
        self.reference
            .rebuild(self.robots.values().map(|r| r.share.as_slice()), now);
    }

    /// Robot `key` left: the fixes it holds are let go (returned for the
    /// calibration if its window agreed or was unchecked, as they would
    /// have been one by one as its later fixes came), and the robot is
    /// forgotten unless the check holds something against it (quarantined,
    /// or fixes kept out: a forger that leaves and comes back stays named).
    pub fn forget(&mut self, key: &str) -> Vec<ReadFix> {
        let Some(robot) = self.robots.get_mut(key) else {
            return Vec::new();
        };
        let held = std::mem::take(&mut robot.held);
        robot.share = Vec::new();
        let agreed = matches!(robot.check, Check::Agrees | Check::Unchecked);
        if robot.check != Check::Quarantined && robot.fixes_quarantined == 0 {
            self.robots.remove(key);
        }
        // Its share stays in the reference until it is next gathered: its
        // misfits were as good as any, and gathering at every departure
        // would sort the fleet's misfits for each robot of a fleet leaving.
        if agreed {
            held.into_iter().map(|h| h.read).collect()
        } else {
            Vec::new()
        }
    }

    /// What the check says of robot `key` (`Checking` when none of its
    /// fixes was seen).
    pub fn robot(&self, key: &str) -> RobotCheck {
        let r = self.robots.get(key);
        RobotCheck {
            check: r.map_or(Check::Checking, |r| r.check),
            fixes_quarantined: r.map_or(0, |r| r.fixes_quarantined),
            misfit_m: r.and_then(|r| r.misfit_m),
            bound_m: r.and_then(|r| r.bound_m),
        }
    }

    /// Fixes held in every robot's window.
    pub fn held(&self) -> usize {
        self.robots.values().map(|r| r.held.len()).sum()
    }

    /// Robots with a window.
    pub fn len(&self) -> usize {
        self.robots.len()
    }

    /// Whether no robot has a window yet.
    pub fn is_empty(&self) -> bool {
        self.robots.is_empty()
    }
}

impl RobotWindow {
    /// Checks a full window against the other robots' misfits.
    fn judge(&mut self, reference: Spread, floor_m: f64) {
        let mut own: Vec<f64> = self.held.iter().map(|h| h.misfit_m).collect();
        let misfit_m = median(&mut own);
        self.misfit_m = Some(misfit_m);
        if reference.count < WINDOW_FIXES {
            // Nothing to compare with; a quarantine stays until the fleet
            // can say the robot agrees again.
            if self.check != Check::Quarantined {
                self.check = Check::Unchecked;
                self.bound_m = None;
            }
            return;
        }
        let centre_m = reference.centre_m;
        let spread_m = (MAD_TO_SIGMA * reference.mad_m).max(floor_m);
        if self.check == Check::Quarantined {
            let release_m = centre_m + RELEASE_SPREADS * spread_m;
            self.bound_m = Some(release_m);
            if misfit_m <= release_m {
                self.check = Check::Agrees;
                self.bound_m = Some(centre_m + QUARANTINE_SPREADS * spread_m);
            }
            return;
        }
        let quarantine_m = centre_m + QUARANTINE_SPREADS * spread_m;
        if misfit_m > quarantine_m {
            // Everything it holds was judged with it: none of it is learnt,
            // and its release is judged on fixes it gives from now on.
            self.fixes_quarantined += self.held.len() as u64;
            self.held.clear();
            self.check = Check::Quarantined;
            self.bound_m = Some(centre_m + RELEASE_SPREADS * spread_m);
        } else {
            self.check = Check::Agrees;
            self.bound_m = Some(quarantine_m);
        }
    }
}

/// The median of `values` (reordered); 0 for none: a robot's own window's.
fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return 0.0;
    }
    let (below, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    if n % 2 == 1 {
        upper
    } else {
        // The largest of the lower half is the other middle value.
        let lower = below
            .iter()
            .copied()
            .max_by(f64::total_cmp)
            .unwrap_or(upper);
        0.5 * (lower + upper)
    }
}

#[cfg(test)]
mod tests;
