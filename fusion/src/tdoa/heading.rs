//! Headings from positioning data: the receiver that heard the first signal
//! (the ICKON paper, eq. 4-6), and two MSUs on one robot (the iGPS paper, eq. 1).
//!
//! Headings are radians counter-clockwise from +x, wrapped to `(-pi, pi]`.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_3};

use nalgebra::Vector2;

use crate::angle;

/// The ICKON paper, eq. 5: six receivers, receiver `i` pointing `i * 60 deg`
/// counter-clockwise from the robot's forward direction.
pub const SEED_RECEIVER_ANGLES_RAD: [f64; 6] = [
    0.0,
    FRAC_PI_3,
    2.0 * FRAC_PI_3,
    3.0 * FRAC_PI_3,
    4.0 * FRAC_PI_3,
    5.0 * FRAC_PI_3,
];

/// Why no heading could be derived.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum HeadingError {
    /// The receiver id has no configured angle.
    #[error("receiver {receiver_id} unknown: {count} receiver angles configured")]
    UnknownReceiver {
        /// The id.
        receiver_id: usize,
        /// How many angles were given.
        count: usize,
    },
    /// A coordinate or angle is NaN or infinite.
    #[error("non-finite {0}")]
    NonFinite(&'static str),
    /// The transmitter is straight above the MSU: no bearing.
    #[error("the transmitter is straight above the MSU: its bearing is undefined")]
    Overhead,
}

/// The ICKON paper, eq. 4-6: heading of the MSU from the receiver that heard the
/// transmitter first. `beta = atan2(x_t - x_g, y_t - y_g)` is the bearing
/// of the transmitter clockwise from +y, `alpha` the receiver's angle, and
/// `gamma = 90 deg - (alpha + beta)`. The receivers are `360 / n` degrees
/// apart, so the result is only good to half that (+-30 deg with six).
pub fn heading_from_first_receiver(
    tx_xy_m: Vector2<f64>,
    msu_xy_m: Vector2<f64>,
    receiver_id: usize,
    receiver_angles_rad: &[f64],
) -> Result<f64, HeadingError> {
    let alpha = *receiver_angles_rad
        .get(receiver_id)
        .ok_or(HeadingError::UnknownReceiver {
            receiver_id,
            count: receiver_angles_rad.len(),
        })?;
    if !alpha.is_finite() {
        return Err(HeadingError::NonFinite("receiver angle"));
    }
    let d = tx_xy_m - msu_xy_m;
    if !d.iter().all(|v| v.is_finite()) {
        return Err(HeadingError::NonFinite("position"));
    }
    if d.x == 0.0 && d.y == 0.0 {
        return Err(HeadingError::Overhead);
    }
    let beta = d.x.atan2(d.y);
    Ok(angle::wrap_pi(FRAC_PI_2 - (alpha + beta)))
}

/// The iGPS paper, eq. 1: heading of a vehicle from the positions of two sensors on
/// it, `theta = atan2(y2 - y1, x2 - x1) + pi/2` (sensor 2 on the right of
/// sensor 1 when looking forward), wrapped to `(-pi, pi]`.
pub fn two_sensor_heading(x1_m: f64, y1_m: f64, x2_m: f64, y2_m: f64) -> f64 {
    angle::wrap_pi((y2_m - y1_m).atan2(x2_m - x1_m) + FRAC_PI_2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn heading(tx: [f64; 2], msu: [f64; 2], receiver: usize) -> f64 {
        heading_from_first_receiver(
            Vector2::from(tx),
            Vector2::from(msu),
            receiver,
            &SEED_RECEIVER_ANGLES_RAD,
        )
        .unwrap()
    }

    #[test]
    fn receiver_zero_facing_the_transmitter_gives_its_bearing() {
        // Transmitter due +x: a robot facing it hears it on receiver 0.
        assert!(heading([5.0, 1.0], [1.0, 1.0], 0).abs() < 1e-12);
        // Transmitter due +y: facing +y is 90 deg.
        assert!((heading([1.0, 5.0], [1.0, 1.0], 0) - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn receiver_angle_is_subtracted_counter_clockwise() {
        // Transmitter due +y heard on receiver 1 (60 deg left of forward):
        // the robot faces 30 deg.
        let h = heading([0.0, 3.0], [0.0, 0.0], 1);
        assert!((h - PI / 6.0).abs() < 1e-12, "{}", h.to_degrees());
    }

    #[test]
    fn heading_wraps_at_plus_minus_180_deg() {
        // Transmitter due -x on receiver 0: facing -x, i.e. +180 deg, and
        // just either side of it the answer stays continuous modulo a turn.
        assert!((heading([-4.0, 0.0], [0.0, 0.0], 0) - PI).abs() < 1e-12);
        let above = heading([-4.0, 1e-6], [0.0, 0.0], 0);
        let below = heading([-4.0, -1e-6], [0.0, 0.0], 0);
        assert!(above > PI - 1e-5 && above <= PI);
        assert!(below < -PI + 1e-5 && below > -PI);
        // Receiver 3 (180 deg) facing away from a transmitter due +x.
        assert!((heading([4.0, 0.0], [0.0, 0.0], 3) - PI).abs() < 1e-12);
        // Every result is in (-pi, pi].
        for i in 0..6 {
            let h = heading([-4.0, -0.3], [0.0, 0.0], i);
            assert!(h > -PI && h <= PI);
        }
    }

    #[test]
    fn receiver_angles_are_a_parameter() {
        let four = [0.0, FRAC_PI_2, PI, -FRAC_PI_2];
        let h = heading_from_first_receiver(Vector2::new(0.0, 3.0), Vector2::zeros(), 1, &four)
            .unwrap();
        assert!(h.abs() < 1e-12);
    }

    #[test]
    fn rejects_unknown_receiver_and_overhead_transmitter() {
        let err = heading_from_first_receiver(
            Vector2::new(1.0, 0.0),
            Vector2::zeros(),
            6,
            &SEED_RECEIVER_ANGLES_RAD,
        );
        assert_eq!(
            err,
            Err(HeadingError::UnknownReceiver {
                receiver_id: 6,
                count: 6
            })
        );
        let p = Vector2::new(2.0, 2.0);
        assert_eq!(
            heading_from_first_receiver(p, p, 0, &SEED_RECEIVER_ANGLES_RAD),
            Err(HeadingError::Overhead)
        );
        assert_eq!(
            heading_from_first_receiver(
                Vector2::new(f64::NAN, 0.0),
                p,
                0,
                &SEED_RECEIVER_ANGLES_RAD
            ),
            Err(HeadingError::NonFinite("position"))
        );
    }

    #[test]
    fn two_sensor_heading_wraps_at_plus_minus_180_deg() {
        // Sensor 2 straight below sensor 1 (on its right when facing -x).
        let h = two_sensor_heading(0.0, 0.0, 0.0, -0.4);
        assert!(h.abs() < 1e-12);
        let h = two_sensor_heading(0.0, 0.0, 1e-9, 0.4);
        assert!((h - PI).abs() < 1e-6 && h <= PI);
        let h = two_sensor_heading(0.0, 0.0, -1e-9, 0.4);
        assert!((h + PI).abs() < 1e-6 && h > -PI);
    }
}
