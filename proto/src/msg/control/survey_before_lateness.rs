//! `central/survey` as it was published before each transmitter carried its
//! lateness (`late_m`, `late_sigma_m`): central units of that time send it,
//! and recordings made then hold it. Read as a calibration that corrects no
//! lateness, which is what an MSU of that time applied, so that such a
//! central unit still calibrates a newer fleet and such a recording replays
//! with its calibration.

use serde::{Deserialize, Serialize};

use super::TransmitterOffset;
use super::survey_older::OlderCalibration;

/// One transmitter's correction, without the lateness (the fields mean
/// what [`TransmitterOffset`]'s of the same name do).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffsetWithoutLateness {
    /// Transmitter id.
    pub tx_id: u32,
    /// What to add to its surveyed position (x, y, z), metres.
    pub offset_m: [f64; 3],
    /// One-sigma uncertainty of each corrected coordinate, metres.
    pub sigma_m: [f64; 3],
}

/// The calibration, without the lateness (see [`OlderCalibration`]).
pub type CalibrationWithoutLateness = OlderCalibration<OffsetWithoutLateness>;

impl From<OffsetWithoutLateness> for TransmitterOffset {
    fn from(o: OffsetWithoutLateness) -> Self {
        TransmitterOffset {
            tx_id: o.tx_id,
            offset_m: o.offset_m,
            sigma_m: o.sigma_m,
            late_m: 0.0,
            late_sigma_m: 0.0,
            left_out: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{DecodeError, decode, encode};
    use crate::msg::control::SurveyCalibration;

    fn old(offsets: usize) -> CalibrationWithoutLateness {
        CalibrationWithoutLateness {
            epoch: 7,
            version: 3,
            fixes_taken: 1200,
            offsets: (0..offsets as u32)
                .map(|k| OffsetWithoutLateness {
                    tx_id: 10 + k,
                    offset_m: [0.01 * f64::from(k), -0.02, 0.005],
                    sigma_m: [0.004, 0.005, 0.012],
                })
                .collect(),
        }
    }

    #[test]
    fn the_layout_before_lateness_is_read_with_no_lateness() {
        let payload = encode(&old(4)).unwrap();
        assert!(
            decode::<SurveyCalibration>(&payload).is_err(),
            "the current layout alone must not read it (else the fallback is never taken)"
        );
        let read = SurveyCalibration::decode(&payload).unwrap();
        assert_eq!((read.epoch, read.version, read.fixes_taken), (7, 3, 1200));
        assert_eq!(read.offsets.len(), 4);
        for (k, o) in read.offsets.iter().enumerate() {
            let was = &old(4).offsets[k];
            assert_eq!(
                (o.tx_id, o.offset_m, o.sigma_m),
                (was.tx_id, was.offset_m, was.sigma_m)
            );
            assert_eq!((o.late_m, o.late_sigma_m), (0.0, 0.0));
        }
    }

    #[test]
    fn the_current_layout_is_read_as_it_is_and_never_as_the_older_one() {
        let mut current = SurveyCalibration::from(old(3));
        current.offsets[1].late_m = 0.012;
        current.offsets[1].late_sigma_m = 0.003;
        let payload = encode(&current).unwrap();
        assert_eq!(SurveyCalibration::decode(&payload).unwrap(), current);
        assert!(decode::<CalibrationWithoutLateness>(&payload).is_err());
    }

    #[test]
    fn a_payload_of_neither_layout_fails_with_the_current_layouts_error() {
        let payload = encode(&old(2)).unwrap();
        let mut longer = payload.clone();
        longer.extend_from_slice(&[0; 8]);
        assert_eq!(
            SurveyCalibration::decode(&longer),
            Err(decode::<SurveyCalibration>(&longer).unwrap_err())
        );
        for cut in [0, 3, 5, 20, payload.len() - 1] {
            assert!(
                SurveyCalibration::decode(&payload[..cut]).is_err(),
                "cut at {cut}"
            );
        }
        assert!(matches!(
            SurveyCalibration::decode(&[0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff]),
            Err(DecodeError::Truncated(_) | DecodeError::Malformed(_))
        ));
    }
}
