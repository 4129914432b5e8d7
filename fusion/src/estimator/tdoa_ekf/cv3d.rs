//! The 3D constant-velocity variant, for a free-flying receiver: state
//! `[p, v]` (metres, m/s), white-noise acceleration between measurements,
//! one scalar update per range difference.
//!
//! Used directly (not through [`crate::estimator::Estimator`], whose pose
//! is planar): `predict_to(t)` then `update_range_difference(&m)` for each
//! measurement in time order; the outcome tells whether it was applied and,
//! if not, why ([`Rejection`]).
//!
//! Robustness, cheapest first: the physical check (`|d|` cannot exceed the
//! distance between the transmitters), then the innovation gate, then the
//! recovery of a lost filter ([`RecoveryParams`]).

use nalgebra::{Matrix6, SMatrix, Vector3, Vector6};

use super::observation::{self, Outcome, Rejection};
use super::recovery::{RecoveryParams, RejectionWatch};
use crate::estimator::{InvalidParameter, RangeDifferenceSample};

/// Parameters of the 3D filter. Every field has a documented default; the
/// defaults are generic, a user sets them for the platform (see the UTIL
/// replay of `ickon replay util` for a flying tag).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TdoaEkf3dParams {
    /// Power spectral density of the white acceleration driving the
    /// constant-velocity model, per axis, in m^2/s^3 (1: manoeuvres of about
    /// 1 m/s^2 sustained over a second).
    pub accel_psd_m2_s3: f64,
    /// Standard deviation of the start position, per axis, metres.
    pub initial_sigma_m: f64,
    /// Standard deviation of the start velocity, per axis, m/s.
    pub initial_velocity_sigma_m_s: f64,
    /// Innovation gate, in standard deviations of the innovation (3: a
    /// consistent measurement passes with 99.7 % probability).
    pub gate_sigma: f64,
    /// Propagation speed used by [`TdoaEkf3d::update_time_difference`],
    /// m/s (343.2: sound in air at 20 C; 299 792 458 for radio).
    pub propagation_speed_m_s: f64,
    /// Extra path of a signal arriving from below the receiver's antenna,
    /// at a depression of 90 degrees, in metres (scaled by the sine of the
    /// depression; 0 = no body in the way). See `observation::linearise`.
    pub shadow_bias_m: f64,
    /// When a filter counts as lost, and how it widens.
    pub recovery: RecoveryParams,
}

impl Default for TdoaEkf3dParams {
    fn default() -> Self {
        Self {
            accel_psd_m2_s3: 1.0,
            initial_sigma_m: 2.0,
            initial_velocity_sigma_m_s: 1.0,
            gate_sigma: 3.0,
            propagation_speed_m_s: 343.2,
            shadow_bias_m: 0.0,
            recovery: RecoveryParams::default(),
        }
    }
}

impl TdoaEkf3dParams {
    /// Checks every parameter is in its domain.
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        let bad = |field, reason| {
            Err(InvalidParameter {
                estimator: "tdoa-ekf",
                field,
                reason,
            })
        };
        for (field, v) in [
            ("accel_psd_m2_s3", self.accel_psd_m2_s3),
            ("initial_sigma_m", self.initial_sigma_m),
            (
                "initial_velocity_sigma_m_s",
                self.initial_velocity_sigma_m_s,
            ),
            ("gate_sigma", self.gate_sigma),
            ("propagation_speed_m_s", self.propagation_speed_m_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, "must be finite and positive");
            }
        }
        if !(self.shadow_bias_m.is_finite() && self.shadow_bias_m >= 0.0) {
            return bad("shadow_bias_m", "must be finite and non-negative");
        }
        self.recovery
            .check()
            .or_else(|(field, reason)| bad(field, reason))
    }
}

/// The 3D constant-velocity TDOA filter.
#[derive(Debug, Clone, PartialEq)]
pub struct TdoaEkf3d {
    params: TdoaEkf3dParams,
    t_s: f64,
    /// `[x, y, z, vx, vy, vz]`.
    x: Vector6<f64>,
    p: Matrix6<f64>,
    watch: RejectionWatch,
    recoveries: u64,
}

impl TdoaEkf3d {
    /// A filter at rest at `start_m` at time `t_s`, with the configured
    /// start uncertainty.
    pub fn new(
        params: TdoaEkf3dParams,
        start_m: [f64; 3],
        t_s: f64,
    ) -> Result<Self, InvalidParameter> {
        params.validate()?;
        if !(start_m.iter().all(|v| v.is_finite()) && t_s.is_finite()) {
            return Err(InvalidParameter {
                estimator: "tdoa-ekf",
                field: "start",
                reason: "must be finite",
            });
        }
        let (sp, sv) = (params.initial_sigma_m, params.initial_velocity_sigma_m_s);
        Ok(Self {
            params,
            t_s,
            x: Vector6::new(start_m[0], start_m[1], start_m[2], 0.0, 0.0, 0.0),
            p: Matrix6::from_diagonal(&Vector6::new(
                sp * sp,
                sp * sp,
                sp * sp,
                sv * sv,
                sv * sv,
                sv * sv,
            )),
            watch: RejectionWatch::default(),
            recoveries: 0,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &TdoaEkf3dParams {
        &self.params
    }

    /// Time of the state, seconds.
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    /// Position, metres.
    pub fn position_m(&self) -> [f64; 3] {
        [self.x[0], self.x[1], self.x[2]]
    }

    /// Velocity, m/s.
    pub fn velocity_m_s(&self) -> [f64; 3] {
        [self.x[3], self.x[4], self.x[5]]
    }

    /// Covariance of `[x, y, z, vx, vy, vz]`.
    pub fn covariance(&self) -> &Matrix6<f64> {
        &self.p
    }

    /// How many times the filter found itself lost and widened its
    /// position variance.
    pub fn recoveries(&self) -> u64 {
        self.recoveries
    }

    /// Moves the state forward to `t_s` with the constant-velocity model.
    /// A time not after the state's (or not finite) leaves it unchanged: a
    /// measurement that old is then applied at the state's time.
    pub fn predict_to(&mut self, t_s: f64) {
        if !t_s.is_finite() || t_s <= self.t_s {
            return;
        }
        let dt = t_s - self.t_s;
        let mut f = Matrix6::identity();
        let q = self.params.accel_psd_m2_s3;
        let mut qm = Matrix6::zeros();
        super::super::kf::constant_velocity(&mut f, &mut qm, 0, 3, dt, q);
        let p = super::super::kf::predict(&self.p, &f, &qm);
        let x = f * self.x;
        if x.iter().chain(p.iter()).all(|v| v.is_finite()) {
            self.x = x;
            self.p = p;
            self.t_s = t_s;
        }
    }

    /// Fuses one range difference at the state's time (call
    /// [`Self::predict_to`] with its time first). On rejection the state is
    /// unchanged, except for the recovery widening described in the module
    /// documentation.
    pub fn update_range_difference(&mut self, m: &RangeDifferenceSample) -> Outcome {
        if let Err(r) = observation::check(m) {
            return Outcome::Rejected(r);
        }
        let p = Vector3::new(self.x[0], self.x[1], self.x[2]);
        let Some(lin) = observation::linearise(&p, m, self.params.shadow_bias_m) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        let mut h = SMatrix::<f64, 1, 6>::zeros();
        h.fixed_view_mut::<1, 3>(0, 0)
            .copy_from(&lin.gradient.transpose());
        let innovation = m.d_m - lin.predicted_m;
        match observation::gated_update(
            &self.x,
            &self.p,
            &h,
            innovation,
            m.sigma_m,
            self.params.gate_sigma,
        ) {
            Ok((x, p, outcome)) => {
                self.x = x;
                self.p = p;
                self.watch.note(false, &self.params.recovery);
                outcome
            }
            Err(r) => {
                let gated = matches!(r, Rejection::Gate { .. });
                if gated && self.watch.note(true, &self.params.recovery) {
                    let v = self.params.recovery.sigma_m.powi(2);
                    for k in 0..3 {
                        self.p[(k, k)] += v;
                    }
                    self.recoveries += 1;
                }
                Outcome::Rejected(r)
            }
        }
    }

    /// Fuses one time difference `dt_s = t_b - t_a` (emission offsets
    /// removed) with standard deviation `sigma_s`, converted at
    /// `propagation_speed_m_s`.
    pub fn update_time_difference(
        &mut self,
        t_s: f64,
        a_m: [f64; 3],
        b_m: [f64; 3],
        dt_s: f64,
        sigma_s: f64,
    ) -> Outcome {
        let m = RangeDifferenceSample::from_time_difference(
            t_s,
            a_m,
            b_m,
            dt_s,
            sigma_s,
            self.params.propagation_speed_m_s,
        );
        self.update_range_difference(&m)
    }
}
