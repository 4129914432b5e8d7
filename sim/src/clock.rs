//! Device clocks with an offset and a drift against true time.

use ickon_proto::time::Time;

/// A free-running device clock: `local = true * (1 + drift) + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceClock {
    /// Offset at true time zero, seconds.
    pub offset_s: f64,
    /// Drift, a fraction (1e-6 = 1 ppm).
    pub drift: f64,
}

impl DeviceClock {
    /// A perfect clock.
    pub const PERFECT: DeviceClock = DeviceClock {
        offset_s: 0.0,
        drift: 0.0,
    };

    /// What the clock reads at true time `t_s`, seconds.
    pub fn local_s(&self, t_s: f64) -> f64 {
        t_s * (1.0 + self.drift) + self.offset_s
    }

    /// The true time at which the clock reads `local_s`.
    pub fn true_s(&self, local_s: f64) -> f64 {
        (local_s - self.offset_s) / (1.0 + self.drift)
    }

    /// What the clock reads at true time `t_s`, as a [`Time`] on its base.
    pub fn stamp(&self, t_s: f64) -> Time {
        Time::from_secs_f64(self.local_s(t_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn true_time_inverts_local_time() {
        let c = DeviceClock {
            offset_s: 0.05,
            drift: 20e-6,
        };
        let t = 1234.5678;
        assert!((c.true_s(c.local_s(t)) - t).abs() < 1e-9);
        assert!((c.local_s(1000.0) - 1000.0 - 0.05 - 0.02).abs() < 1e-9);
    }
}
