//! Positioning from one cycle of ultrasonic arrivals: the TDOA solver, its
//! error bound, and the headings the MSU derives from the same data.
//!
//! # Model and symbols
//! Transmitter `i` sits at the surveyed position `s_i` (metres). It fires at
//! the cycle start plus its scheduled offset, and the MSU hears it at
//! `t_i` on its own clock. Neither the cycle start nor the MSU clock offset
//! is known, so each arrival gives a **pseudo-range**
//!
//! ```text
//! rho_i = c (t_i - offset_i) = |p - s_i| + b
//! ```
//!
//! with `p` the receiver position and `b` one unknown offset common to the
//! whole cycle (the cycle start on the MSU clock, times `c`). Only range
//! differences carry information: `r_i1 = rho_i - rho_1 = r_i - r_1`, with
//! `r_i = |p - s_i|` and signal 1 the reference (the first used signal).
//!
//! # Pipeline of [`solve`]
//! 1. Input checks: finite numbers, unique transmitter ids, enough signals
//!    for the [`Mode`] (bad input is an error of kind
//!    [`ErrorKind::BadInput`]; data that determine no position give
//!    [`ErrorKind::NoFix`]).
//! 2. Cheap physical check (as the Crazyflie LPS TDoA code does): a range
//!    difference cannot exceed the distance between its two transmitters.
//!    A reflection is late, so the longer of a violating pair is dropped.
//! 3. Closed form of the ICKON paper, s3.1 eq. 1-3 ([`closed_form`]): subtracting
//!    the circle equations `|p - s_i|^2 = (r_1 + r_i1)^2` from the reference
//!    one gives equations linear in `p` and `r_1`; least squares gives
//!    `p = u + r_1 v`, and `r_1^2 = |p - s_1|^2` is a quadratic in `r_1`.
//!    Physical roots have `r_i >= 0` for every `i`; of two, the one with the
//!    smaller residual (and inside the allowed area) wins.
//! 4. Gauss-Newton on the range differences, seeded by the closed form.
//!    Eliminating `b` makes least squares on the pseudo-ranges the same
//!    problem as least squares on the range differences with their full
//!    correlation, in 3 (2D: 2) unknowns.
//! 5. With redundant signals, leave-one-out on the residuals removes
//!    arrivals that do not fit (reflections), one at a time, while some
//!    residual exceeds the gate. Every removal is reported with its reason
//!    in [`Fix::rejected`].
//! 6. When that leaves a residual over the gate or no fix (more reflections
//!    than it may remove; a wrong transmitter id heard far too early, which
//!    the physical check, built for late arrivals, answers by dropping every
//!    other signal), a consensus over small subsets looks for the largest
//!    set agreeing on one position: at least two signals more than the
//!    minimum and a majority of the cycle.
//!
//! [`solve_moving`] is the same pipeline for a receiver that moves during
//! the cycle: each arrival is related to the position at its own arrival
//! time through the displacement odometry measured since the reference
//! instant.
//!
//! [`refine_pairs`] runs the same Gauss-Newton on independent pairwise
//! differences `|p - s_b| - |p - s_a| = d` (UWB anchor pairs).
//!
//! [`Mode::ThreeD`] needs 4 signals (exact, possibly two roots) and 5 for an
//! over-determined fix; its transmitters must not be coplanar.
//! [`Mode::TwoD`] knows the receiver height and needs 3; its transmitters
//! must not be collinear seen from above.
//!
//! # Noise and bounds
//! Each pseudo-range carries independent noise of standard deviation
//! `sigma_range_m` (the timing noise times `c`), so the range differences
//! against one reference are correlated. The solver's covariance and
//! [`crlb`] use the pseudo-range model with `b` as a nuisance parameter,
//! which is the same information as the range-difference model with its
//! full correlation. [`dop`] gives the same matrix per unit noise.
//!
//! # Headings
//! [`heading_from_first_receiver`] (the ICKON paper, eq. 4-6) and
//! [`two_sensor_heading`] (the iGPS paper, eq. 1). Angles follow the crate
//! convention: radians, counter-clockwise from +x, wrapped to `(-pi, pi]`.

mod bound;
mod closed_form;
mod config;
mod consensus;
mod error;
mod fix;
mod heading;
mod moving;
mod pairs;
mod refine;
mod residuals;
mod robust;
mod signal;
mod sound;

#[cfg(test)]
mod tests;

pub use bound::{Bound, Dop, crlb, dop};
pub use closed_form::{Candidate, ClosedForm, MIN_THICKNESS_RATIO, closed_form};
pub use config::{Aabb, Gate, Mode, RefineConfig, SolverConfig};
pub use error::{ErrorKind, SolveError};
pub use fix::{Fix, Quality, RejectReason, Rejection};
pub use heading::{
    HeadingError, SEED_RECEIVER_ANGLES_RAD, heading_from_first_receiver, two_sensor_heading,
};
pub use moving::{displacements_at_velocity, displacements_from_track, solve_moving};
pub use pairs::{PairMeasurement, Solution3, refine_pairs};
pub use robust::solve;
pub use signal::{MAX_SIGNALS, Signal};
pub use sound::{SoundError, speed_of_sound_m_s};
