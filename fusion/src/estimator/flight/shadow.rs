//! The range-difference observation of a receiver carried by a body:
//! `h = |p - b| - |p - a| + s (g(b) - g(a))`, with `g(c) = max(0, (p_z -
//! c_z) / |p - c|)` the sine of the depression angle of transmitter `c`
//! seen from the antenna. A signal from below the antenna crosses the body
//! carrying it and arrives late by up to `s` (the body's extra path at a
//! 90 degree depression). `s` is a state, estimated online from its own
//! geometric signature (only pairs with one transmitter below the antenna
//! see it), not a constant sized on any flight.

use nalgebra::Vector3;

use crate::estimator::RangeDifferenceSample;

/// Closer than this to a transmitter the gradient is not defined, metres.
const MIN_DISTANCE_M: f64 = 1e-6;

/// `h` at the linearisation point and its derivatives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Linearised {
    /// Predicted range difference, metres.
    pub predicted_m: f64,
    /// `dh/dp` (the shadow term's own gradient, a few per cent of the
    /// geometric one, is left out).
    pub gradient: Vector3<f64>,
    /// `dh/ds`: `g(b) - g(a)`.
    pub d_shadow: f64,
}

/// Linearises at antenna position `p` with shadow `s`; `None` when `p`
/// sits on a transmitter.
pub(crate) fn linearise(
    p: &Vector3<f64>,
    m: &RangeDifferenceSample,
    shadow_m: f64,
) -> Option<Linearised> {
    let (ra, rb) = (p - Vector3::from(m.a_m), p - Vector3::from(m.b_m));
    let (da, db) = (ra.norm(), rb.norm());
    if da < MIN_DISTANCE_M || db < MIN_DISTANCE_M {
        return None;
    }
    let g = |r: &Vector3<f64>, d: f64| (r.z / d).max(0.0);
    let d_shadow = g(&rb, db) - g(&ra, da);
    Some(Linearised {
        predicted_m: db - da + shadow_m * d_shadow,
        gradient: rb / db - ra / da,
        d_shadow,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_transmitter_below_lengthens_its_path() {
        let m = RangeDifferenceSample {
            a_t_s: None,
            t_s: 0.0,
            a_m: [0.0, 0.0, 3.0],
            b_m: [0.0, 0.0, 0.0],
            d_m: 0.0,
            sigma_m: 0.1,
            clocks: None,
            speed_rel_sigma: None,
        };
        let p = Vector3::new(0.0, 0.0, 1.0);
        let l = linearise(&p, &m, 0.1).unwrap();
        // |p - b| - |p - a| = 1 - 2, plus the whole shadow on B.
        assert!((l.predicted_m - (-1.0 + 0.1)).abs() < 1e-12);
        assert_eq!(l.d_shadow, 1.0);
        assert!(linearise(&Vector3::zeros(), &m, 0.1).is_none());
    }
}
