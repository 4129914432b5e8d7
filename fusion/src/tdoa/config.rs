//! Solver configuration, validated once at the edge of [`super::solve`].

use nalgebra::Vector3;

use super::SolveError;

/// What is unknown about the receiver position.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Mode {
    /// The receiver height is known (the MSU on its robot): solve `x, y`.
    TwoD {
        /// Receiver height, metres, in the transmitters' frame.
        height_m: f64,
    },
    /// Solve `x, y, z`.
    ThreeD,
}

impl Mode {
    /// Fewest signals that give a fix: unknowns plus the common offset.
    pub fn min_signals(self) -> usize {
        self.dimension() + 1
    }

    /// Number of position unknowns.
    pub fn dimension(self) -> usize {
        match self {
            Self::TwoD { .. } => 2,
            Self::ThreeD => 3,
        }
    }

    /// The known height, if any.
    pub fn height_m(self) -> Option<f64> {
        match self {
            Self::TwoD { height_m } => Some(height_m),
            Self::ThreeD => None,
        }
    }

    pub(crate) fn validate(self) -> Result<(), SolveError> {
        match self.height_m() {
            Some(h) if !h.is_finite() => Err(SolveError::InvalidConfig {
                field: "mode.height_m",
                reason: "must be finite",
            }),
            _ => Ok(()),
        }
    }
}

/// An axis-aligned box the receiver must be in (the cell, the floor).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Aabb {
    /// Lower corner, metres.
    pub min_m: Vector3<f64>,
    /// Upper corner, metres.
    pub max_m: Vector3<f64>,
}

impl Aabb {
    /// Whether `p` is inside (bounds included). In 2D only `x, y` are
    /// checked: the height is given, not solved.
    pub fn contains(&self, p: &Vector3<f64>, mode: Mode) -> bool {
        (0..mode.dimension()).all(|k| self.min_m[k] <= p[k] && p[k] <= self.max_m[k])
    }
}

/// Residual gate: how far a pseudo-range may sit from the fitted model.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Gate {
    /// Multiples of `sigma_range_m`.
    Sigmas(f64),
    /// Metres.
    Metres(f64),
}

impl Gate {
    /// The gate in metres for a given range noise.
    pub fn metres(self, sigma_range_m: f64) -> f64 {
        match self {
            Self::Sigmas(k) => k * sigma_range_m,
            Self::Metres(m) => m,
        }
    }
}

/// Configuration of [`super::solve`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverConfig {
    /// 2D with known height, or 3D.
    pub mode: Mode,
    /// Standard deviation of each pseudo-range (timing noise times the speed
    /// of sound), metres. Sets the covariance floor and the default gate.
    pub sigma_range_m: f64,
    /// Largest accepted residual; beyond it, redundant signals are tested
    /// one by one for removal.
    pub gate: Gate,
    /// Where the receiver can be; solutions outside are discarded.
    pub allowed_area_m: Option<Aabb>,
    /// Run Gauss-Newton after the closed form.
    pub refine: bool,
    /// Iteration cap of the refinement.
    pub max_iterations: u32,
    /// Most signals removed by the leave-one-out test per cycle (the
    /// physical check is not counted). Zero switches rejection off,
    /// the consensus fallback included; otherwise the consensus (tried
    /// when leave-one-out leaves a residual over the gate or no fix) may
    /// set aside more, as long as two signals more than the minimum agree.
    pub max_rejections: u32,
    /// Only late arrivals (positive residual) are rejected by the
    /// leave-one-out test: a reflection can only lengthen a path.
    pub late_only: bool,
}

impl Default for SolverConfig {
    /// 3D, 2.5 cm range noise (70 us of timing jitter at 343 m/s, the
    /// paper profile of the simulator), a 4-sigma gate, refinement on,
    /// up to 3 rejections of late arrivals.
    fn default() -> Self {
        Self {
            mode: Mode::ThreeD,
            sigma_range_m: 0.025,
            gate: Gate::Sigmas(4.0),
            allowed_area_m: None,
            refine: true,
            max_iterations: 10,
            max_rejections: 3,
            late_only: true,
        }
    }
}

impl SolverConfig {
    /// The residual gate in metres.
    pub fn gate_m(&self) -> f64 {
        self.gate.metres(self.sigma_range_m)
    }

    /// Checks every field's domain.
    pub fn validate(&self) -> Result<(), SolveError> {
        self.mode.validate()?;
        let bad = |field, reason| Err(SolveError::InvalidConfig { field, reason });
        if !(self.sigma_range_m > 0.0 && self.sigma_range_m.is_finite()) {
            return bad("sigma_range_m", "must be positive and finite");
        }
        // An infinite gate is allowed: it switches the consensus test off.
        if self.gate_m() <= 0.0 || self.gate_m().is_nan() {
            return bad("gate", "must be positive");
        }
        if let Some(area) = &self.allowed_area_m {
            let finite = area
                .min_m
                .iter()
                .chain(area.max_m.iter())
                .all(|v| !v.is_nan());
            if !finite || (0..3).any(|k| area.min_m[k] > area.max_m[k]) {
                return bad("allowed_area_m", "needs min <= max on every axis");
            }
        }
        if self.refine && self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1 when refining");
        }
        Ok(())
    }
}

/// Configuration of the pairwise refinement [`super::refine_pairs`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineConfig {
    /// Standard deviation of each range difference, metres.
    pub sigma_m: f64,
    /// Iteration cap.
    pub max_iterations: u32,
    /// A step shorter than this ends the iteration, metres.
    pub step_tolerance_m: f64,
}

impl Default for RefineConfig {
    /// 5 cm noise, 50 iterations (an arbitrary start may be far), 1 um.
    fn default() -> Self {
        Self {
            sigma_m: 0.05,
            max_iterations: 50,
            step_tolerance_m: 1e-6,
        }
    }
}

impl RefineConfig {
    pub(crate) fn validate(&self) -> Result<(), SolveError> {
        let bad = |field, reason| Err(SolveError::InvalidConfig { field, reason });
        if !(self.sigma_m > 0.0 && self.sigma_m.is_finite()) {
            return bad("sigma_m", "must be positive and finite");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if !(self.step_tolerance_m > 0.0 && self.step_tolerance_m.is_finite()) {
            return bad("step_tolerance_m", "must be positive and finite");
        }
        Ok(())
    }
}
