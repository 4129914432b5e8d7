//! The sync slave: estimates this cell's clock against the master from
//! NTP-style four-timestamp exchanges.
//!
//! Each exchange gives `t1` (request leaves, local), `t2` (arrives, master),
//! `t3` (reply leaves, master), `t4` (reply arrives, local); the offset
//! `master - local` is `((t2 - t1) + (t3 - t4)) / 2`, wrong by at most half
//! the round-trip asymmetry, and the delay is `(t4 - t1) - (t3 - t2)`. Only
//! the samples with the smallest delays of a sliding window are trusted
//! (queueing only ever adds delay), and a straight line through them,
//! `offset(local) = a + b (local - t_ref)`, gives offset and drift.

use std::collections::VecDeque;

use ickon_proto::time::Time;

/// One four-timestamp exchange.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockSample {
    /// Request sent, local clock.
    pub t1: Time,
    /// Request received, master clock.
    pub t2: Time,
    /// Reply sent, master clock.
    pub t3: Time,
    /// Reply received, local clock.
    pub t4: Time,
}

impl ClockSample {
    /// `master - local` at the middle of the exchange, nanoseconds.
    pub fn offset_ns(&self) -> f64 {
        ((self.t2.as_nanos() - self.t1.as_nanos()) + (self.t3.as_nanos() - self.t4.as_nanos()))
            as f64
            / 2.0
    }

    /// Round-trip delay without the master's processing time, nanoseconds.
    pub fn delay_ns(&self) -> f64 {
        ((self.t4.as_nanos() - self.t1.as_nanos()) - (self.t3.as_nanos() - self.t2.as_nanos()))
            as f64
    }

    /// The local time at the middle of the exchange.
    pub fn local_mid(&self) -> Time {
        Time::from_nanos(self.t1.as_nanos() + (self.t4.as_nanos() - self.t1.as_nanos()) / 2)
    }
}

/// The current estimate of the local clock against the master.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyncEstimate {
    /// Local time the fit is centred on.
    pub reference: Time,
    /// `master - local` at `reference`, nanoseconds.
    pub offset_ns: f64,
    /// Rate of change of the offset (master runs faster by this), seconds per second.
    pub drift: f64,
    /// One-sigma uncertainty of the offset, nanoseconds.
    pub sigma_ns: f64,
    /// Samples behind the estimate.
    pub samples: usize,
}

impl SyncEstimate {
    /// The master time at local time `local`.
    pub fn to_master(&self, local: Time) -> Time {
        let dt = (local.as_nanos() - self.reference.as_nanos()) as f64;
        Time::from_nanos(local.as_nanos() + (self.offset_ns + self.drift * dt).round() as i64)
    }

    /// The local time at master time `master` (inverse of [`to_master`](Self::to_master)).
    pub fn to_local(&self, master: Time) -> Time {
        // master = local + a + b (local - r)  =>  local = (master - a + b r) / (1 + b)
        let m = master.as_nanos() as f64;
        let r = self.reference.as_nanos() as f64;
        let local = (m - self.offset_ns + self.drift * r) / (1.0 + self.drift);
        Time::from_nanos(local.round() as i64)
    }
}

/// Tuning of the sync slave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyncConfig {
    /// Samples kept.
    pub window: usize,
    /// Of those, the ones with the smallest delay used for the fit.
    pub best: usize,
    /// Drift is fitted only over at least this span of local time, seconds.
    pub min_drift_span_s: f64,
}

impl Default for SyncConfig {
    fn default() -> Self {
        Self {
            window: 40,
            best: 12,
            min_drift_span_s: 1.0,
        }
    }
}

/// The sync slave state.
#[derive(Debug, Clone, Default)]
pub struct SyncSlave {
    config: SyncConfig,
    samples: VecDeque<ClockSample>,
}

impl SyncSlave {
    /// A slave with no samples yet.
    pub fn new(config: SyncConfig) -> Self {
        Self {
            config,
            samples: VecDeque::new(),
        }
    }

    /// Adds an exchange; exchanges with a negative delay (clock stepped, or a
    /// reply to an old request) are discarded and reported `false`.
    pub fn add(&mut self, s: ClockSample) -> bool {
        if s.delay_ns() < 0.0 {
            return false;
        }
        if self.samples.len() == self.config.window.max(2) {
            self.samples.pop_front();
        }
        self.samples.push_back(s);
        true
    }

    /// The estimate from the best samples, or `None` before the first one.
    pub fn estimate(&self) -> Option<SyncEstimate> {
        let mut best: Vec<&ClockSample> = self.samples.iter().collect();
        best.sort_by(|a, b| a.delay_ns().total_cmp(&b.delay_ns()));
        best.truncate(self.config.best.max(1));
        let first = *best.first()?;
        let n = best.len() as f64;
        let reference = Time::from_nanos(
            (best
                .iter()
                .map(|s| s.local_mid().as_nanos() as f64)
                .sum::<f64>()
                / n)
                .round() as i64,
        );
        let xs: Vec<f64> = best
            .iter()
            .map(|s| (s.local_mid().as_nanos() - reference.as_nanos()) as f64)
            .collect();
        let ys: Vec<f64> = best.iter().map(|s| s.offset_ns()).collect();
        let mean_y = ys.iter().sum::<f64>() / n;
        let sxx: f64 = xs.iter().map(|x| x * x).sum();
        let span_s = (xs.iter().copied().fold(f64::MIN, f64::max)
            - xs.iter().copied().fold(f64::MAX, f64::min))
            / 1e9;
        let drift = if best.len() >= 3 && span_s >= self.config.min_drift_span_s && sxx > 0.0 {
            xs.iter()
                .zip(&ys)
                .map(|(x, y)| x * (y - mean_y))
                .sum::<f64>()
                / sxx
        } else {
            0.0
        };
        let residual_var = xs
            .iter()
            .zip(&ys)
            .map(|(x, y)| (y - mean_y - drift * x).powi(2))
            .sum::<f64>()
            / n;
        // The asymmetry of the best exchange bounds what the fit cannot see.
        let sigma_ns = (residual_var / n).sqrt().max(first.delay_ns() / 4.0);
        Some(SyncEstimate {
            reference,
            offset_ns: mean_y,
            drift,
            sigma_ns,
            samples: best.len(),
        })
    }

    /// Number of samples kept.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether no sample was kept yet.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A local clock `offset` ahead of the master and drifting, exchanges with
    /// symmetric delays plus some queueing on one side.
    fn exchange(
        master_s: f64,
        offset_ns: f64,
        drift: f64,
        out_ns: f64,
        back_ns: f64,
    ) -> ClockSample {
        let local = |m: f64| m + offset_ns + drift * m;
        let m1 = master_s * 1e9;
        let m2 = m1 + out_ns;
        let m3 = m2 + 20_000.0;
        let m4 = m3 + back_ns;
        ClockSample {
            t1: Time::from_nanos(local(m1) as i64),
            t2: Time::from_nanos(m2 as i64),
            t3: Time::from_nanos(m3 as i64),
            t4: Time::from_nanos(local(m4) as i64),
        }
    }

    #[test]
    fn offset_and_drift_are_recovered_from_noisy_exchanges() {
        let mut s = SyncSlave::new(SyncConfig::default());
        let (offset, drift) = (50e6, -100e-6);
        for k in 0..40 {
            let queue = if k % 3 == 0 { 3e6 } else { 0.0 };
            s.add(exchange(
                1_000.0 + k as f64 * 0.5,
                offset,
                drift,
                150_000.0 + queue,
                150_000.0,
            ));
        }
        let e = s.estimate().unwrap();
        // True master time at a local instant, against the estimate.
        let master_s = 1_020.0;
        let local = Time::from_nanos((master_s * 1e9 + offset + drift * master_s * 1e9) as i64);
        let err_ns = e.to_master(local).as_nanos() as f64 - master_s * 1e9;
        assert!(err_ns.abs() < 5_000.0, "error {err_ns} ns");
        assert!((e.drift + drift).abs() < 5e-6, "drift {}", e.drift);
        assert!(e.sigma_ns > 0.0);
        let back = e.to_local(e.to_master(local));
        assert!((back.as_nanos() - local.as_nanos()).abs() <= 1);
    }

    #[test]
    fn impossible_exchanges_are_discarded() {
        let mut s = SyncSlave::new(SyncConfig::default());
        let mut bad = exchange(1.0, 0.0, 0.0, 1000.0, 1000.0);
        bad.t4 = Time::from_nanos(bad.t1.as_nanos() - 1);
        assert!(!s.add(bad));
        assert!(s.estimate().is_none());
    }
}
