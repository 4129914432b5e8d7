//! The speed of sound in air, from the temperature.

/// A temperature or speed of sound outside the physical range.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SoundError {
    /// At or below absolute zero, or not a number.
    #[error("temperature {0} degC is not above absolute zero")]
    BadTemperature(f64),
    /// A speed of sound that is not positive and finite.
    #[error("speed of sound {0} m/s is not positive and finite")]
    BadSpeed(f64),
}

/// Absolute zero in degrees Celsius.
const ABSOLUTE_ZERO_C: f64 = -273.15;

/// Speed of sound in dry air, `331.3 sqrt(1 + T / 273.15)` m/s, with `T`
/// in degrees Celsius (343.2 m/s at 20 degC).
pub fn speed_of_sound_m_s(temperature_c: f64) -> Result<f64, SoundError> {
    if !(temperature_c > ABSOLUTE_ZERO_C && temperature_c.is_finite()) {
        return Err(SoundError::BadTemperature(temperature_c));
    }
    Ok(331.3 * (1.0 + temperature_c / 273.15).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tdoa::Signal;
    use nalgebra::Vector3;

    #[test]
    fn speed_of_sound_follows_the_temperature() {
        assert!((speed_of_sound_m_s(0.0).unwrap() - 331.3).abs() < 1e-12);
        assert!((speed_of_sound_m_s(20.0).unwrap() - 343.21).abs() < 0.01);
        assert!(speed_of_sound_m_s(30.0).unwrap() > speed_of_sound_m_s(10.0).unwrap());
    }

    #[test]
    fn rejects_temperatures_at_or_below_absolute_zero() {
        for t in [-273.15, -300.0, f64::NAN, f64::INFINITY] {
            assert!(speed_of_sound_m_s(t).is_err(), "{t}");
        }
    }

    #[test]
    fn signal_from_times_rejects_non_positive_speed_of_sound() {
        let tx = Vector3::new(1.0, 2.0, 3.0);
        for c in [0.0, -343.0, f64::NAN] {
            assert!(matches!(
                Signal::from_times(1, tx, 0.01, 0.0, c),
                Err(SoundError::BadSpeed(_))
            ));
        }
        let s = Signal::from_times(1, tx, 0.060, 0.050, 340.0).unwrap();
        assert!((s.pseudo_range_m - 3.4).abs() < 1e-12);
    }
}
