//! The 3D constant-velocity filter with the body shadow and the anchors'
//! excess paths as states: `[p, v, s, e_1..e_8]` (metres, m/s, metres,
//! metres; see `excess.rs`), white-noise acceleration, one scalar update
//! per range difference through the shared gate
//! ([`crate::estimator::tdoa_ekf`]), run under [`crate::estimator::guard::Guarded`].

use nalgebra::{SMatrix, SVector, Vector3};

use super::excess::{EXCESS_SLOTS, ExcessParams, ExcessSlots};
use super::shadow;
use crate::estimator::guard::{FlightVolume, GuardedFilter};
use crate::estimator::tdoa_ekf::{Outcome, Rejection, gated_update};
use crate::estimator::{InvalidParameter, RangeDifferenceSample};

const S: usize = 6;
/// First excess-path state.
const E: usize = 7;
const N: usize = E + EXCESS_SLOTS;
type VN = SVector<f64, N>;
type MN = SMatrix<f64, N, N>;

/// Parameters of [`CvFilter`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CvParams {
    /// Power spectral density of the white acceleration, per axis,
    /// m^2/s^3.
    pub accel_psd_m2_s3: f64,
    /// The vertical axis's acceleration density as a share of
    /// `accel_psd_m2_s3` (1: the same on every axis). A vehicle that
    /// changes its height less briskly than its horizontal velocity has a
    /// smaller one; where the anchors' geometry sees height poorly (a
    /// receiver level with most anchors) the dynamics then carry the
    /// height through a run of biased range differences instead of letting
    /// the run pull it.
    pub vertical_psd_ratio: f64,
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
    /// The anchors' excess paths (off by default).
    pub excess: ExcessParams,
}

impl Default for CvParams {
    /// 1 m^2/s^3 (velocity changes of about 1 m/s within a second) on
    /// every axis, 1 m/s,
    /// 3 sigma, no body shadow. (Estimating the shadow online is possible
    /// but weak: it is nearly the same signature as a height error, and on
    /// the UTIL flights the estimate wandered; see the README.)
    fn default() -> Self {
        Self {
            accel_psd_m2_s3: 1.0,
            vertical_psd_ratio: 1.0,
            initial_velocity_sigma_m_s: 1.0,
            gate_sigma: 3.0,
            shadow_m: 0.0,
            shadow_prior_sigma_m: 0.0,
            excess: ExcessParams::default(),
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
            ("vertical_psd_ratio", self.vertical_psd_ratio),
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
        self.excess.validate("tdoa-ekf")?;
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
    x: VN,
    p: MN,
    excess: ExcessSlots,
}

impl CvFilter {
    /// An unplaced filter.
    pub fn new(params: CvParams) -> Result<Self, InvalidParameter> {
        params.validate()?;
        let mut p = MN::identity();
        let excess = ExcessSlots::new(params.excess, E);
        excess.init(&mut p);
        // Unobserved when the shadow is held: any variance will do.
        p[(S, S)] = if params.shadow_prior_sigma_m > 0.0 {
            params.shadow_prior_sigma_m.powi(2)
        } else {
            1.0
        };
        let mut x = VN::zeros();
        x[S] = params.shadow_m;
        Ok(Self {
            params,
            t_s: 0.0,
            x,
            p,
            excess,
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

    /// The excess-path estimates of the anchors heard lately: `(anchor,
    /// metres, standard deviation)`.
    pub fn excess_paths_m(&self) -> Vec<([f64; 3], f64, f64)> {
        self.excess.estimates(&self.x, &self.p)
    }

    /// The predicted range difference and its row of `H`.
    fn linearise(&self, m: &RangeDifferenceSample) -> Option<(f64, SMatrix<f64, 1, N>)> {
        let p = Vector3::new(self.x[0], self.x[1], self.x[2]);
        let l = shadow::linearise(&p, m, self.x[S])?;
        let (mut h, excess_m) = self.excess.observe(&self.x, m);
        h.fixed_view_mut::<1, 3>(0, 0)
            .copy_from(&l.gradient.transpose());
        // Held: no column in H.
        if self.params.shadow_prior_sigma_m > 0.0 {
            h[(0, S)] = l.d_shadow;
        }
        Some((l.predicted_m + excess_m, h))
    }
}

impl GuardedFilter for CvFilter {
    fn predict_to(&mut self, t_s: f64) {
        if !t_s.is_finite() || t_s <= self.t_s {
            return;
        }
        let dt = t_s - self.t_s;
        let q = self.params.accel_psd_m2_s3;
        let mut f = MN::identity();
        let mut qm = MN::zeros();
        crate::estimator::kf::constant_velocity(&mut f, &mut qm, 0, 3, dt, q);
        // The vertical axis (z, index 2 of the position and velocity
        // blocks) has its own share of the density.
        for (i, j) in [(2, 2), (2, 5), (5, 2), (5, 5)] {
            qm[(i, j)] *= self.params.vertical_psd_ratio;
        }
        let mut p = crate::estimator::kf::predict(&self.p, &f, &qm);
        let mut x = f * self.x;
        self.excess.decay(&mut x, &mut p, dt);
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
        self.linearise(m).map(|(predicted_m, _)| predicted_m)
    }

    fn update(&mut self, m: &RangeDifferenceSample) -> Outcome {
        self.excess.assign(&mut self.x, &mut self.p, m);
        let Some((predicted_m, h)) = self.linearise(m) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        match gated_update(
            &self.x,
            &self.p,
            &h,
            m.d_m - predicted_m,
            m.sigma_m,
            self.params.gate_sigma,
        ) {
            Ok((x, p, outcome)) => {
                (self.x, self.p) = (x, p);
                // A body can only delay a signal: the shadow is one-sided.
                self.x[S] = self.x[S].max(0.0);
                self.excess.clamp(&mut self.x);
                outcome
            }
            Err(r) => Outcome::Rejected(r),
        }
    }

    fn reset(&mut self, t_s: f64, position_m: Vector3<f64>, sigma_m: f64) {
        let sv = self.params.initial_velocity_sigma_m_s;
        // The shadow belongs to the body, the excess paths to the arena,
        // not to the lost track: kept, uncorrelated with the new start.
        self.x.fixed_rows_mut::<3>(0).copy_from(&position_m);
        self.x.fixed_rows_mut::<3>(3).fill(0.0);
        self.p.fixed_view_mut::<6, N>(0, 0).fill(0.0);
        self.p.fixed_view_mut::<N, 6>(0, 0).fill(0.0);
        self.excess.decouple(&mut self.p);
        for k in 0..3 {
            self.p[(k, k)] = sigma_m * sigma_m;
            self.p[(k + 3, k + 3)] = sv * sv;
        }
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
