//! Why a solve failed, split into the caller's fault and the cycle's.

use super::fix::Rejection;

/// Whether a [`SolveError`] is the caller's fault or the cycle's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The input or configuration is malformed: a bug or bad config upstream.
    BadInput,
    /// The input is well formed but determines no position this cycle: the
    /// MSU reports "no fix" and waits for the next cycle.
    NoFix,
}

/// A failed solve. Nothing here is a panic and no path returns a NaN
/// position: every way to fail has a variant.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// A number in the input is NaN or infinite.
    #[error("{field} of input {index} is not finite")]
    NonFinite {
        /// Which field.
        field: &'static str,
        /// Index of the signal, pair or transmitter in the input slice.
        index: usize,
    },
    /// Two signals of one cycle name the same transmitter.
    #[error("transmitter {tx_id} appears twice in one cycle")]
    DuplicateTransmitter {
        /// The repeated id.
        tx_id: u32,
    },
    /// More signals than the solver's fixed-size bookkeeping holds.
    #[error("{got} signals in one cycle, at most {max} are supported")]
    TooManySignals {
        /// Signals given.
        got: usize,
        /// The limit, [`super::MAX_SIGNALS`].
        max: usize,
    },
    /// A configuration value outside its domain.
    #[error("configuration `{field}` {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// A pair measurement whose two transmitters coincide.
    #[error("pair {index} has the same position for both transmitters")]
    CoincidentPair {
        /// Index of the pair.
        index: usize,
    },
    /// Fewer signals than the mode needs.
    #[error("{got} signals, at least {need} needed")]
    TooFewSignals {
        /// Signals (or pairs, or transmitters) given.
        got: usize,
        /// The minimum for the mode.
        need: usize,
    },
    /// Enough signals arrived, but too many were rejected as inconsistent.
    #[error(
        "{got} consistent signals after rejecting {} of them, at least {need} needed",
        rejected.len()
    )]
    TooFewConsistent {
        /// Signals left.
        got: usize,
        /// The minimum for the mode.
        need: usize,
        /// What was rejected and why.
        rejected: Vec<Rejection>,
    },
    /// The transmitters are (nearly) coplanar in 3D or collinear seen from
    /// above in 2D: the linear equations of the closed form do not fix the
    /// position.
    #[error(
        "transmitters are nearly {shape}: thickness/spread {thickness_ratio:.1e} is below {min:.1e}",
        shape = if *two_d { "collinear seen from above" } else { "coplanar" },
        min = super::closed_form::MIN_THICKNESS_RATIO
    )]
    DegenerateGeometry {
        /// Smallest over largest spread of the transmitters around the
        /// reference (square root of the eigenvalue ratio of `A^T A`).
        thickness_ratio: f64,
        /// Whether the mode was 2D.
        two_d: bool,
    },
    /// The Fisher information (`J^T J`) of the linearised problem is
    /// singular at this position: the geometry does not fix it locally.
    #[error("the geometry does not fix the position locally (singular information matrix)")]
    SingularInformation,
    /// The quadratic in `r_1` has no real root: the hyperbolas do not meet.
    #[error("the hyperbolas do not intersect (discriminant {discriminant:.3e} < 0)")]
    NoRealRoot {
        /// The discriminant of the quadratic in `r_1`.
        discriminant: f64,
    },
    /// Every root of the quadratic has a negative distance to some transmitter.
    #[error("no root gives non-negative distances to every transmitter")]
    NoPhysicalRoot,
    /// Every solution lies outside the allowed area.
    #[error("solution ({:.3}, {:.3}, {:.3}) m is outside the allowed area", position_m[0], position_m[1], position_m[2])]
    OutsideAllowedArea {
        /// The best solution found, metres.
        position_m: [f64; 3],
    },
    /// [`super::solve_moving`] got a different number of displacements
    /// than signals.
    #[error("{signals} signals but {displacements} displacements")]
    DisplacementCount {
        /// Signals given.
        signals: usize,
        /// Displacements given.
        displacements: usize,
    },
    /// The iteration did not settle (pairwise refinement from a poor start).
    #[error("no convergence after {iterations} iterations (last step {last_step_m:.3e} m)")]
    NotConverged {
        /// Iterations run.
        iterations: u32,
        /// Length of the last step, metres.
        last_step_m: f64,
    },
}

impl SolveError {
    /// Whether the caller's input or the cycle's data is at fault.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Self::NonFinite { .. }
            | Self::DuplicateTransmitter { .. }
            | Self::TooManySignals { .. }
            | Self::InvalidConfig { .. }
            | Self::CoincidentPair { .. }
            | Self::DisplacementCount { .. } => ErrorKind::BadInput,
            Self::TooFewSignals { .. }
            | Self::TooFewConsistent { .. }
            | Self::DegenerateGeometry { .. }
            | Self::SingularInformation
            | Self::NoRealRoot { .. }
            | Self::NoPhysicalRoot
            | Self::OutsideAllowedArea { .. }
            | Self::NotConverged { .. } => ErrorKind::NoFix,
        }
    }

    /// Shorthand for `kind() == ErrorKind::BadInput`.
    pub fn is_bad_input(&self) -> bool {
        self.kind() == ErrorKind::BadInput
    }
}
