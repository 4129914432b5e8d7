//! The IMU stream of a flight file screened before it reaches the filter:
//! samples that are not finite, that sit at the sensor's full scale
//! (clipped: the true value is unknown), that go back in time, or that
//! are stamped far ahead of the rest of the stream are dropped and counted
//! by reason, never integrated.

use super::dataset::ImuRow;

/// Full scale of the UTIL vehicle's accelerometer, m/s^2: its IMU (a
/// Bosch BMI088 on the Crazyflie 2.1) is configured to +-24 g; a
/// component at or beyond 99 % of it is clipped.
pub const ACCEL_FULL_SCALE_M_S2: f64 = 24.0 * 9.80665;
/// Full scale of its gyro, rad/s: +-2000 deg/s.
pub const GYRO_FULL_SCALE_RAD_S: f64 = 2000.0 * std::f64::consts::PI / 180.0;
/// Share of the full scale from which a reading counts as clipped.
const CLIPPED_SHARE: f64 = 0.99;
/// A sample this far ahead of its successor is stamped in the future (a
/// clock glitch), seconds: far longer than any gap between IMU samples
/// (1 ms at 1 kHz), short against a flight.
pub const FUTURE_S: f64 = 1.0;

/// Samples dropped, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ImuDropped {
    /// A reading or the time is NaN or infinite.
    pub non_finite: u64,
    /// A reading at the sensor's full scale.
    pub saturated: u64,
    /// Not after the last sample kept.
    pub out_of_order: u64,
    /// Stamped ahead of the stream that follows it.
    pub future: u64,
}

impl ImuDropped {
    /// All of them.
    pub fn total(&self) -> u64 {
        self.non_finite + self.saturated + self.out_of_order + self.future
    }
}

/// Screens `samples` (in file order): the samples to integrate, in time
/// order, and what was dropped (the whole-slice form of [`Screen`]).
#[cfg(test)]
pub fn screen(samples: &[ImuRow]) -> (Vec<ImuRow>, ImuDropped) {
    let mut screen = Screen::default();
    let mut kept: Vec<ImuRow> = Vec::with_capacity(samples.len());
    for s in samples {
        kept.extend(screen.push(*s));
    }
    kept.extend(screen.finish());
    (kept, screen.dropped)
}

/// The screening of a stream one sample at a time: a sample is decided
/// once the next with a finite time is known (to tell one stamped in the
/// future), so at most one is held.
#[derive(Debug, Clone, Default)]
pub struct Screen {
    held: Option<ImuRow>,
    last_kept_s: Option<f64>,
    /// Samples dropped so far, by reason.
    pub dropped: ImuDropped,
    /// Samples read.
    pub read: u64,
    /// Samples kept.
    pub kept: u64,
}

impl Screen {
    /// Takes the next sample in file order; the sample before it, when it
    /// is now known to be kept.
    pub fn push(&mut self, s: ImuRow) -> Option<ImuRow> {
        self.read += 1;
        let mut out = None;
        if s.t_s.is_finite()
            && let Some(h) = self.held.take()
        {
            out = self.decide(h, Some(s.t_s));
        }
        let finite = s.t_s.is_finite()
            && s.accel_m_s2
                .iter()
                .chain(&s.gyro_rad_s)
                .all(|v| v.is_finite());
        if finite {
            self.held = Some(s);
        } else {
            self.dropped.non_finite += 1;
        }
        out
    }

    /// The end of the stream: the last sample, when it is kept.
    pub fn finish(&mut self) -> Option<ImuRow> {
        let h = self.held.take()?;
        self.decide(h, None)
    }

    fn decide(&mut self, s: ImuRow, next_s: Option<f64>) -> Option<ImuRow> {
        if s.accel_m_s2
            .iter()
            .any(|a| a.abs() >= CLIPPED_SHARE * ACCEL_FULL_SCALE_M_S2)
            || s.gyro_rad_s
                .iter()
                .any(|w| w.abs() >= CLIPPED_SHARE * GYRO_FULL_SCALE_RAD_S)
        {
            self.dropped.saturated += 1;
            return None;
        }
        let last_s = self.last_kept_s.unwrap_or(f64::NEG_INFINITY);
        if s.t_s <= last_s {
            self.dropped.out_of_order += 1;
            return None;
        }
        // Ahead of the next sample by more than any gap, while that one
        // still follows the stream kept so far: this one is the odd one
        // out, not all those after it.
        if next_s.is_some_and(|n| s.t_s > n + FUTURE_S && n > last_s) {
            self.dropped.future += 1;
            return None;
        }
        self.last_kept_s = Some(s.t_s);
        self.kept += 1;
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t_s: f64) -> ImuRow {
        ImuRow {
            t_s,
            accel_m_s2: [0.1, -0.2, 9.8],
            gyro_rad_s: [0.01, 0.0, -0.02],
        }
    }

    #[test]
    fn a_clean_stream_passes_untouched() {
        let s: Vec<ImuRow> = (0..100).map(|k| at(f64::from(k) * 0.001)).collect();
        let (kept, dropped) = screen(&s);
        assert_eq!(kept, s);
        assert_eq!(dropped, ImuDropped::default());
    }

    #[test]
    fn each_bad_sample_is_dropped_and_counted_for_its_reason() {
        let mut s: Vec<ImuRow> = (0..20).map(|k| at(f64::from(k) * 0.001)).collect();
        s[3].accel_m_s2[1] = f64::NAN;
        s[5].t_s = f64::INFINITY;
        s[7].gyro_rad_s[2] = 40.0;
        s[9].accel_m_s2[2] = -240.0;
        // Out of order: stamped before its predecessor.
        s[11].t_s = 0.0095;
        // From the future: a minute ahead of the rest.
        s[14].t_s = 60.0;
        let (kept, dropped) = screen(&s);
        assert_eq!(
            dropped,
            ImuDropped {
                non_finite: 2,
                saturated: 2,
                out_of_order: 1,
                future: 1,
            }
        );
        assert_eq!(kept.len(), 20 - 6);
        assert!(kept.windows(2).all(|w| w[0].t_s < w[1].t_s));
        assert!(kept.iter().all(|k| k.t_s < 0.02));
    }

    #[test]
    fn a_stream_that_restarts_far_back_keeps_its_first_part() {
        // The clock set back by 10 s: the later samples go back in time;
        // the filter is not fed a second copy of the same seconds.
        let mut s: Vec<ImuRow> = (0..10).map(|k| at(20.0 + f64::from(k) * 0.001)).collect();
        s.extend((0..10).map(|k| at(10.0 + f64::from(k) * 0.001)));
        let (kept, dropped) = screen(&s);
        assert_eq!(kept.len(), 10);
        assert_eq!(dropped.out_of_order, 10);
        assert_eq!(dropped.future, 0);
    }
}
