//! A fix from a receiver that moves during the cycle.
//!
//! [`super::solve`] assumes one receiver position per cycle, but a robot at
//! 0.3 m/s moves about 12 cm between the first and the last arrival of a
//! 0.4 s cycle; along a corridor, where the transmitters sit in two rows,
//! that motion turns into errors across it. The robot's own odometry knows
//! the motion between arrivals well (a few millimetres over a cycle), so
//! each arrival is related to the position at its own arrival time:
//!
//! ```text
//! rho_i = |p + m_i - s_i| + b = |p - (s_i - m_i)| + b
//! ```
//!
//! with `p` the position at the reference instant and `m_i` the receiver's
//! displacement from that instant to arrival `i`. Shifting each
//! transmitter by `-m_i` gives the static problem exactly, so the whole
//! pipeline of [`super::solve`] (physical check, closed form, Gauss-Newton,
//! leave-one-out, allowed area) applies unchanged; the returned position is
//! the receiver's at the reference instant.

use nalgebra::Vector3;

use super::signal::MAX_SIGNALS;
use super::{Fix, Signal, SolveError, SolverConfig, solve};

/// [`super::solve`] with per-signal receiver displacements:
/// `displacements_m[i]` is where the receiver was when signal `i` arrived,
/// minus where it was at the reference instant (from odometry), in metres
/// and the transmitters' frame. The fix is the position at the reference
/// instant; all-zero displacements give exactly [`super::solve`].
///
/// Errors: [`SolveError::DisplacementCount`] when the two slices differ in
/// length, [`SolveError::NonFinite`] for a non-finite displacement, and
/// every error of [`super::solve`].
pub fn solve_moving(
    signals: &[Signal],
    displacements_m: &[Vector3<f64>],
    config: &SolverConfig,
) -> Result<Fix, SolveError> {
    if signals.len() != displacements_m.len() {
        return Err(SolveError::DisplacementCount {
            signals: signals.len(),
            displacements: displacements_m.len(),
        });
    }
    if signals.len() > MAX_SIGNALS {
        return Err(SolveError::TooManySignals {
            got: signals.len(),
            max: MAX_SIGNALS,
        });
    }
    if let Some(index) = displacements_m
        .iter()
        .position(|m| !m.iter().all(|v| v.is_finite()))
    {
        return Err(SolveError::NonFinite {
            field: "displacements_m",
            index,
        });
    }
    let shifted: Vec<Signal> = signals
        .iter()
        .zip(displacements_m)
        .map(|(s, m)| Signal {
            tx_m: s.tx_m - m,
            ..*s
        })
        .collect();
    solve(&shifted, config)
}

/// Displacements along a straight drive at `velocity_m_s` for arrivals at
/// `arrival_times_s`, relative to `reference_s`: the simplest odometry
/// model, for callers that only know a velocity over the cycle.
pub fn displacements_at_velocity(
    arrival_times_s: &[f64],
    reference_s: f64,
    velocity_m_s: Vector3<f64>,
) -> Vec<Vector3<f64>> {
    arrival_times_s
        .iter()
        .map(|t| velocity_m_s * (t - reference_s))
        .collect()
}
