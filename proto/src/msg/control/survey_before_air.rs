//! `central/survey` as it was published before it carried the learnt
//! speed of sound and which transmitters are left out: read with the
//! site's speed of sound and every transmitter in use, which is what an
//! MSU of that time did.

use serde::{Deserialize, Serialize};

use super::TransmitterOffset;
use super::survey_older::OlderCalibration;

/// One transmitter's correction, without `left_out` (the fields mean what
/// [`TransmitterOffset`]'s of the same name do).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffsetWithoutHealth {
    /// Transmitter id.
    pub tx_id: u32,
    /// What to add to its surveyed position (x, y, z), metres.
    pub offset_m: [f64; 3],
    /// One-sigma uncertainty of each corrected coordinate, metres.
    pub sigma_m: [f64; 3],
    /// How late its bursts arrive, metres of path.
    pub late_m: f64,
    /// One-sigma uncertainty of `late_m`, metres.
    pub late_sigma_m: f64,
}

/// The calibration without the speed of sound (see [`OlderCalibration`]).
pub type CalibrationWithoutAir = OlderCalibration<OffsetWithoutHealth>;

impl From<OffsetWithoutHealth> for TransmitterOffset {
    fn from(o: OffsetWithoutHealth) -> Self {
        TransmitterOffset {
            tx_id: o.tx_id,
            offset_m: o.offset_m,
            sigma_m: o.sigma_m,
            late_m: o.late_m,
            late_sigma_m: o.late_sigma_m,
            left_out: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{decode, encode};
    use crate::msg::control::SurveyCalibration;

    fn old(offsets: usize) -> CalibrationWithoutAir {
        CalibrationWithoutAir {
            epoch: 8,
            version: 5,
            fixes_taken: 900,
            offsets: (0..offsets as u32)
                .map(|k| OffsetWithoutHealth {
                    tx_id: 20 + k,
                    offset_m: [0.01 * f64::from(k), -0.02, 0.005],
                    sigma_m: [0.004, 0.005, 0.012],
                    late_m: 0.003 * f64::from(k),
                    late_sigma_m: 0.002,
                })
                .collect(),
        }
    }

    #[test]
    fn the_layout_before_the_air_is_read_with_the_sites_speed_and_none_left_out() {
        for n in [0, 1, 4, 16] {
            let payload = encode(&old(n)).unwrap();
            if n > 0 {
                assert!(
                    decode::<SurveyCalibration>(&payload).is_err(),
                    "the current layout alone must not read it"
                );
            }
            let read = SurveyCalibration::decode(&payload).unwrap();
            assert_eq!(read, SurveyCalibration::from(old(n)));
            assert_eq!(read.speed_of_sound_or(343.0), 343.0);
            assert!(read.offsets.iter().all(|o| !o.left_out));
        }
    }

    #[test]
    fn the_current_layout_is_never_read_as_the_one_before() {
        let mut current = SurveyCalibration::from(old(3));
        current.offsets[1].left_out = true;
        current.speed_of_sound_m_s = 346.5;
        current.speed_of_sound_sigma_m_s = 0.2;
        let payload = encode(&current).unwrap();
        assert_eq!(SurveyCalibration::decode(&payload).unwrap(), current);
        assert!(decode::<CalibrationWithoutAir>(&payload).is_err());
        assert_eq!(current.speed_of_sound_or(343.0), 346.5);
    }
}
