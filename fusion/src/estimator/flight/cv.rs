//! The 3D constant-velocity filter with the body shadow as a state:
//! `[p, v, s]` (metres, m/s, metres), white-noise acceleration, one scalar
//! update per range difference through the shared gate
//! ([`crate::estimator::tdoa_ekf`]), run under [`crate::estimator::guard::Guarded`].

use nalgebra::{SMatrix, SVector, Vector3};

use super::shadow;
use crate::estimator::guard::{FlightVolume, GuardedFilter};
use crate::estimator::tdoa_ekf::{Outcome, Rejection, gated_update};
use crate::estimator::{InvalidParameter, RangeDifferenceSample};

type V7 = SVector<f64, 7>;
type M7 = SMatrix<f64, 7, 7>;
const S: usize = 6;

/// Parameters of [`CvFilter`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CvParams {
    /// Power spectral density of the white acceleration, per axis,
    /// m^2/s^3.
    pub accel_psd_m2_s3: f64,
    /// Standard deviation of the velocity when (re)placed, per axis, m/s.
    pub initial_velocity_sigma_m_s: f64,
    /// Innovation gate, standard deviations.
    pub gate_sigma: f64,
    /// The body shadow `s` known before the flight (from the body's
    /// geometry), metres; the prior mean of the estimate. 0: no body.
    pub shadow_m: f64,
    /// Prior standard deviation of `s`, metres; 0 holds it at `shadow_m`
    /// (not estimated).
    pub shadow_prior_sigma_m: f64,
}

impl Default for CvParams {
    /// 1 m^2/s^3 (velocity changes of about 1 m/s within a second), 1 m/s,
    /// 3 sigma, no body shadow. (Estimating the shadow online is possible
    /// but weak: it is nearly the same signature as a height error, and on
    /// the UTIL flights the estimate wandered; see the README.)
    fn default() -> Self {
        Self {
            accel_psd_m2_s3: 1.0,
            initial_velocity_sigma_m_s: 1.0,
            gate_sigma: 3.0,
            shadow_m: 0.0,
            shadow_prior_sigma_m: 0.0,
        }
    }
}

impl CvParams {
    /// Checks every parameter is in its domain.
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        let bad = |field| {
            Err(InvalidParameter {
                estimator: "tdoa-ekf",
                field,
                reason: "must be finite and positive",
            })
        };
        for (field, v) in [
            ("accel_psd_m2_s3", self.accel_psd_m2_s3),
            (
                "initial_velocity_sigma_m_s",
                self.initial_velocity_sigma_m_s,
            ),
            ("gate_sigma", self.gate_sigma),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field);
            }
        }
        for (field, v) in [
            ("shadow_m", self.shadow_m),
            ("shadow_prior_sigma_m", self.shadow_prior_sigma_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(InvalidParameter {
                    estimator: "tdoa-ekf",
                    field,
                    reason: "must be finite and non-negative",
                });
            }
        }
        Ok(())
    }
}

/// The filter. Before [`GuardedFilter::reset`] places it, its position is
/// meaningless (it is not published).
#[derive(Debug, Clone, PartialEq)]
pub struct CvFilter {
    params: CvParams,
    t_s: f64,
    x: V7,
    p: M7,
}

impl CvFilter {
    /// An unplaced filter.
    pub fn new(params: CvParams) -> Result<Self, InvalidParameter> {
        params.validate()?;
        let mut p = M7::identity();
        // Unobserved when the shadow is held: any variance will do.
        p[(S, S)] = if params.shadow_prior_sigma_m > 0.0 {
            params.shadow_prior_sigma_m.powi(2)
        } else {
            1.0
        };
        let mut x = V7::zeros();
        x[S] = params.shadow_m;
        Ok(Self {
            params,
            t_s: 0.0,
            x,
            p,
        })
    }

    /// Velocity, m/s.
    pub fn velocity_m_s(&self) -> [f64; 3] {
        [self.x[3], self.x[4], self.x[5]]
    }

    /// The body shadow estimate and its standard deviation, metres.
    pub fn shadow_m(&self) -> (f64, f64) {
        (self.x[S], self.p[(S, S)].sqrt())
    }

    fn linearise(&self, m: &RangeDifferenceSample) -> Option<shadow::Linearised> {
        let p = Vector3::new(self.x[0], self.x[1], self.x[2]);
        let mut l = shadow::linearise(&p, m, self.x[S])?;
        if self.params.shadow_prior_sigma_m == 0.0 {
            // Held: no column in H.
            l.d_shadow = 0.0;
        }
        Some(l)
    }
}

impl GuardedFilter for CvFilter {
    fn predict_to(&mut self, t_s: f64) {
        if !t_s.is_finite() || t_s <= self.t_s {
            return;
        }
        let dt = t_s - self.t_s;
        let q = self.params.accel_psd_m2_s3;
        let mut f = M7::identity();
        let mut qm = M7::zeros();
        crate::estimator::kf::constant_velocity(&mut f, &mut qm, 0, 3, dt, q);
        let p = crate::estimator::kf::predict(&self.p, &f, &qm);
        let x = f * self.x;
        if x.iter().chain(p.iter()).all(|v| v.is_finite()) {
            (self.x, self.p, self.t_s) = (x, p, t_s);
        }
    }

    fn position_m(&self) -> Vector3<f64> {
        Vector3::new(self.x[0], self.x[1], self.x[2])
    }

    fn position_sigma_m(&self) -> f64 {
        crate::estimator::kf::largest_axis_sigma(&self.p, 0)
    }

    fn position_covariance_m2(&self) -> nalgebra::Matrix3<f64> {
        self.p.fixed_view::<3, 3>(0, 0).into_owned()
    }

    fn predicted_m(&self, m: &RangeDifferenceSample) -> Option<f64> {
        self.linearise(m).map(|l| l.predicted_m)
    }

    fn update(&mut self, m: &RangeDifferenceSample) -> Outcome {
        let Some(l) = self.linearise(m) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        let mut h = SMatrix::<f64, 1, 7>::zeros();
        h.fixed_view_mut::<1, 3>(0, 0)
            .copy_from(&l.gradient.transpose());
        h[(0, S)] = l.d_shadow;
        match gated_update(
            &self.x,
            &self.p,
            &h,
            m.d_m - l.predicted_m,
            m.sigma_m,
            self.params.gate_sigma,
        ) {
            Ok((x, p, outcome)) => {
                (self.x, self.p) = (x, p);
                // A body can only delay a signal: the shadow is one-sided.
                self.x[S] = self.x[S].max(0.0);
                outcome
            }
            Err(r) => Outcome::Rejected(r),
        }
    }

    fn reset(&mut self, t_s: f64, position_m: Vector3<f64>, sigma_m: f64) {
        let sv = self.params.initial_velocity_sigma_m_s;
        // The shadow belongs to the body, not to the lost track: kept.
        let (s, var_s) = (self.x[S], self.p[(S, S)]);
        self.x = V7::zeros();
        self.x.fixed_rows_mut::<3>(0).copy_from(&position_m);
        self.x[S] = s;
        self.p = M7::zeros();
        for k in 0..3 {
            self.p[(k, k)] = sigma_m * sigma_m;
            self.p[(k + 3, k + 3)] = sv * sv;
        }
        self.p[(S, S)] = var_s;
        self.t_s = t_s;
    }

    fn constrain(&mut self, volume: &FlightVolume) -> bool {
        let (q, moved) = volume.clamp(&self.position_m());
        for k in 0..3 {
            if moved[k] {
                self.x[k] = q[k];
                // Pressed against a wall: it does not keep going through.
                self.x[k + 3] = 0.0;
            }
        }
        moved.iter().any(|&m| m)
    }
}
