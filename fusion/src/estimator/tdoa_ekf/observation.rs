//! The range-difference observation shared by both variants: the cheap
//! physical check, the prediction with its gradient, and the outcome of an
//! update.

use nalgebra::{SMatrix, SVector, Vector1, Vector3};

use crate::estimator::RangeDifferenceSample;
use crate::estimator::kf;

/// Closer than this to a transmitter the gradient of the distance is not
/// defined (metres).
const MIN_DISTANCE_M: f64 = 1e-6;

/// Why a range difference was not applied. The filter state is unchanged.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// A field of the measurement is NaN or infinite.
    #[error("field `{field}` is not finite")]
    NonFinite {
        /// The offending field.
        field: &'static str,
    },
    /// The standard deviation is not positive.
    #[error("sigma_m = {sigma_m} is not positive")]
    BadSigma {
        /// The reported standard deviation, metres.
        sigma_m: f64,
    },
    /// `|d|` exceeds the distance between the transmitters: no receiver
    /// position can produce it (an outlier, a wrong id, a reflection).
    #[error("|d| = {d_m} m exceeds the {baseline_m} m between the transmitters")]
    Physical {
        /// The measured range difference, metres.
        d_m: f64,
        /// The distance between the two transmitters, metres.
        baseline_m: f64,
    },
    /// The innovation is further than the gate from the prediction, in
    /// standard deviations of the innovation (Mahalanobis distance).
    #[error("innovation of {normalised} sigma is beyond the gate")]
    Gate {
        /// `|innovation| / sqrt(S)`.
        normalised: f64,
    },
    /// The transmitter is set aside for a while: most of its recent
    /// arrivals came late (blocked, heard by a reflection;
    /// [`crate::estimator::guard::LateArrivals`]).
    #[error("the transmitter is set aside as late")]
    SetAside,
    /// The filter is not initialised yet (ground variant without a start
    /// pose, before enough transmitters were heard).
    #[error("the filter is not initialised")]
    NotInitialised,
    /// The receiver sits on a transmitter, or the update would make the
    /// state non-finite or its covariance not positive definite.
    #[error("the update would make the state numerically invalid")]
    Numerical,
}

/// What an update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// The measurement corrected the state.
    Accepted {
        /// Measured minus predicted range difference, metres.
        innovation_m: f64,
        /// `|innovation| / sqrt(S)`.
        normalised: f64,
    },
    /// The measurement was refused; the state is unchanged.
    Rejected(Rejection),
}

impl Outcome {
    /// Whether the measurement was applied.
    pub fn is_accepted(&self) -> bool {
        matches!(self, Outcome::Accepted { .. })
    }
}

/// Checks the fields are finite, the sigma positive and `|d|` physically
/// possible, cheapest first.
pub(crate) fn check(s: &RangeDifferenceSample) -> Result<(), Rejection> {
    let fields = [("t_s", s.t_s), ("d_m", s.d_m), ("sigma_m", s.sigma_m)];
    for (field, v) in fields {
        if !v.is_finite() {
            return Err(Rejection::NonFinite { field });
        }
    }
    if s.a_t_s.is_some_and(|t| !t.is_finite()) {
        return Err(Rejection::NonFinite { field: "a_t_s" });
    }
    if !s.a_m.iter().all(|v| v.is_finite()) {
        return Err(Rejection::NonFinite { field: "a_m" });
    }
    if !s.b_m.iter().all(|v| v.is_finite()) {
        return Err(Rejection::NonFinite { field: "b_m" });
    }
    if s.sigma_m <= 0.0 {
        return Err(Rejection::BadSigma { sigma_m: s.sigma_m });
    }
    let baseline_m = s.baseline_m();
    if s.d_m.abs() > baseline_m {
        return Err(Rejection::Physical {
            d_m: s.d_m,
            baseline_m,
        });
    }
    Ok(())
}

/// The predicted range difference at receiver position `p` and its
/// gradient with respect to `p`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Linearised {
    pub predicted_m: f64,
    pub gradient: Vector3<f64>,
}

/// `h(p) = |p - b| - |p - a| + shadow(b) - shadow(a)`, with
/// `shadow(c) = shadow_bias_m * max(0, (p_z - c_z) / |p - c|)`: the extra
/// path of a signal from a transmitter below the receiver's antenna, which
/// crosses the body carrying it. The shadow term is treated as a known
/// offset at the linearisation point (its gradient is `shadow_bias_m / |p -
/// c|`, a few per cent of the geometric one). `None` when `p` sits on a
/// transmitter.
pub(super) fn linearise(
    p: &Vector3<f64>,
    s: &RangeDifferenceSample,
    shadow_bias_m: f64,
) -> Option<Linearised> {
    let a = Vector3::from(s.a_m);
    let b = Vector3::from(s.b_m);
    let (ra, rb) = (p - a, p - b);
    let (da, db) = (ra.norm(), rb.norm());
    if da < MIN_DISTANCE_M || db < MIN_DISTANCE_M {
        return None;
    }
    let shadow = |r: &Vector3<f64>, d: f64| shadow_bias_m * (r.z / d).max(0.0);
    Some(Linearised {
        predicted_m: db - da + shadow(&rb, db) - shadow(&ra, da),
        gradient: rb / db - ra / da,
    })
}

/// The gated scalar update of a state of size `N` with observation row
/// `h`: refuses an innovation beyond `gate_sigma` standard deviations of
/// `S = h P h^T + sigma^2`, else applies the Joseph-form update. Returns the
/// new state and covariance with the outcome.
pub(crate) fn gated_update<const N: usize>(
    x: &SVector<f64, N>,
    p: &SMatrix<f64, N, N>,
    h: &SMatrix<f64, 1, N>,
    innovation_m: f64,
    sigma_m: f64,
    gate_sigma: f64,
) -> Result<(SVector<f64, N>, SMatrix<f64, N, N>, Outcome), Rejection> {
    let r = sigma_m * sigma_m;
    let s = (h * p * h.transpose())[(0, 0)] + r;
    if !(s.is_finite() && s > 0.0) {
        return Err(Rejection::Numerical);
    }
    let normalised = innovation_m.abs() / s.sqrt();
    if normalised > gate_sigma {
        return Err(Rejection::Gate { normalised });
    }
    let (x, p) = kf::update(
        x,
        p,
        h,
        &SMatrix::<f64, 1, 1>::new(r),
        &Vector1::new(innovation_m),
    )
    .ok_or(Rejection::Numerical)?;
    if p.cholesky().is_none() {
        return Err(Rejection::Numerical);
    }
    Ok((
        x,
        p,
        Outcome::Accepted {
            innovation_m,
            normalised,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(d_m: f64) -> RangeDifferenceSample {
        RangeDifferenceSample {
            a_t_s: None,
            t_s: 0.0,
            a_m: [0.0, 0.0, 0.0],
            b_m: [4.0, 0.0, 0.0],
            d_m,
            sigma_m: 0.1,
            clocks: None,
            speed_rel_sigma: None,
        }
    }

    #[test]
    fn range_difference_longer_than_the_baseline_is_physically_impossible() {
        assert_eq!(
            check(&sample(4.5)),
            Err(Rejection::Physical {
                d_m: 4.5,
                baseline_m: 4.0
            })
        );
        assert_eq!(check(&sample(-3.9)), Ok(()));
    }

    #[test]
    fn non_finite_and_non_positive_sigma_are_named() {
        let mut s = sample(1.0);
        s.b_m[2] = f64::NAN;
        assert_eq!(check(&s), Err(Rejection::NonFinite { field: "b_m" }));
        let mut s = sample(1.0);
        s.a_t_s = Some(f64::INFINITY);
        assert_eq!(check(&s), Err(Rejection::NonFinite { field: "a_t_s" }));
        let mut s = sample(1.0);
        s.sigma_m = 0.0;
        assert!(matches!(check(&s), Err(Rejection::BadSigma { .. })));
    }

    #[test]
    fn gradient_matches_finite_differences_and_sign_is_b_minus_a() {
        let s = sample(0.0);
        let p = Vector3::new(1.0, 2.0, 0.5);
        let l = linearise(&p, &s, 0.0).unwrap();
        let h = |p: Vector3<f64>| (p - Vector3::from(s.b_m)).norm() - p.norm();
        assert!((l.predicted_m - h(p)).abs() < 1e-12);
        // Closer to A than to B: B minus A is positive.
        assert!(l.predicted_m > 0.0);
        for k in 0..3 {
            let mut dp = Vector3::zeros();
            dp[k] = 1e-6;
            let numeric = (h(p + dp) - h(p - dp)) / 2e-6;
            assert!((numeric - l.gradient[k]).abs() < 1e-6);
        }
    }

    #[test]
    fn shadow_lengthens_only_paths_from_below_the_receiver() {
        let s = RangeDifferenceSample {
            a_m: [0.0, 0.0, 3.0],
            b_m: [0.0, 0.0, 0.0],
            ..sample(0.0)
        };
        let p = Vector3::new(0.0, 0.0, 1.0);
        let plain = linearise(&p, &s, 0.0).unwrap().predicted_m;
        // B straight below: its path gains the whole bias; A above gains nothing.
        let shadowed = linearise(&p, &s, 0.1).unwrap().predicted_m;
        assert!((shadowed - plain - 0.1).abs() < 1e-12);
    }

    #[test]
    fn receiver_on_a_transmitter_has_no_gradient() {
        assert!(linearise(&Vector3::zeros(), &sample(0.0), 0.0).is_none());
    }
}
