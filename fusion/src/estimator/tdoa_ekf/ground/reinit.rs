//! Recovery of a lost (or not yet confirmed) filter: consistent cycles
//! that agree with each other either confirm the state or move it.

use std::f64::consts::PI;

use nalgebra::{Matrix2, Vector3};

use super::{Candidate, MAX_REINITS_KEPT, Reinitialisation, TdoaEkf, prior};
use crate::estimator::tdoa_ekf::ground_chain::Arrival;
use crate::estimator::tdoa_ekf::ground_state::{self as gs, State, TH, X, Y};
use crate::estimator::tdoa_ekf::observation::Outcome;
use crate::estimator::tdoa_ekf::recovery::RejectionWatch;
use crate::tdoa;

/// Share of the distance driven that the wheels may be wrong by when two
/// candidate fixes are compared with the filter's own motion (a few times
/// the sheet's 1 % slip, and the heading's error over a short drive).
const CANDIDATE_MOTION_SLACK: f64 = 0.1;

/// Share of recent arrivals gated above which a start not yet confirmed may
/// be replaced: most of them (a start 7 m off has nearly all gated; a
/// right one is gated only where reflections come early).
const START_DOUBTED_GATED_SHARE: f64 = 0.5;

/// Agreeing consistent cycles that replace a start pose not yet confirmed:
/// one more than the two that place a lost filter, since two cycles can
/// share a bias (the same reflection off a rack passes the solver's check
/// in both: on warehouse one robot's right start was moved 1.4 m that way
/// and lost its heading).
const AGREEING_CYCLES_AGAINST_A_START: u32 = 3;

/// Shortest time the cycles against a start pose, or against the state of
/// a filter that has been tracking, must span, seconds. The
/// count above was set for a full schedule's rate (`warehouse` 2.6,
/// `lab` 3.8 cycles/s: three cycles span about a second); at 10 cycles/s (occupancy firing, two carrier channels)
/// three cycles come within 0.3 s from one place and share its reflections,
/// and a robot's right start was replaced by a wrong place 0.8 m off whose
/// heading then came from the track the wrong way round (`warehouse` with
/// two channels, 16 robots: that robot 127 mm mean, p95 569 mm).
/// The same holds for a tracked state: on `warehouse` at 6 cycles/s (16
/// robots, seed 8) a robot tracked to 11 mm was marked lost at a rack end
/// and moved 0.87 m by two cycles 0.17 s apart that shared one place's
/// reflections; it was wrong for 10 s.
const AGREEING_SPAN_AGAINST_A_START_S: f64 = 1.0;

/// A redundant fix of one cycle whose arrivals agree with each other (no
/// rejected residuals).
struct ConsistentFix {
    /// Time of the cycle's first arrival, seconds.
    chain_start_s: f64,
    /// Position `(x, y)`, metres.
    xy_m: [f64; 2],
    /// Covariance of the position, square metres.
    cov: Matrix2<f64>,
    /// Range sigma the solver assumed, metres.
    sigma_range_m: f64,
    /// Whether the filter's own motion is known (started, heading known).
    known_motion: bool,
}

impl TdoaEkf {
    /// While lost (or not started): re-initialises at a redundant,
    /// self-consistent fix of the chain's arrivals. Returns whether it did.
    pub(super) fn try_reinitialise(&mut self, t_s: f64) -> bool {
        let Some(fix) = self.consistent_fix(t_s) else {
            return false;
        };
        let [fx, fy] = fix.xy_m;
        // One self-consistent cycle can still be a coincidence of
        // reflections: the fixes of two different cycles must agree (within
        // their noise and the distance driven between them).
        let sigma = fix.cov.trace().max(0.0).sqrt();
        let state_xy_m = self
            .state
            .filter(|_| fix.known_motion)
            .map(|(x, _)| [x[X], x[Y]]);
        let candidate = Candidate {
            chain_start_s: fix.chain_start_s,
            t_s,
            xy_m: [fx, fy],
            sigma_m: sigma,
            agreeing_before: 0,
            agreeing_since_s: t_s,
            state_xy_m,
        };
        let Some(candidate) = self.agreeing_candidate(candidate) else {
            return false;
        };
        let agreeing = candidate.agreeing_before + 1;
        self.candidate = None;
        let tracking = self.heading_from_track.is_none();
        if tracking && self.keeps_state(candidate, agreeing) {
            return false;
        }
        self.start_confirmed = true;
        self.move_to(t_s, fix.xy_m, &fix.cov, tracking);
        self.restart_chain(t_s, fix.sigma_range_m);
        true
    }

    /// The chain's arrivals solved as one cycle, motion-compensated when
    /// the filter's motion is known, at time `t_s`: `None` unless the fix
    /// is good, uses every arrival and lies on the floor.
    fn consistent_fix(&self, t_s: f64) -> Option<ConsistentFix> {
        let arrivals = self.chain.arrivals().to_vec();
        if arrivals.len() < self.params.reinit_arrivals.max(4) {
            return None;
        }
        let height = self.params.receiver_height_m;
        let heading = self.state.map_or(0.0, |(x, _)| x[TH]);
        let known_motion = self.state.is_some() && self.heading_from_track.is_none();
        let (s, c) = heading.sin_cos();
        let speed = if known_motion { self.speed_m_s } else { 0.0 };
        let signals: Vec<tdoa::Signal> = arrivals
            .iter()
            .enumerate()
            .map(|(i, a)| tdoa::Signal {
                tx_id: i as u32,
                tx_m: Vector3::from(a.tx_m),
                pseudo_range_m: a.rho_m,
                t_s: a.t_s,
            })
            .collect();
        let moves: Vec<Vector3<f64>> = arrivals
            .iter()
            .map(|a| Vector3::new(c, s, 0.0) * speed * (a.t_s - t_s))
            .collect();
        let config = tdoa::SolverConfig {
            mode: tdoa::Mode::TwoD { height_m: height },
            sigma_range_m: 0.03,
            ..tdoa::SolverConfig::default()
        };
        let Ok(fix) = tdoa::solve_moving(&signals, &moves, &config) else {
            return None;
        };
        if fix.quality != tdoa::Quality::Good || !fix.rejected.is_empty() {
            return None;
        }
        let (fx, fy) = (fix.position_m.x, fix.position_m.y);
        if self.params.floor.is_some_and(|f| !f.contains(fx, fy)) {
            return None;
        }
        Some(ConsistentFix {
            chain_start_s: arrivals[0].t_s,
            xy_m: [fx, fy],
            cov: fix.covariance_xy_m2(),
            sigma_range_m: config.sigma_range_m,
            known_motion,
        })
    }

    /// Compares `candidate` with the previous cycle's: returns it, counting
    /// the agreeing run, when the two agree; otherwise keeps the one to
    /// compare the next cycle with and returns `None`.
    fn agreeing_candidate(&mut self, mut candidate: Candidate) -> Option<Candidate> {
        let [fx, fy] = candidate.xy_m;
        let (t_s, sigma) = (candidate.t_s, candidate.sigma_m);
        match self.candidate {
            Some(c) if c.chain_start_s != candidate.chain_start_s => {
                let (dx, dy) = (fx - c.xy_m[0], fy - c.xy_m[1]);
                // With the motion known, the fixes must have moved as the
                // filter did (a kidnapped robot's fixes do: both are at the
                // new place); two cycles that share one place's reflections
                // but not the robot's motion do not. Without it, as far as
                // the robot can have driven.
                let (apart, slack) = match (candidate.state_xy_m, c.state_xy_m) {
                    (Some(now), Some(then)) => {
                        let (mx, my) = (now[0] - then[0], now[1] - then[1]);
                        (
                            (dx - mx).hypot(dy - my),
                            CANDIDATE_MOTION_SLACK * mx.hypot(my),
                        )
                    }
                    _ => (dx.hypot(dy), self.speed_m_s.abs() * (t_s - c.t_s).abs()),
                };
                if apart > 3.0 * (sigma + c.sigma_m) + slack {
                    self.candidate = Some(candidate);
                    return None;
                }
                candidate.agreeing_before = c.agreeing_before + 1;
                candidate.agreeing_since_s = c.agreeing_since_s;
                Some(candidate)
            }
            Some(_) => None,
            None => {
                self.candidate = Some(candidate);
                None
            }
        }
    }

    /// For a filter that knows its heading, given an agreeing run of
    /// `agreeing` cycles ending with `candidate`: whether the filter keeps
    /// its state (the cycles put the robot where it has it, or do not yet
    /// outweigh it). Forgets the state when the start pose it came from
    /// was wrong.
    fn keeps_state(&mut self, candidate: Candidate, agreeing: u32) -> bool {
        let Some((x, p)) = &self.state else {
            return false;
        };
        let [fx, fy] = candidate.xy_m;
        let sigma = candidate.sigma_m;
        // The consistent cycles put the robot where the filter has it:
        // it is not displaced (its arrivals only disagreed with its
        // model for a while), so there is nothing to jump to.
        let own = (p[(X, X)] + p[(Y, Y)]).max(0.0).sqrt();
        if (fx - x[X]).hypot(fy - x[Y]) <= 3.0 * (sigma + own) {
            self.lost = false;
            self.start_confirmed = true;
            self.watch = RejectionWatch::default();
            return true;
        }
        let span_s = candidate.t_s - candidate.agreeing_since_s;
        // A start whose arrivals mostly agree with it is not replaced
        // by cycles that merely agree with each other: near a rack end
        // several cycles share one place's reflections (`warehouse`, 16
        // robots at 6 cycles/s, seed 7: a right start moved 0.26 m,
        // then 0.9 m, wrong for 10 s). A restarted MSU on a robot that
        // drove away has nearly all its arrivals gated.
        if span_s < AGREEING_SPAN_AGAINST_A_START_S
            || (!self.start_confirmed
                && (agreeing < AGREEING_CYCLES_AGAINST_A_START
                    || self.gated_share < START_DOUBTED_GATED_SHARE))
        {
            // Not yet: the next consistent cycle may confirm the start
            // (or the tracked state).
            self.candidate = Some(candidate);
            return true;
        }
        if !self.start_confirmed {
            // The start pose was wrong (an MSU restarted on a robot
            // that had driven away): its heading is no better than its
            // position, so start as without one, at the consistent fix.
            self.state = None;
        }
        false
    }

    /// Moves the position to `xy_m` (covariance `cov`) at `t_s`, or starts
    /// there without a state; `tracking` says whether the heading was known
    /// (then the move is recorded as a re-initialisation).
    fn move_to(&mut self, t_s: f64, xy_m: [f64; 2], cov: &Matrix2<f64>, tracking: bool) {
        let [fx, fy] = xy_m;
        let cov = [[cov[(0, 0)], cov[(0, 1)]], [cov[(1, 0)], cov[(1, 1)]]];
        let extra = self.params.reinit_heading_sigma_deg.to_radians().powi(2);
        match &mut self.state {
            Some((x, p)) => {
                let from = [x[X], x[Y]];
                gs::reset_position(x, p, [fx, fy], cov, if tracking { extra } else { 0.0 });
                if !tracking {
                    // Still starting: not an event, and the chord of an
                    // unknown heading starts again (the jump is no motion).
                    self.heading_from_track = Some(None);
                } else if self.reinits.len() >= MAX_REINITS_KEPT {
                    self.reinits.remove(0);
                }
                if tracking {
                    self.reinits.push(Reinitialisation {
                        t_s,
                        from_m: from,
                        to_m: [fx, fy],
                    });
                }
            }
            None => {
                let mut x = State::zeros();
                x[X] = fx;
                x[Y] = fy;
                let mut p = prior(&self.params, 1.0, PI);
                gs::reset_position(&mut x, &mut p, [fx, fy], cov, 0.0);
                self.state = Some((x, p));
                self.clocks.clear();
                self.heading_from_track = Some(None);
                self.heard.clear();
            }
        }
    }

    /// After the state moved at `t_s`: the chain's offset is set again
    /// from its last arrival (sigma `sigma_m`) and the blame measured
    /// against the old state is forgotten.
    fn restart_chain(&mut self, t_s: f64, sigma_m: f64) {
        // The state moved under the chain's offset: set it again; the
        // blame was measured against a state now known to be wrong.
        self.offset_ready = false;
        self.late.clear();
        self.lost = false;
        self.gated_share = 0.0;
        self.watch = RejectionWatch::default();
        let last = *self.chain.arrivals().last().unwrap_or(&Arrival {
            tx_m: [0.0; 3],
            rho_m: 0.0,
            t_s,
            clock: None,
        });
        self.offset_from(&last, sigma_m);
        self.last_outcome = Some(Outcome::Accepted {
            innovation_m: 0.0,
            normalised: 0.0,
        });
    }
}
