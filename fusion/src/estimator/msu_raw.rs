//! `msu-raw`: the MSU fixes alone, held between cycles (baseline).
//!
//! - The pose is the newest fix by measurement time; a fix older than the
//!   held one (after replay, see [`super::replay`]) is superseded by it.
//! - Heading: the fix's receiver-id heading (the ICKON paper, eq. 4-6). A fix without
//!   a heading keeps the previous heading, with a 180 deg standard deviation
//!   once none was ever received.
//! - Covariance: the fix's own position covariance (floored to
//!   1e-12, non-PD reports reduced to their diagonal), no
//!   cross terms with the heading, heading variance
//!   `heading_sigma_deg^2` (default 30 deg, the receiver spacing of 60 deg
//!   quantises the heading to +-30 deg).
//! - Holding does not grow the covariance: the baseline is "what the MSU
//!   said", and the evaluator scores the hold separately.

use nalgebra::{Matrix2, Matrix3};

use super::history::InOrderFilter;
use super::{Input, PoseEstimate};
use crate::tdoa::Fix;

/// Parameters of `msu-raw`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MsuRawParams {
    /// Standard deviation reported for the receiver-id heading, degrees.
    pub heading_sigma_deg: f64,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for MsuRawParams {
    fn default() -> Self {
        Self {
            heading_sigma_deg: 30.0,
            history_s: super::history::default_history_s(),
        }
    }
}

/// The `msu-raw` state machine.
#[derive(Debug, Clone)]
pub struct MsuRaw {
    params: MsuRawParams,
    fix: Option<Fix>,
    heading_rad: Option<f64>,
}

impl MsuRaw {
    /// Empty until the first fix.
    pub fn new(params: &MsuRawParams) -> Self {
        Self {
            params: *params,
            fix: None,
            heading_rad: None,
        }
    }
}

impl InOrderFilter for MsuRaw {
    fn name(&self) -> &'static str {
        "msu-raw"
    }

    fn step(&mut self, input: &Input) {
        if let Input::Fix(fix) = input {
            self.fix = Some(fix.clone());
            if let Some(h) = fix.heading_rad {
                self.heading_rad = Some(h);
            }
        }
    }

    fn pose(&self) -> Option<PoseEstimate> {
        let fix = self.fix.as_ref()?;
        let mut p: Matrix2<f64> =
            (fix.covariance_xy_m2() + fix.covariance_xy_m2().transpose()) * 0.5;
        if p.cholesky().is_none() {
            p = Matrix2::from_diagonal(&p.diagonal().map(|v| v.abs().max(super::MIN_VARIANCE)));
        }
        let sigma_h = match self.heading_rad {
            Some(_) => self.params.heading_sigma_deg.to_radians(),
            None => std::f64::consts::PI,
        };
        let mut covariance = Matrix3::zeros();
        covariance.fixed_view_mut::<2, 2>(0, 0).copy_from(&p);
        covariance[(2, 2)] = sigma_h * sigma_h;
        Some(PoseEstimate {
            t_s: fix.t_s,
            x_m: fix.x_m(),
            y_m: fix.y_m(),
            theta_rad: self.heading_rad.unwrap_or(0.0),
            covariance,
        })
    }
}
