//! The CDA paper, section 3.2, eq. 7-8: gyro offset and noise measured at rest.

/// Running sum, minimum and maximum of gyro readings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RateStats {
    count: u32,
    sum: f64,
    min: f64,
    max: f64,
}

impl RateStats {
    const EMPTY: Self = Self {
        count: 0,
        sum: 0.0,
        min: f64::INFINITY,
        max: f64::NEG_INFINITY,
    };

    fn add(&mut self, rate: f64) {
        self.count += 1;
        self.sum += rate;
        self.min = self.min.min(rate);
        self.max = self.max.max(rate);
    }

    fn merge(&mut self, other: &Self) {
        self.count += other.count;
        self.sum += other.sum;
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }
}

/// Gyro offset and noise from samples at rest (eq. 7-8). The maximum
/// deviation from the mean is `max(max - mean, mean - min)`, so no sample
/// needs to be stored. A reading counts as "at rest" only once the encoder
/// step that covers it and the step after it both report no motion (a guard
/// band: a single reading taken as the robot starts to turn would otherwise
/// enter eq. 8's maximum and widen the dead band to the turn rate itself).
/// Readings wait in `pending` and `guarded` until then, and are dropped if
/// the robot moved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GyroCalibration {
    at_rest: RateStats,
    guarded: RateStats,
    pending: RateStats,
    pub(crate) result: Option<(f64, f64)>,
}

impl GyroCalibration {
    pub(crate) fn new() -> Self {
        Self {
            at_rest: RateStats::EMPTY,
            guarded: RateStats::EMPTY,
            pending: RateStats::EMPTY,
            result: None,
        }
    }

    pub(crate) fn add(&mut self, rate: f64) {
        self.pending.add(rate);
    }

    /// Called at each encoder step with whether the robot stood still.
    pub(crate) fn encoder_step(&mut self, still: bool, target: u32) {
        if self.result.is_some() {
            return;
        }
        if still {
            let guarded = self.guarded;
            self.at_rest.merge(&guarded);
            self.guarded = self.pending;
            if self.at_rest.count >= target {
                self.close();
            }
        } else {
            self.guarded = RateStats::EMPTY;
            self.close();
        }
        self.pending = RateStats::EMPTY;
    }

    /// Offset (eq. 7) and noise (eq. 8), fixed from now on.
    pub(crate) fn close(&mut self) -> (f64, f64) {
        *self.result.get_or_insert_with(|| {
            let s = &self.at_rest;
            if s.count == 0 {
                return (0.0, 0.0);
            }
            let offset = s.sum / f64::from(s.count);
            (offset, (s.max - offset).max(offset - s.min))
        })
    }
}
