//! Arrivals against the prediction: the cycle's offset, the innovation
//! gate with its one-sided tail for late arrivals, the watch that marks
//! the filter lost, and the adaptation that reopens the heading when the
//! model stops holding.

use nalgebra::Vector3;

use super::{TdoaEkf, turn_scale_sigma};
use crate::estimator::RangeDifferenceSample;
use crate::estimator::tdoa_ekf::ground_chain::{Arrival, Link};
use crate::estimator::tdoa_ekf::ground_state::{
    self as gs, BIAS, OFFSET, Row, SOUND_SCALE, State, TH, TURN_SCALE, WIND_X, WIND_Y, X, Y,
};
use crate::estimator::tdoa_ekf::observation::{self, Outcome, Rejection};

/// Weight of one arrival in [`TdoaEkf`]'s gated share (about ten arrivals,
/// one or two cycles).
const GATED_SHARE_WEIGHT: f64 = 0.1;

/// Weight of one early arrival in the unexplained variance (about a
/// hundred: 15 to 20 s of driving at a few cycles a second, the time a
/// robot takes to cross the air of one place).
const UNEXPLAINED_WEIGHT: f64 = 0.01;

impl TdoaEkf {
    /// Predicted pseudo-range of an arrival without the offset, and its
    /// row (position columns, the local speed of sound when it is learnt,
    /// and its cell's clock bias in `clock`). A path of length `d` through
    /// air where sound is faster by the fraction `k` than the speed the
    /// MSU assumes reads `d / (1 + k)`, `(1 - k) d` to first order.
    fn arrival_model(&self, x: &State, a: &Arrival, clock: Option<usize>) -> Option<(f64, Row)> {
        let p = self.position_at(x, a.t_s);
        let r = p - Vector3::from(a.tx_m);
        let d = r.norm();
        if d < 1e-6 {
            return None;
        }
        let mut h = Row::zeros();
        let scale = if self.params.sensors.learns_local_air() {
            h[SOUND_SCALE] = -d;
            1.0 - x[SOUND_SCALE]
        } else {
            1.0
        };
        h[X] = scale * r.x / d;
        h[Y] = scale * r.y / d;
        // Wind `w` along the path from the transmitter shortens its travel
        // time by `w . r / c^2` to first order: the range reads `w . r / c`
        // short; the state holds `w / c`.
        let wind = if self.params.sensors.learns_local_wind() {
            h[WIND_X] = -r.x;
            h[WIND_Y] = -r.y;
            -(x[WIND_X] * r.x + x[WIND_Y] * r.y)
        } else {
            0.0
        };
        let bias = clock.map_or(0.0, |c| {
            h[c] = 1.0;
            x[c]
        });
        Some((scale * d + wind + bias, h))
    }

    /// The state column of the clock bias of `a`'s cell (giving the cell a
    /// slot when it has none).
    fn clock_column(&mut self, a: &Arrival) -> Option<usize> {
        if !self.params.learn_cell_sync {
            return None;
        }
        let sigma_m = self.params.sensors.clock_bias_sigma_m();
        let (x, p) = self.state.as_mut()?;
        self.clocks.column(a.clock, a.t_s, sigma_m, x, p)
    }

    /// Variance of one arrival's pseudo-range whose timing noise is
    /// `sigma_m`: never less than the survey's sigma squared. Where each
    /// transmitter really hangs is known only to the survey's accuracy, so
    /// an arrival is never better than that, however fine its stamp. With
    /// the timing alone, receivers five times better than the data sheet's
    /// (5 us instead of 70) made the filter trust its arrivals beyond the
    /// transmitters' 1 cm, gate the good ones and lose robots on
    /// `warehouse` (one at 321 mm mean; 31 mm at worst with the floor), and
    /// the `ideal` profile's microsecond stamps put `lab`'s `eight` at 36.6
    /// mm (7.8 with it). A floor and not a sum: at the sheet's timing (24
    /// mm) the survey's share is small beside it, and adding it cost about
    /// 1 mm of mean error on `warehouse`'s routes (seeds 1-3); with the
    /// floor every number at the sheet's timing is unchanged.
    fn arrival_variance(&self, sigma_m: f64) -> f64 {
        sigma_m.max(self.params.sensors.survey_sigma_m).powi(2)
    }

    /// Initialises the cycle's offset from arrival `a`.
    pub(super) fn offset_from(&mut self, a: &Arrival, sigma_m: f64) -> bool {
        let clock = self.clock_column(a);
        let Some((x, _)) = self.state else {
            return false;
        };
        let Some((pred, h)) = self.arrival_model(&x, a, clock) else {
            return false;
        };
        let r = self.arrival_variance(sigma_m);
        if let Some((x, p)) = &mut self.state {
            gs::init_offset(x, p, &h, a.rho_m, pred, r);
        }
        self.offset_ready = true;
        self.offset_confirmed = false;
        self.offset_range_m = pred;
        true
    }

    /// Watches the normalised innovations of accepted arrivals: their
    /// squares average one when the model holds. A run well above that
    /// (a gyro bias step, a slipping wheel: the data sheet's model no
    /// longer holds) reopens the heading and the turn bias to the sheet's
    /// power-up uncertainty, so the arrivals can pull them back.
    pub(super) fn adapt(&mut self, normalised: f64) {
        let n = f64::from(self.params.recovery.window.max(1));
        let nis = normalised * normalised;
        self.nis_mean += (nis - self.nis_mean) / n;
        self.nis_seen = self.nis_seen.saturating_add(1);
        if self.nis_seen < self.params.recovery.window || self.nis_mean < self.params.model_nis {
            return;
        }
        self.nis_seen = 0;
        self.nis_mean = 1.0;
        if let Some((_, p)) = &mut self.state {
            let b = self.params.sensors.gyro_bias_sigma_deg_s.to_radians();
            p[(BIAS, BIAS)] += b * b;
            p[(TH, TH)] += self.params.reinit_heading_sigma_deg.to_radians().powi(2) / 4.0;
            let s = turn_scale_sigma(&self.params);
            p[(TURN_SCALE, TURN_SCALE)] += s * s;
        }
        self.adaptations = self.adaptations.saturating_add(1);
    }

    /// Learns how much of an arrival's error the filter did not predict:
    /// the running mean of `nu^2 - s` over the arrivals on time or early.
    /// A reflection only ever makes an arrival late, so the early half of
    /// the innovations is free of them, and for an error symmetric about
    /// zero its mean square is the whole one's. What is left over is error
    /// the filter has no model of, mostly air that the site-wide speed of
    /// sound does not follow; it is the same cycle after cycle where the
    /// robot is, so it widens the published covariance (`systematic.rs`),
    /// not the arrivals' weights. `within_gate`: not an early arrival the
    /// offset is restarted from.
    fn note_unexplained(&mut self, nu_m: f64, s_m2: f64, within_gate: bool) {
        if nu_m <= 0.0 && within_gate && (nu_m * nu_m - s_m2).is_finite() {
            self.unexplained_m2 += UNEXPLAINED_WEIGHT * (nu_m * nu_m - s_m2 - self.unexplained_m2);
        }
    }

    /// Fuses one arrival of the chain (offset already initialised).
    fn arrival(&mut self, a: &Arrival, sigma_m: f64) -> Outcome {
        let clock = self.clock_column(a);
        let Some((x, p)) = self.state else {
            return Outcome::Rejected(Rejection::NotInitialised);
        };
        let Some((pred, mut h)) = self.arrival_model(&x, a, clock) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        h[OFFSET] = 1.0;
        let nu = a.rho_m - pred - x[OFFSET];
        // The speed of sound is known only as well as the air's temperature:
        // a range error in proportion to the distance. The part common to
        // the cycle goes into its offset; what is left is the error of the
        // difference to the arrival that set it. Without it, an exact world
        // (timing sigma 0.3 mm, the 1 us stamp) made the filter trust its
        // arrivals beyond every other model error it has and fail (57-118
        // mm on `lab` under `ideal`; 2-5 mm with it, see the README).
        // When the local speed is a state, its error is in the row instead.
        let speed = self.unmodelled_speed_rel_sigma() * (pred - self.offset_range_m);
        let r = self.arrival_variance(sigma_m) + speed * speed;
        let s = gs::innovation_variance(&p, &h, r);
        if !(s.is_finite() && s > 0.0) {
            return Outcome::Rejected(Rejection::Numerical);
        }
        let normalised = nu / s.sqrt();
        let (gate, soft) = (self.params.gate_sigma, self.params.late_soft_sigma);
        self.note_unexplained(nu, s, normalised >= -gate);
        self.gated_late = normalised > gate;
        let gated = normalised.abs() > gate;
        self.gated_share += GATED_SHARE_WEIGHT * (f64::from(u8::from(gated)) - self.gated_share);
        if normalised > gate {
            // Far later than predicted: a reflection. Not evidence of a lost
            // filter (a healthy one in a burst of reflections sees many).
            return Outcome::Rejected(Rejection::Gate { normalised });
        }
        if normalised < -gate || (normalised < -soft && !self.offset_confirmed) {
            // Earlier than predicted beyond the noise: no path is shorter
            // than the direct one, so the offset (set by an earlier arrival
            // that was itself late) is what is wrong: it starts again from
            // this arrival, which is not fused. While no arrival has yet
            // agreed with the offset, "beyond the noise" is the soft bound;
            // once one has, only the gate, and it counts as evidence of a
            // lost filter.
            self.note(normalised < -gate);
            self.offset_from(a, sigma_m);
            return Outcome::Rejected(Rejection::Gate {
                normalised: normalised.abs(),
            });
        }
        let r = if normalised > soft {
            // One-sided heavy tail: a moderately late arrival may carry a
            // short reflection; trust it less the later it is.
            r + s * ((normalised / soft).powi(2) - 1.0)
        } else {
            r
        };
        match gs::update(&x, &p, &h, nu, r) {
            Some((nx, np)) => {
                self.state = Some((nx, np));
                self.note(false);
                self.confirm_start_by_tracking(a.t_s);
                self.offset_confirmed |= normalised.abs() <= soft;
                self.adapt(normalised);
                self.project_on_floor();
                self.unknown_heading_drift_m = 0.0;
                self.heading_from_track();
                Outcome::Accepted {
                    innovation_m: nu,
                    normalised: normalised.abs(),
                }
            }
            None => Outcome::Rejected(Rejection::Numerical),
        }
    }

    /// Notes a gated measurement; marks the filter lost when most recent
    /// ones were rejected.
    pub(super) fn note(&mut self, rejected: bool) {
        if rejected {
            // Far earlier than predicted: evidence against the state, so
            // the time tracked from the start counts again from zero.
            self.tracking_since_s = None;
        }
        if self.watch.note(rejected, &self.params.recovery) {
            self.lost = true;
            self.tracking_since_s = None;
        }
    }

    pub(super) fn range_difference(&mut self, m: &RangeDifferenceSample) -> Outcome {
        let physical = observation::check(m);
        if let Err(r @ (Rejection::NonFinite { .. } | Rejection::BadSigma { .. })) = physical {
            return Outcome::Rejected(r);
        }
        let link = self
            .chain
            .add(m.a_m, m.b_m, m.d_m, m.t_s, m.a_t_s, m.clocks);
        // One arrival's sigma: the pair's is that of two.
        let sigma = m.sigma_m / std::f64::consts::SQRT_2;
        if self.state.is_none() {
            self.start_from_transmitters(m);
        }
        if self.lost && self.try_reinitialise(m.t_s) {
            return self
                .last_outcome
                .unwrap_or(Outcome::Rejected(Rejection::Gate {
                    normalised: f64::INFINITY,
                }));
        }
        if self.state.is_none() {
            return Outcome::Rejected(Rejection::NotInitialised);
        }
        let b = match link {
            Link::Started(a, b) => {
                self.offset_ready = false;
                // A transmitter set aside as late does not set the offset.
                if !self.late.is_arrival_aside(a.t_s, a.tx_m) && !self.offset_from(&a, sigma) {
                    return Outcome::Rejected(Rejection::Numerical);
                }
                b
            }
            Link::Continued(b) => b,
        };
        if self.late.is_arrival_aside(b.t_s, b.tx_m) {
            return Outcome::Rejected(Rejection::SetAside);
        }
        if !self.offset_ready {
            // The first arrival of the chain not set aside: it carries no
            // position by itself.
            return if self.offset_from(&b, sigma) {
                Outcome::Accepted {
                    innovation_m: 0.0,
                    normalised: 0.0,
                }
            } else {
                Outcome::Rejected(Rejection::Numerical)
            };
        }
        // A |d| beyond the baseline (physical check) means one of the two
        // arrivals is a reflection: the chain keeps the difference (the
        // next one undoes it) and the arrival is judged against the
        // prediction like any other, where a late one fails.
        let out = self.arrival(&b, sigma);
        match out {
            Outcome::Accepted { .. } => self.late.note_arrival(b.t_s, b.tx_m, false),
            Outcome::Rejected(Rejection::Gate { normalised }) => {
                // Gated late: blamed on this arrival. An early one (it
                // re-set the offset instead) is no late arrival.
                self.late
                    .note_arrival(b.t_s, b.tx_m, normalised > 0.0 && self.gated_late);
            }
            _ => {}
        }
        out
    }
}
