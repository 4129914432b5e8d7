//! How the filter starts and finds its heading: from the transmitters
//! heard, from the track once the robot has driven, from the MSU fixes'
//! receiver-id heading, and when tracking confirms a start pose.

use std::f64::consts::PI;

use super::{TdoaEkf, TrackStart, prior};
use crate::angle;
use crate::estimator::RangeDifferenceSample;
use crate::estimator::tdoa_ekf::ground_state::{self as gs, Row, State, TH, X, Y};
use crate::estimator::tdoa_ekf::recovery::RejectionWatch;
use crate::tdoa;

/// A start pose from which the filter has fused arrivals this long, its
/// heading known and no arrival far earlier than predicted (the evidence
/// of a wrong state: a wrong start makes some arrivals early), is
/// confirmed, seconds: twice the span of
/// the cycles that may replace it, so the evidence for the start is the
/// stronger. Without it a start was confirmed only by cycles met while
/// lost, and a filter that had tracked from a right start for seconds,
/// once marked lost by a run of early arrivals, could still be moved by
/// three biased cycles as if it had never been right (`warehouse`, 16
/// robots, seed 3, `--fire-range-m 7`: robot r13 moved 0.8 m with its
/// heading reversed, wrong for ten seconds).
const TRACKING_CONFIRMS_A_START_S: f64 = 2.0;

impl TdoaEkf {
    /// After an accepted arrival at `t_s`: confirms the start pose once the
    /// filter has tracked from it for [`TRACKING_CONFIRMS_A_START_S`].
    pub(super) fn confirm_start_by_tracking(&mut self, t_s: f64) {
        if self.heading_from_track.is_some() {
            self.tracking_since_s = None;
            return;
        }
        let since = *self.tracking_since_s.get_or_insert(t_s);
        if t_s - since >= TRACKING_CONFIRMS_A_START_S {
            self.start_confirmed = true;
            // A filter that tracks is not lost, whatever marked it so (a
            // start counts as lost until confirmed): it is found again as
            // when consistent cycles agree with it.
            if self.lost {
                self.lost = false;
                self.candidate = None;
                self.watch = RejectionWatch::default();
            }
        }
    }

    pub(super) fn start_from_transmitters(&mut self, m: &RangeDifferenceSample) {
        for c in [m.a_m, m.b_m] {
            if !self.heard.contains(&c) {
                self.heard.push(c);
            }
        }
        if self.heard.len() < self.params.start_transmitters.max(1) {
            return;
        }
        let n = self.heard.len() as f64;
        let cx = self.heard.iter().map(|c| c[0]).sum::<f64>() / n;
        let cy = self.heard.iter().map(|c| c[1]).sum::<f64>() / n;
        let sxy = self.params.start_sigma_xy_m;
        let mut x = State::zeros();
        x[X] = cx;
        x[Y] = cy;
        self.state = Some((x, prior(&self.params, sxy, PI)));
        self.clocks.clear();
        self.heading_from_track = Some(None);
        self.heard.clear();
    }

    /// While the heading is unknown, after each accepted update: starts the
    /// chord once the position has settled, and sets the heading when it is
    /// long enough.
    pub(super) fn heading_from_track(&mut self) {
        let (Some(track), Some((x, p))) = (&mut self.heading_from_track, &mut self.state) else {
            return;
        };
        if p[(X, X)].max(p[(Y, Y)]).sqrt() > self.params.settled_sigma_m {
            return;
        }
        let Some(start) = track else {
            *track = Some(TrackStart {
                x_m: x[X],
                y_m: x[Y],
                turn_rad: 0.0,
            });
            return;
        };
        let (dx, dy) = (x[X] - start.x_m, x[Y] - start.y_m);
        if dx.hypot(dy) < self.params.heading_chord_m {
            return;
        }
        x[TH] = dy.atan2(dx) + 0.5 * start.turn_rad;
        let v = self.params.track_heading_sigma_deg.to_radians().powi(2);
        for k in 0..gs::N {
            if k != TH {
                p[(k, TH)] = 0.0;
                p[(TH, k)] = 0.0;
            }
        }
        p[(TH, TH)] = v;
        self.heading_from_track = None;
    }

    /// Fuses the receiver-id heading of one MSU fix.
    pub(super) fn fix(&mut self, f: &tdoa::Fix) {
        let sigma = self.params.heading_sigma_deg.to_radians();
        let (Some(heading), true) = (f.heading_rad, sigma > 0.0) else {
            return;
        };
        // A lost filter's heading waits for its position; an unconfirmed
        // start pose is no lost filter (the heading is measured as well).
        if self.heading_from_track.is_some() || (self.lost && self.start_confirmed) {
            return;
        }
        let Some((x, p)) = self.state else {
            return;
        };
        let mut h = Row::zeros();
        h[TH] = 1.0;
        let nu = angle::diff(heading, x[TH]);
        let r = sigma * sigma;
        let s = gs::innovation_variance(&p, &h, r);
        if nu.abs() > self.params.gate_sigma * s.sqrt() {
            return;
        }
        if let Some(next) = gs::update(&x, &p, &h, nu, r) {
            self.state = Some(next);
        }
    }
}
