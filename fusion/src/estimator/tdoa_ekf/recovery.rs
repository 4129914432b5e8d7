//! Getting a lost filter back. A filter that has drifted away (after a
//! burst of outliers it let in, or a long gap) sees most good measurements
//! fail its gate, and those it still accepts happen to agree with the wrong
//! position; left alone it stays lost. So the share of gate rejections is
//! watched over the last measurements, and when it exceeds a threshold the
//! caller widens the position variance, which reopens the gate to the
//! consistent measurements while a single outlier still fails it. A healthy
//! filter rejects a few per cent (the outliers), far below the threshold.

/// When to widen, and by how much.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RecoveryParams {
    /// Number of gated measurements the rejection share is averaged over
    /// (exponential forgetting with this time constant).
    pub window: u32,
    /// Share of gate rejections in that window above which the filter
    /// counts as lost, in `(0, 1)`.
    pub rejected_share: f64,
    /// Standard deviation added to each position axis when lost, metres.
    pub sigma_m: f64,
}

impl Default for RecoveryParams {
    fn default() -> Self {
        Self {
            window: 50,
            rejected_share: 0.5,
            sigma_m: 0.3,
        }
    }
}

impl RecoveryParams {
    /// Checks the domain; `Err((field, reason))`.
    pub(crate) fn check(&self) -> Result<(), (&'static str, &'static str)> {
        if self.window == 0 {
            return Err(("recovery.window", "must be at least 1"));
        }
        if !(self.rejected_share > 0.0 && self.rejected_share < 1.0) {
            return Err(("recovery.rejected_share", "must be within (0, 1)"));
        }
        if !(self.sigma_m.is_finite() && self.sigma_m > 0.0) {
            return Err(("recovery.sigma_m", "must be finite and positive"));
        }
        Ok(())
    }
}

/// The running share of gate rejections.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct RejectionWatch {
    share: f64,
    seen: u32,
}

impl RejectionWatch {
    /// Notes one gated measurement; returns `true` when the filter should
    /// widen its position variance (and starts watching afresh).
    pub fn note(&mut self, rejected: bool, params: &RecoveryParams) -> bool {
        let alpha = 1.0 / f64::from(params.window.max(1));
        self.share += alpha * (f64::from(u8::from(rejected)) - self.share);
        self.seen = self.seen.saturating_add(1);
        if self.seen >= params.window && self.share > params.rejected_share {
            *self = Self::default();
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scattered_rejections_never_trigger_and_a_run_of_them_does() {
        let params = RecoveryParams::default();
        let mut w = RejectionWatch::default();
        // One in five rejected, for a long time: healthy.
        assert!(!(0..10_000).any(|k| w.note(k % 5 == 0, &params)));
        // Then everything rejected: lost within about a window.
        let after = (1..=200).find(|_| w.note(true, &params)).unwrap();
        assert!((20..=60).contains(&after), "{after}");
    }
}
