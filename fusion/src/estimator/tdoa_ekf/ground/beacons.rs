//! Absolute ranges to radio beacons, with their bias and scale estimated.

use super::TdoaEkf;
use crate::estimator::tdoa_ekf::ground_state::{self as gs, RANGE_BIAS, RANGE_SCALE, Row, X, Y};
use crate::estimator::tdoa_ekf::observation::{Outcome, Rejection};

impl TdoaEkf {
    /// Fuses one absolute range `range_m` (standard deviation `sigma_m`)
    /// to a beacon at `beacon_m` (`x, y`, same height as the antenna),
    /// measured at `t_s`, read as `(1 + scale) d + bias` with both estimated. Late (long)
    /// ranges are down-weighted and rejected like late arrivals.
    pub fn range(&mut self, t_s: f64, beacon_m: [f64; 2], range_m: f64, sigma_m: f64) -> Outcome {
        let out = self.range_update(t_s, beacon_m, range_m, sigma_m);
        self.t_s = self.t_s.max(t_s);
        self.last_outcome = Some(out);
        out
    }

    fn range_update(
        &mut self,
        t_s: f64,
        beacon_m: [f64; 2],
        range_m: f64,
        sigma_m: f64,
    ) -> Outcome {
        if ![t_s, beacon_m[0], beacon_m[1], range_m]
            .iter()
            .all(|v| v.is_finite())
        {
            return Outcome::Rejected(Rejection::NonFinite { field: "range" });
        }
        if !(sigma_m.is_finite() && sigma_m > 0.0) {
            return Outcome::Rejected(Rejection::BadSigma { sigma_m });
        }
        let Some((x, p)) = self.state else {
            return Outcome::Rejected(Rejection::NotInitialised);
        };
        let at = self.position_at(&x, t_s);
        let (dx, dy) = (at.x - beacon_m[0], at.y - beacon_m[1]);
        let d = dx.hypot(dy);
        if d < 1e-6 {
            return Outcome::Rejected(Rejection::Numerical);
        }
        let k = 1.0 + x[RANGE_SCALE];
        let mut h = Row::zeros();
        h[X] = k * dx / d;
        h[Y] = k * dy / d;
        h[RANGE_BIAS] = 1.0;
        h[RANGE_SCALE] = d;
        let nu = range_m - k * d - x[RANGE_BIAS];
        let r = sigma_m * sigma_m;
        let s = gs::innovation_variance(&p, &h, r);
        let normalised = nu / s.sqrt();
        if normalised.abs() > self.params.gate_sigma {
            // Only a range far shorter than predicted (impossible for a
            // late, non-direct path) is evidence of a lost filter.
            self.note(normalised < 0.0);
            return Outcome::Rejected(Rejection::Gate {
                normalised: normalised.abs(),
            });
        }
        let soft = self.params.late_soft_sigma;
        let r = if normalised > soft {
            r + s * ((normalised / soft).powi(2) - 1.0)
        } else {
            r
        };
        match gs::update(&x, &p, &h, nu, r) {
            Some(next) => {
                self.state = Some(next);
                self.note(false);
                self.adapt(normalised);
                self.project_on_floor();
                Outcome::Accepted {
                    innovation_m: nu,
                    normalised: normalised.abs(),
                }
            }
            None => Outcome::Rejected(Rejection::Numerical),
        }
    }
}
