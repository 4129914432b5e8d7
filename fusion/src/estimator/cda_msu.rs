//! `cda-msu`: the CDA paper's heading chain ([`super::cda::CdaChain`]) feeding
//! the ICKON paper's heading and position filters, so that the encoder/gyro
//! chain gains absolute positioning.
//!
//! Per encoder step the chain's distance and heading change (encoder or gyro
//! by the curvature decision, plus the obstacle-avoidance complementary
//! filter) replace `dd` and `d_gamma_b` of the ICKON paper: heading KF prediction
//! (eq. 7), relative position correction (eq. 10-11), position AKF
//! prediction (eq. 12-15). MSU fixes correct the heading (eq. 8) and the
//! position (eq. 16-19) exactly as in `ickon-akf`.
//!
//! Choices: the ICKON paper's `sigma_w = 2 deg` per step is kept although the
//! chain's heading is better than raw encoders (conservative). After each fix
//! the chain's heading is re-based onto the fused heading so that a planned
//! obstacle-avoidance heading (world frame) and the chain agree.

use super::cda::{CdaChain, CdaParams};
use super::heading_kf::HeadingKfParams;
use super::history::InOrderFilter;
use super::ickon_akf::HeadingPositionFusion;
use super::position_akf::PositionAkfParams;
use super::{InitialPose, Input, PoseEstimate};

/// Parameters of `cda-msu`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CdaMsuParams {
    /// The CDA paper's heading chain (its `initial_pose` is ignored).
    pub cda: CdaParams,
    /// Heading fusion unit (the ICKON paper, eq. 7-8).
    pub heading: HeadingKfParams,
    /// Position fusion unit (the ICKON paper, eq. 12-19).
    pub position: PositionAkfParams,
    /// Known start pose; `None` starts from the first fix.
    pub initial_pose: Option<InitialPose>,
    /// Seconds of input history kept for late inputs.
    pub history_s: f64,
}

impl Default for CdaMsuParams {
    fn default() -> Self {
        Self {
            cda: CdaParams::default(),
            heading: HeadingKfParams::default(),
            position: PositionAkfParams::default(),
            initial_pose: None,
            history_s: super::history::default_history_s(),
        }
    }
}

/// The `cda-msu` state machine.
#[derive(Debug, Clone)]
pub struct CdaMsu {
    chain: CdaChain,
    fusion: HeadingPositionFusion,
}

impl CdaMsu {
    /// A filter with the given parameters.
    pub fn new(params: &CdaMsuParams) -> Self {
        let mut cda = params.cda;
        if let Some(p) = params.initial_pose {
            cda.initial_pose = p;
        }
        Self {
            chain: CdaChain::new(&cda),
            fusion: HeadingPositionFusion::new(
                params.heading,
                params.position,
                params.initial_pose,
            ),
        }
    }
}

impl InOrderFilter for CdaMsu {
    fn name(&self) -> &'static str {
        "cda-msu"
    }

    fn step(&mut self, input: &Input) {
        if let Input::Fix(fix) = input {
            self.fusion.fix(fix);
            self.chain.rebase_heading(self.fusion.heading.heading_rad());
        } else if let Some(inc) = self.chain.step(input) {
            self.fusion
                .relative_step(inc.t_s, inc.distance_m, inc.dtheta_rad);
        }
    }

    fn pose(&self) -> Option<PoseEstimate> {
        self.fusion.pose()
    }
}
