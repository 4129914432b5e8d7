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

/// Displacements from a recorded track: `track` holds `(t_s, [x_m, y_m])`
/// samples in time order (the robot's odometry or fused poses, any frame:
/// only differences are used); each arrival's displacement is the track
/// position at its time minus the one at `reference_s`, both linearly
/// interpolated (held at the ends). `None` when the track is empty or not
/// in time order. The receiver height does not change on a ground robot,
/// so `z` is zero.
pub fn displacements_from_track(
    track: &[(f64, [f64; 2])],
    arrival_times_s: &[f64],
    reference_s: f64,
) -> Option<Vec<Vector3<f64>>> {
    // NaN times count as out of order too.
    let ordered = track
        .windows(2)
        .all(|w| w[1].0.partial_cmp(&w[0].0).is_some_and(|o| o.is_ge()));
    if track.is_empty() || !ordered {
        return None;
    }
    let at = |t: f64| -> [f64; 2] {
        let k = track.partition_point(|s| s.0 <= t);
        if k == 0 {
            return track[0].1;
        }
        if k >= track.len() {
            return track[track.len() - 1].1;
        }
        let ((t0, a), (t1, b)) = (track[k - 1], track[k]);
        let w = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])]
    };
    let r = at(reference_s);
    Some(
        arrival_times_s
            .iter()
            .map(|t| {
                let p = at(*t);
                Vector3::new(p[0] - r[0], p[1] - r[1], 0.0)
            })
            .collect(),
    )
}
