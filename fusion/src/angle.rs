//! Angle helpers shared by every heading path.

use std::f64::consts::{PI, TAU};

/// Wraps an angle in radians to `(-pi, pi]`.
///
/// Non-finite input is returned unchanged so that callers can detect it.
pub fn wrap_pi(angle_rad: f64) -> f64 {
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    let wrapped = (angle_rad + PI).rem_euclid(TAU) - PI;
    // rem_euclid maps +pi to -pi; keep +pi so the interval is (-pi, pi].
    if wrapped <= -PI {
        wrapped + TAU
    } else {
        wrapped
    }
}

/// Re-expresses `measured_rad` by whole turns so that it lies within half a
/// turn of `reference_rad` (the ICKON paper: "the MSU heading re-expressed by
/// +-360 deg towards the prediction").
pub fn unwrap_towards(measured_rad: f64, reference_rad: f64) -> f64 {
    reference_rad + wrap_pi(measured_rad - reference_rad)
}

/// Signed smallest difference `a - b`, wrapped to `(-pi, pi]`.
pub fn diff(a_rad: f64, b_rad: f64) -> f64 {
    wrap_pi(a_rad - b_rad)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_keeps_interval_half_open() {
        assert!((wrap_pi(PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(-PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(0.5 + 10.0 * TAU) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn unwrap_moves_measurement_next_to_reference() {
        let reference = 10.0 * TAU + 3.0;
        let measured = -3.0;
        let unwrapped = unwrap_towards(measured, reference);
        assert!((unwrapped - reference).abs() <= PI);
        assert!((wrap_pi(unwrapped) - wrap_pi(measured)).abs() < 1e-9);
    }
}
