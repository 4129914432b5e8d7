//! The ground filter's state, its dead-reckoning prediction and its scalar
//! update.
//!
//! State (SI units): `x, y` (m), `theta` (rad), `turn_bias` (rad/s, the
//! bias of the heading source: the gyro's, or the wheels' heading drift when
//! no gyro runs), `distance_scale` (the travelled distance is the measured
//! one times `1 + distance_scale`), `offset` (m, the unknown common offset
//! of the pseudo-ranges of the cycle being fused, re-initialised at the
//! start of every cycle) and `range_bias` (m, a constant excess of absolute
//! radio ranges) and `range_scale` (their excess proportional to the
//! distance, a ranging clock-rate error): a range reads
//! `(1 + range_scale) d + range_bias`; both used by range updates only;
//! `turn_scale` (the scale error of the heading source: the heading change
//! it reports is the true one times `1 + turn_scale`, plus the bias).
//!
//! Why a turn scale state: a gyro's scale error (0.5 % on a low-cost MEMS
//! sheet) is one constant, not white noise per step. Treated as white, its
//! share of the heading error after a full turn is counted as
//! `0.005 * 2 pi / sqrt(steps)` instead of `0.005 * 2 pi` (1.8 deg), so the
//! filter trusted a heading that was off by up to two degrees after every
//! loop; on the `eight` route, which turns the whole time, that was the
//! largest error left (diagnosed by switching the simulated scale error off:
//! 23.4 -> 15.6 mm mean). As a state with the sheet's prior it is learnt from
//! the arrivals while the robot turns.
//!
//! `sound_scale` (the relative error of the speed of sound in the air
//! around the robot against the site-wide speed the MSU uses: an arrival's
//! pseudo-range reads `(1 - sound_scale) d` for a path of length `d`; see
//! `ground_noise.rs` for why it is a state).
//!
//! Last, [`CLOCK_SLOTS`] clock biases (m): the residual sync error of each
//! cell heard lately, as the extra path it adds to every arrival of that
//! cell (see `ClockSlots` in `ground.rs`).

use nalgebra::{SMatrix, SVector};

use crate::estimator::dead_reckoning::arc_step;
use crate::estimator::kf;

/// Cells whose clock bias the state holds at once (a robot hears two or
/// three cells at a time on `warehouse`, all four on `lab`).
pub(super) const CLOCK_SLOTS: usize = 4;
/// Index of the first clock bias.
pub(super) const CLOCK: usize = 12;
/// Number of state components.
pub(super) const N: usize = CLOCK + CLOCK_SLOTS;
/// State vector.
pub(super) type State = SVector<f64, N>;
/// Covariance of the state.
pub(super) type Cov = SMatrix<f64, N, N>;
/// One observation row.
pub(super) type Row = SMatrix<f64, 1, N>;

/// Index of `x`.
pub(super) const X: usize = 0;
/// Index of `y`.
pub(super) const Y: usize = 1;
/// Index of `theta`.
pub(super) const TH: usize = 2;
/// Index of the turn-rate bias.
pub(super) const BIAS: usize = 3;
/// Index of the distance scale error.
pub(super) const SCALE: usize = 4;
/// Index of the cycle's pseudo-range offset.
pub(super) const OFFSET: usize = 5;
/// Index of the range bias.
pub(super) const RANGE_BIAS: usize = 6;
/// Index of the range scale error.
pub(super) const RANGE_SCALE: usize = 7;
/// Index of the turn scale error of the heading source.
pub(super) const TURN_SCALE: usize = 8;
/// Index of the local relative error of the speed of sound.
pub(super) const SOUND_SCALE: usize = 9;
/// Index of the local wind's east component over the speed of sound.
pub(super) const WIND_X: usize = 10;
/// Index of the local wind's north component over the speed of sound.
pub(super) const WIND_Y: usize = 11;

/// One dead-reckoning step as the sensors measured it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Step {
    /// Measured distance, metres (signed).
    pub distance_m: f64,
    /// Measured heading change, bias included, radians.
    pub dtheta_rad: f64,
    /// Time over which the heading change was integrated, seconds (the
    /// bias acts over it).
    pub turn_time_s: f64,
    /// Variance of the measured distance, m^2.
    pub var_distance: f64,
    /// Variance of the measured heading change, rad^2.
    pub var_dtheta: f64,
    /// Variance added to the turn bias (random walk), (rad/s)^2.
    pub var_bias: f64,
}

/// Propagates `(x, p)` through one step: the arc of the CDA paper with the
/// distance scaled and the bias removed, linearised at the mid heading.
/// `None` when the result is not finite.
pub(super) fn predict(x: &State, p: &Cov, s: &Step) -> Option<(State, Cov)> {
    let scale = 1.0 + x[SCALE];
    let d = s.distance_m * scale;
    // First order in the scale error (a few thousandths).
    let dth = s.dtheta_rad * (1.0 - x[TURN_SCALE]) - x[BIAS] * s.turn_time_s;
    let (nx, ny, nt) = arc_step(x[X], x[Y], x[TH], d, dth);
    let mid = x[TH] + 0.5 * dth;
    let (sn, cs) = mid.sin_cos();
    let mut f = Cov::identity();
    f[(X, TH)] = -d * sn;
    f[(Y, TH)] = d * cs;
    // The bias turns the heading over the step, and the mid heading by half.
    f[(TH, BIAS)] = -s.turn_time_s;
    f[(X, BIAS)] = d * sn * 0.5 * s.turn_time_s;
    f[(Y, BIAS)] = -d * cs * 0.5 * s.turn_time_s;
    // The scale error likewise, in proportion to the measured turn.
    f[(TH, TURN_SCALE)] = -s.dtheta_rad;
    f[(X, TURN_SCALE)] = d * sn * 0.5 * s.dtheta_rad;
    f[(Y, TURN_SCALE)] = -d * cs * 0.5 * s.dtheta_rad;
    f[(X, SCALE)] = s.distance_m * cs;
    f[(Y, SCALE)] = s.distance_m * sn;
    let mut q = Cov::zeros();
    let vd = s.var_distance * scale * scale;
    q[(X, X)] = vd * cs * cs;
    q[(Y, Y)] = vd * sn * sn;
    q[(X, Y)] = vd * cs * sn;
    q[(Y, X)] = vd * cs * sn;
    q[(TH, TH)] = s.var_dtheta;
    q[(BIAS, BIAS)] = s.var_bias;
    let mut nxv = *x;
    nxv[X] = nx;
    nxv[Y] = ny;
    nxv[TH] = nt;
    let np = kf::predict(p, &f, &q);
    let finite = nxv.iter().chain(np.iter()).all(|v| v.is_finite());
    finite.then_some((nxv, np))
}

/// The scalar update with innovation `nu` and measurement variance `r`:
/// the innovation variance `S`, and the new state and covariance (Joseph
/// form), or `None` when not numerically valid.
pub(super) fn update(x: &State, p: &Cov, h: &Row, nu: f64, r: f64) -> Option<(State, Cov)> {
    let (x, p) = kf::update(
        x,
        p,
        h,
        &SMatrix::<f64, 1, 1>::new(r),
        &SVector::<f64, 1>::new(nu),
    )?;
    p.cholesky()?;
    Some((x, p))
}

/// A first-order Gauss-Markov step of component `k` of stationary sigma
/// `sigma`: its mean and its correlations shrink by `memory` (in 0..=1),
/// its variance relaxes towards `sigma^2`.
pub(super) fn forget(x: &mut State, p: &mut Cov, k: usize, memory: f64, sigma: f64) {
    let m = memory.clamp(0.0, 1.0);
    x[k] *= m;
    for j in 0..N {
        if j != k {
            p[(k, j)] *= m;
            p[(j, k)] *= m;
        }
    }
    p[(k, k)] = m * m * p[(k, k)] + (1.0 - m * m) * sigma * sigma;
}

/// `h P h^T + r`.
pub(super) fn innovation_variance(p: &Cov, h: &Row, r: f64) -> f64 {
    (h * p * h.transpose())[(0, 0)] + r
}

/// Initialises the offset from one pseudo-range `rho` predicted as `pred`
/// (without offset) with gradient `h` (no offset column) and variance `r`:
/// the offset takes the value that explains the arrival, with the exact
/// cross-covariance, so the arrival carries no position information by
/// itself and each later one of the cycle is a proper range difference.
pub(super) fn init_offset(x: &mut State, p: &mut Cov, h: &Row, rho: f64, pred: f64, r: f64) {
    x[OFFSET] = rho - pred;
    for k in 0..N {
        p[(OFFSET, k)] = 0.0;
        p[(k, OFFSET)] = 0.0;
    }
    let hp = h * *p;
    let var = (hp * h.transpose())[(0, 0)] + r;
    for k in 0..N {
        p[(OFFSET, k)] = -hp[(0, k)];
        p[(k, OFFSET)] = -hp[(0, k)];
    }
    p[(OFFSET, OFFSET)] = var;
}

/// Resets the position block to `xy` with covariance `cov_xy`, dropping
/// its correlations, and adds `extra_heading_var` to the heading.
pub(super) fn reset_position(
    x: &mut State,
    p: &mut Cov,
    xy: [f64; 2],
    cov_xy: [[f64; 2]; 2],
    extra_heading_var: f64,
) {
    x[X] = xy[0];
    x[Y] = xy[1];
    for i in [X, Y] {
        for k in 0..N {
            p[(i, k)] = 0.0;
            p[(k, i)] = 0.0;
        }
    }
    for (i, a) in [X, Y].into_iter().enumerate() {
        for (j, b) in [X, Y].into_iter().enumerate() {
            p[(a, b)] = cov_xy[i][j];
        }
    }
    let floor = crate::estimator::MIN_VARIANCE;
    p[(X, X)] = p[(X, X)].max(floor);
    p[(Y, Y)] = p[(Y, Y)].max(floor);
    p[(TH, TH)] += extra_heading_var;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diag() -> Cov {
        Cov::from_diagonal(&State::from_element(1e-4))
    }

    #[test]
    fn a_known_bias_is_removed_from_the_turn() {
        let mut x = State::zeros();
        x[BIAS] = 0.01;
        let s = Step {
            distance_m: 0.0,
            dtheta_rad: 0.01,
            turn_time_s: 1.0,
            var_distance: 0.0,
            var_dtheta: 0.0,
            var_bias: 0.0,
        };
        let (x, _) = predict(&x, &diag(), &s).unwrap();
        assert!(x[TH].abs() < 1e-12);
    }

    #[test]
    fn the_scale_lengthens_the_step_and_correlates_with_the_position() {
        let mut x = State::zeros();
        x[SCALE] = 0.1;
        let s = Step {
            distance_m: 1.0,
            dtheta_rad: 0.0,
            turn_time_s: 0.1,
            var_distance: 0.0,
            var_dtheta: 0.0,
            var_bias: 0.0,
        };
        let (x, p) = predict(&x, &diag(), &s).unwrap();
        assert!((x[X] - 1.1).abs() < 1e-12 && x[Y].abs() < 1e-12);
        assert!(p[(X, SCALE)] > 0.0);
    }

    #[test]
    fn an_offset_initialised_from_an_arrival_explains_it_exactly() {
        let mut x = State::zeros();
        let mut p = diag();
        let mut h = Row::zeros();
        h[X] = 0.6;
        h[Y] = 0.8;
        init_offset(&mut x, &mut p, &h, 5.0, 3.0, 1e-4);
        assert!((x[OFFSET] - 2.0).abs() < 1e-12);
        // The same arrival again would carry no information: its innovation
        // variance is only the measurement noise counted twice.
        let mut hh = h;
        hh[OFFSET] = 1.0;
        let s = innovation_variance(&p, &hh, 0.0);
        assert!((s - 1e-4).abs() < 1e-12, "{s}");
        assert!(p.cholesky().is_some());
    }
}
