//! What [`super::solve`] returns.

use nalgebra::{Matrix2, Matrix3, Vector3};

/// How much a fix can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Quality {
    /// Redundant signals, every residual within the gate, one root.
    Good,
    /// Exactly the minimum number of signals: residuals cannot be checked.
    Minimal,
    /// Two positions fit the signals; the other is in [`Fix::alternative_m`].
    Ambiguous,
    /// Residuals beyond the gate remain that no rejection could explain.
    Suspect,
}

/// Why a signal was left out of the fix.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum RejectReason {
    /// Its range difference to another signal exceeds the distance between
    /// the two transmitters (plus the noise allowance): impossible for any
    /// position, so the later (longer) arrival is taken as a reflection.
    ExceedsBaseline {
        /// The transmitter it conflicts with.
        other_tx_id: u32,
        /// By how much the difference exceeds the baseline, metres.
        excess_m: f64,
    },
    /// With the others fitting, its pseudo-range misses the fix by more
    /// than the gate (leave-one-out).
    Residual {
        /// Its residual against the fix of the others, metres (positive:
        /// late, as after a reflection).
        residual_m: f64,
    },
}

/// A signal left out, and why.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rejection {
    /// Transmitter id.
    pub tx_id: u32,
    /// The reason.
    pub reason: RejectReason,
}

/// A position fix from one cycle: what the solver found, and the one fix
/// type every estimator consumes (the wire's `robot/<id>/fix` is its
/// encoding; `fusion` does not know the wire).
#[derive(Debug, Clone, PartialEq)]
pub struct Fix {
    /// Time of the fix, seconds: the mean arrival time of the cycle's
    /// signals (the robot's position is taken as the one at that instant).
    pub t_s: f64,
    /// Receiver position, metres (in 2D, `z` is the given height).
    pub position_m: Vector3<f64>,
    /// Covariance of the position, m^2: `sigma^2 (J^T J)^-1` at the fix,
    /// with `sigma` the configured range noise, or the residuals' own
    /// scale when that is larger. In 2D the `z` row and column are zero.
    pub covariance_m2: Matrix3<f64>,
    /// The common offset `b` of the cycle, metres.
    pub bias_m: f64,
    /// Transmitters used, in input order.
    pub used_tx_ids: Vec<u32>,
    /// Pseudo-range residual of each used signal (same order), metres.
    pub residuals_m: Vec<f64>,
    /// Transmitters left out, in the order they were rejected.
    pub rejected: Vec<Rejection>,
    /// How much to trust the fix.
    pub quality: Quality,
    /// The other position that fits as well, when [`Quality::Ambiguous`].
    pub alternative_m: Option<Vector3<f64>>,
    /// Gauss-Newton iterations run (0 without refinement).
    pub iterations: u32,
    /// Heading from the first-hit receiver id (the ICKON paper, eq. 4-6) or from two
    /// MSUs on one robot (the iGPS paper, eq. 1), radians. The solver leaves it
    /// `None`: only the MSU knows which receiver heard which signal, see
    /// [`Fix::with_heading`].
    pub heading_rad: Option<f64>,
}

impl Fix {
    /// A fix known only by its position and covariance (a replayed or
    /// synthetic source, or another positioning system): no signals behind
    /// it, [`Quality::Minimal`] since nothing can be checked.
    pub fn from_position(t_s: f64, x_m: f64, y_m: f64, covariance_xy_m2: Matrix2<f64>) -> Self {
        let mut covariance_m2 = Matrix3::zeros();
        covariance_m2
            .fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&covariance_xy_m2);
        Self {
            t_s,
            position_m: Vector3::new(x_m, y_m, 0.0),
            covariance_m2,
            bias_m: 0.0,
            used_tx_ids: Vec::new(),
            residuals_m: Vec::new(),
            rejected: Vec::new(),
            quality: Quality::Minimal,
            alternative_m: None,
            iterations: 0,
            heading_rad: None,
        }
    }

    /// The same fix with a heading measurement attached.
    pub fn with_heading(mut self, heading_rad: Option<f64>) -> Self {
        self.heading_rad = heading_rad;
        self
    }

    /// Horizontal position, metres.
    pub fn x_m(&self) -> f64 {
        self.position_m.x
    }

    /// Horizontal position, metres.
    pub fn y_m(&self) -> f64 {
        self.position_m.y
    }

    /// The horizontal block of the covariance, m^2.
    pub fn covariance_xy_m2(&self) -> Matrix2<f64> {
        self.covariance_m2.fixed_view::<2, 2>(0, 0).into_owned()
    }

    /// Root mean square of the residuals, metres.
    pub fn rms_residual_m(&self) -> f64 {
        let n = self.residuals_m.len().max(1) as f64;
        (self.residuals_m.iter().map(|r| r * r).sum::<f64>() / n).sqrt()
    }
}
