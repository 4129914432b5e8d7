//! The sync slave: estimates this cell's clock against the master from
//! NTP-style four-timestamp exchanges.
//!
//! Each exchange gives `t1` (request leaves, local), `t2` (arrives, master),
//! `t3` (reply leaves, master), `t4` (reply arrives, local); the offset
//! `master - local` is `((t2 - t1) + (t3 - t4)) / 2`, wrong by at most half
//! the round-trip asymmetry, and the delay is `(t4 - t1) - (t3 - t2)`.
//! Queueing only ever adds delay, so the exchanges with the smallest delay
//! are the most trustworthy.
//!
//! The time the window of kept exchanges spans is cut into
//! [`SyncConfig::buckets`] equal stretches, and the exchange with the
//! smallest delay of each is kept: the fit sees good samples spread evenly
//! over the window (even while fast start-up exchanges still fill most of
//! it) rather than the best ones bunched in one quiet moment, which would
//! make the drift, and every extrapolation, fragile. A straight line through them,
//! `offset(local) = a + b (local - t_ref)`, gives offset and drift.
//!
//! The request does not leave at `t1`: Zenoh takes it some time after the
//! call (a few tens to hundreds of microseconds on a busy machine), and
//! counted whole that time makes the outward leg look longer than the way
//! back. Each exchange notes when Zenoh had taken it
//! ([`ClockSample::queued_ns`]), and `t1` is moved by half the **median** of
//! those times over the window, not by the exchange's own: a task that
//! stalls after its request has left but before it notes the time would
//! otherwise move `t1` past the moment the request left, shrinking the
//! delay of exactly that exchange, which the fit then trusts most (seen on
//! a loaded machine: the exchanges with the smallest delays were 60 us
//! early on average, and bursts fired 200 us early).
//!
//! The fitted line weighs each exchange by the inverse square of its delay
//! (half the delay bounds an exchange's error), and its drift has a prior,
//! zero give or take [`SyncConfig::drift_bound`]. On a 2-core machine
//! running 64 robots (exchanges delayed 4-6.5 ms at the median), cells
//! went 14 s without an exchange under 1.5 ms: replayed offline from two
//! runs' exchanges, the worst error after 8 s was 1.6 / 5.6 ms with an
//! unweighted fit, 0.87 / 3.6 ms weighted, 0.77 / 1.8 ms with the prior.
//!
//! Before the exchanges span [`SyncConfig::min_drift_span_s`] the drift is
//! unknown: the offset then comes from the one exchange with the smallest
//! error bound, half its delay plus [`SyncConfig::drift_bound`] times its
//! age, so that newer exchanges are preferred unless they were stalled.

use std::collections::VecDeque;

use ickon_proto::time::{Duration, Time};

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
    /// The epoch of the central unit that answered.
    pub epoch: u64,
    /// How long after `t1` Zenoh had taken the request, on the local clock,
    /// nanoseconds (0 when unknown). See the module's documentation.
    pub queued_ns: i64,
}

impl ClockSample {
    /// `master - local` at the middle of the exchange, nanoseconds.
    /// (In i128: the master's stamps come from the network and may be
    /// anything; a nonsense offset is refused by the filter, not a panic.)
    pub fn offset_ns(&self) -> f64 {
        let [t1, t2, t3, t4] = self.stamps();
        ((t2 - t1) + (t3 - t4)) as f64 / 2.0
    }

    /// Round-trip delay without the master's processing time, nanoseconds.
    pub fn delay_ns(&self) -> f64 {
        let [t1, t2, t3, t4] = self.stamps();
        ((t4 - t1) - (t3 - t2)) as f64
    }

    /// The local time at the middle of the exchange.
    pub fn local_mid(&self) -> Time {
        let [t1, _, _, t4] = self.stamps();
        Time::from_nanos(i64::try_from(t1 + (t4 - t1) / 2).unwrap_or(i64::MAX))
    }

    fn stamps(&self) -> [i128; 4] {
        [self.t1, self.t2, self.t3, self.t4].map(|t| i128::from(t.as_nanos()))
    }

    /// The exchange with `t1` moved `ns` later (saturating).
    fn sent_later_by(&self, ns: i64) -> Self {
        Self {
            t1: Time::from_nanos(self.t1.as_nanos().saturating_add(ns)),
            ..*self
        }
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
        // Saturating: a local clock that jumped to the ends of time gives
        // the ends of time, not an overflow.
        let dt = (i128::from(local.as_nanos()) - i128::from(self.reference.as_nanos())) as f64;
        local + Duration::from_nanos((self.offset_ns + self.drift * dt).round() as i64)
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
    /// Exchanges kept.
    pub window: usize,
    /// Stretches of time the window is cut into; the best exchange of each is fitted.
    pub buckets: usize,
    /// Drift is fitted only over at least this span of local time, seconds.
    pub min_drift_span_s: f64,
    /// Before that, the drift assumed at most (seconds per second) when
    /// weighing an older exchange against a newer one; after, the
    /// standard deviation of the drift's prior.
    pub drift_bound: f64,
    /// No estimate before this many exchanges.
    pub min_samples: usize,
}

impl Default for SyncConfig {
    fn default() -> Self {
        Self {
            window: 100,
            buckets: 12,
            min_drift_span_s: 1.5,
            drift_bound: 200e-6,
            min_samples: 3,
        }
    }
}

/// The sync slave state.
#[derive(Debug, Clone, Default)]
pub struct SyncSlave {
    config: SyncConfig,
    samples: VecDeque<ClockSample>,
}

/// The exchange with the smallest delay; of equals the newest (the least drift since).
fn min_delay<'a>(samples: impl IntoIterator<Item = &'a ClockSample>) -> Option<&'a ClockSample> {
    samples.into_iter().fold(None, |best, s| match best {
        Some(b) if b.delay_ns() < s.delay_ns() => Some(b),
        _ => Some(s),
    })
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
        if self.samples.len() >= self.config.window.max(2) {
            self.samples.pop_front();
        }
        self.samples.push_back(s);
        true
    }

    /// How long after `t1` the requests of the window typically left: half
    /// the median time Zenoh took to take them (see the module's
    /// documentation for why the median), nanoseconds.
    pub fn typical_send_delay_ns(&self) -> i64 {
        let mut queued: Vec<i64> = self.samples.iter().map(|s| s.queued_ns.max(0)).collect();
        if queued.is_empty() {
            return 0;
        }
        let mid = queued.len() / 2;
        *queued.select_nth_unstable(mid).1 / 2
    }

    /// `s` with its `t1` moved to when its request typically left: the
    /// exchange as the estimate uses it (and as a caller comparing an
    /// exchange with the estimate should).
    pub fn adjusted(&self, s: &ClockSample) -> ClockSample {
        s.sent_later_by(self.typical_send_delay_ns())
    }

    /// Every exchange of the window, [`adjusted`](Self::adjusted).
    fn adjusted_window(&self) -> Vec<ClockSample> {
        let send_delay_ns = self.typical_send_delay_ns();
        self.samples
            .iter()
            .map(|s| s.sent_later_by(send_delay_ns))
            .collect()
    }

    /// The exchanges the fit uses, adjusted: the best of each equal
    /// stretch of time of the window (stretches without an exchange give
    /// none).
    fn fitted(&self) -> Vec<ClockSample> {
        let window = self.adjusted_window();
        let buckets = self.config.buckets.max(1);
        let (Some(first), Some(last)) = (window.first(), window.last()) else {
            return Vec::new();
        };
        // In i128: a local clock that jumped across the window spans more than i64.
        let t0 = i128::from(first.local_mid().as_nanos());
        let span = (i128::from(last.local_mid().as_nanos()) - t0).max(1) as f64;
        let mut best: Vec<Option<&ClockSample>> = vec![None; buckets];
        for s in &window {
            let at = (i128::from(s.local_mid().as_nanos()) - t0) as f64 / span;
            let k = ((at * buckets as f64) as usize).min(buckets - 1);
            best[k] = min_delay(best[k].into_iter().chain(std::iter::once(s)));
        }
        best.into_iter().flatten().copied().collect()
    }

    /// The estimate, or `None` before [`SyncConfig::min_samples`] exchanges.
    pub fn estimate(&self) -> Option<SyncEstimate> {
        if self.samples.len() < self.config.min_samples.max(1) {
            return None;
        }
        let span_s = match (self.samples.front(), self.samples.back()) {
            (Some(a), Some(b)) => b.local_mid().since(a.local_mid()).as_secs_f64(),
            _ => return None,
        };
        if span_s < self.config.min_drift_span_s {
            // An exchange's error is at most half its delay, plus what an
            // unknown drift adds since: the best bound wins, so a stall
            // that delays every recent exchange keeps an older good one.
            let adjusted = self.adjusted_window();
            let newest = adjusted.last()?.local_mid();
            let bound = |s: &ClockSample| {
                s.delay_ns().max(0.0) / 2.0
                    + self.config.drift_bound * newest.since(s.local_mid()).as_nanos() as f64
            };
            let best = adjusted
                .iter()
                .min_by(|a, b| bound(a).total_cmp(&bound(b)))?;
            return Some(SyncEstimate {
                reference: best.local_mid(),
                offset_ns: best.offset_ns(),
                drift: 0.0,
                sigma_ns: bound(best),
                samples: 1,
            });
        }
        let mut fitted = self.fitted();
        // A stretch in which every exchange was stalled gives a poor best:
        // keep the bests within twice the median delay of all of them.
        let mut delays: Vec<f64> = fitted.iter().map(|s| s.delay_ns()).collect();
        delays.sort_by(f64::total_cmp);
        // (At least the median: adjusted delays can be negative.)
        let median = delays[delays.len() / 2];
        let limit = (2.0 * median).max(median);
        fitted.retain(|s| s.delay_ns() <= limit);
        // Weights: the inverse square of each exchange's error bound, half
        // its delay (1 us at least: an adjusted delay can reach zero).
        let weights: Vec<f64> = fitted
            .iter()
            .map(|s| (s.delay_ns() / 2.0).max(1_000.0).powi(-2))
            .collect();
        let weight_sum: f64 = weights.iter().sum();
        // Centred on the weighted mean time, summed from the first exchange
        // (local times in f64 would lose a few hundred nanoseconds).
        let first = fitted.first()?.local_mid();
        let centre_ns = fitted
            .iter()
            .zip(&weights)
            .map(|(s, w)| {
                w * (i128::from(s.local_mid().as_nanos()) - i128::from(first.as_nanos())) as f64
            })
            .sum::<f64>()
            / weight_sum;
        let reference = Time::from_nanos(first.as_nanos().saturating_add(centre_ns.round() as i64));
        let xs: Vec<f64> = fitted
            .iter()
            .map(|s| {
                (i128::from(s.local_mid().as_nanos()) - i128::from(reference.as_nanos())) as f64
            })
            .collect();
        let ys: Vec<f64> = fitted.iter().map(ClockSample::offset_ns).collect();
        let mean_y = ys.iter().zip(&weights).map(|(y, w)| w * y).sum::<f64>() / weight_sum;
        let sxx: f64 = xs.iter().zip(&weights).map(|(x, w)| w * x * x).sum();
        // The drift has a prior: zero, give or take `drift_bound`. Over a
        // short span of poor exchanges (a loaded machine right after a
        // start) the data say little and the drift stays small, instead of
        // a slope through noise that every extrapolation then multiplies.
        // A full window of good exchanges (25 s, delays of 300 us)
        // outweighs it a thousandfold; 4 s of them twentyfold.
        let drift_precision = if self.config.drift_bound > 0.0 {
            self.config.drift_bound.powi(-2)
        } else {
            0.0
        };
        let drift = if fitted.len() >= 3 && sxx > 0.0 {
            xs.iter()
                .zip(&ys)
                .zip(&weights)
                .map(|((x, y), w)| w * x * (y - mean_y))
                .sum::<f64>()
                / (sxx + drift_precision)
        } else {
            0.0
        };
        let residual_var = xs
            .iter()
            .zip(&ys)
            .zip(&weights)
            .map(|((x, y), w)| w * (y - mean_y - drift * x).powi(2))
            .sum::<f64>()
            / weight_sum;
        // The scatter of the fitted exchanges, and at least a quarter of the
        // best round trip: an asymmetry no exchange can see.
        let best_delay = min_delay(&fitted).map_or(0.0, |s| s.delay_ns().max(0.0));
        let sigma_ns = residual_var.sqrt().max(best_delay / 4.0);
        Some(SyncEstimate {
            reference,
            offset_ns: mean_y,
            drift,
            sigma_ns,
            samples: fitted.len(),
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

    /// Found by `fuzz_cell_core`: a clock answer stamped at the ends of
    /// time overflowed the offset (a panic in a debug build); it is now
    /// one more exchange the filter refuses.
    #[test]
    fn a_clock_answer_at_the_ends_of_time_is_refused_not_a_panic() {
        let s = ClockSample {
            t1: Time(1_000),
            t2: Time(i64::MIN),
            t3: Time(i64::MAX),
            t4: Time(2_000),
            epoch: 0,
            queued_ns: 0,
        };
        assert!(s.offset_ns().is_finite() && s.delay_ns().is_finite());
        let mut slave = SyncSlave::new(SyncConfig::default());
        slave.add(s);
        let far = ClockSample {
            t1: Time(i64::MIN),
            t2: Time(i64::MAX),
            t3: Time(i64::MAX),
            t4: Time(i64::MAX),
            epoch: 0,
            queued_ns: 0,
        };
        assert_eq!(far.local_mid(), Time(-1));
        slave.add(far);
        // And a window whose exchanges span the whole of i64 (a local
        // clock jump found by `fuzz_cell_core`).
        for t in [i64::MIN, i64::MAX, i64::MIN] {
            slave.add(ClockSample {
                t1: Time(t),
                t2: Time(0),
                t3: Time(0),
                t4: Time(t),
                epoch: 0,
                queued_ns: 0,
            });
        }
        assert!(slave.estimate().is_none_or(|e| e.offset_ns.is_finite()));
        // A local clock at the ends of time maps to them, saturated.
        let e = SyncEstimate {
            reference: Time(0),
            offset_ns: 5.0,
            drift: 1e-6,
            sigma_ns: 1.0,
            samples: 3,
        };
        assert_eq!(e.to_master(Time(i64::MAX)), Time(i64::MAX));
        assert_eq!(e.to_master(Time(i64::MIN)), Time(i64::MIN));
    }

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
            epoch: 0,
            queued_ns: 0,
        }
    }

    /// Error of `e` in master time at true master instant `master_s`.
    fn error_ns(e: &SyncEstimate, master_s: f64, offset: f64, drift: f64) -> f64 {
        let local = Time::from_nanos((master_s * 1e9 + offset + drift * master_s * 1e9) as i64);
        e.to_master(local).as_nanos() as f64 - master_s * 1e9
    }

    #[test]
    fn offset_and_drift_are_recovered_from_noisy_exchanges() {
        let mut s = SyncSlave::new(SyncConfig::default());
        let (offset, drift) = (50e6, -100e-6);
        for k in 0..60 {
            let queue = if k % 3 == 0 { 3e6 } else { 0.0 };
            s.add(exchange(
                1_000.0 + k as f64 * 0.25,
                offset,
                drift,
                150_000.0 + queue,
                150_000.0,
            ));
        }
        let e = s.estimate().unwrap();
        // Half a second past the newest exchange.
        let err_ns = error_ns(&e, 1_015.25, offset, drift);
        assert!(err_ns.abs() < 5_000.0, "error {err_ns} ns");
        assert!((e.drift + drift).abs() < 2e-6, "drift {}", e.drift);
        assert!(e.sigma_ns > 0.0);
        let local = Time::from_nanos(1_015_000_000_000);
        let back = e.to_local(e.to_master(local));
        assert!((back.as_nanos() - local.as_nanos()).abs() <= 1);
    }

    #[test]
    fn a_quiet_moment_does_not_carry_the_whole_fit() {
        // Exchanges delayed by queueing on the way out, except a run of quiet
        // ones early on: the drift must come from the whole window.
        let mut s = SyncSlave::new(SyncConfig::default());
        let (offset, drift) = (-20e6, 80e-6);
        for k in 0..60 {
            let out = if k < 8 {
                100_000.0
            } else {
                100_000.0 + 40_000.0 * (k % 2) as f64 + 60_000.0
            };
            s.add(exchange(
                500.0 + k as f64 * 0.25,
                offset,
                drift,
                out,
                100_000.0,
            ));
        }
        let e = s.estimate().unwrap();
        assert!((e.drift + drift).abs() < 10e-6, "drift {}", e.drift);
        let err_ns = error_ns(&e, 515.5, offset, drift);
        assert!(err_ns.abs() < 60_000.0, "error {err_ns} ns");
    }

    #[test]
    fn before_the_drift_is_known_the_newest_exchanges_set_the_offset() {
        let config = SyncConfig::default();
        let mut s = SyncSlave::new(config);
        let (offset, drift) = (10e6, 100e-6);
        s.add(exchange(200.0, offset, drift, 100_000.0, 100_000.0));
        s.add(exchange(200.05, offset, drift, 100_000.0, 100_000.0));
        assert!(s.estimate().is_none(), "fewer than min_samples");
        for k in 2..16 {
            s.add(exchange(
                200.0 + k as f64 * 0.05,
                offset,
                drift,
                100_000.0,
                100_000.0,
            ));
        }
        let e = s.estimate().unwrap();
        assert_eq!(e.drift, 0.0);
        // 0.75 s of exchanges at 100 ppm: the oldest is 75 us off, the
        // newest less than 1 us; 0.3 s on the error is the drift since it.
        let err_ns = error_ns(&e, 201.05, offset, drift);
        assert!(err_ns.abs() < 32_000.0, "error {err_ns} ns");
    }

    #[test]
    fn fast_start_up_exchanges_do_not_pin_the_fit_to_the_first_seconds() {
        // 2 s of exchanges every 20 ms, then every 250 ms, each leg delayed
        // by 100 us plus up to 400 us of pseudo-random queueing.
        let mut s = SyncSlave::new(SyncConfig::default());
        let (offset, drift) = (30e6, -100e-6);
        let mut seed = 12345u64;
        let mut queue = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % 400_000) as f64
        };
        let mut t = 100.0;
        for k in 0..130 {
            s.add(exchange(
                t,
                offset,
                drift,
                100_000.0 + queue(),
                100_000.0 + queue(),
            ));
            t += if k < 100 { 0.02 } else { 0.25 };
        }
        let e = s.estimate().unwrap();
        assert!((e.drift + drift).abs() < 10e-6, "drift {}", e.drift);
        let err_ns = error_ns(&e, t + 0.5, offset, drift);
        assert!(err_ns.abs() < 60_000.0, "error {err_ns} ns");
    }

    /// Seen on a loaded machine: a task that stalls after its request has
    /// left but before it notes when Zenoh took it. Moving that exchange's
    /// own `t1` by half its noted time made its delay the smallest of all,
    /// the fit trusted it most, and bursts fired 200 us early.
    #[test]
    fn a_request_noted_late_does_not_become_the_most_trusted_exchange() {
        let mut s = SyncSlave::new(SyncConfig::default());
        let (offset, drift) = (-50e6, -100e-6);
        // Zenoh takes a request 100 us after `t1`; it then needs 150 us
        // each way. Every fourth task stalls 800 us before noting the time.
        let (taken_ns, leg_ns, stall_ns) = (100_000.0, 150_000.0, 800_000i64);
        for k in 0..40 {
            let mut x = exchange(
                300.0 + k as f64 * 0.1,
                offset,
                drift,
                taken_ns + leg_ns,
                leg_ns,
            );
            x.queued_ns = taken_ns as i64 + if k % 4 == 0 { stall_ns } else { 0 };
            assert!(s.add(x));
        }
        assert_eq!(s.typical_send_delay_ns(), 50_000);
        let e = s.estimate().unwrap();
        // Half of what is left of the outward leg's extra 100 us: 25 us.
        let err_ns = error_ns(&e, 304.0, offset, drift);
        assert!(err_ns.abs() < 30_000.0, "error {err_ns} ns");
        // The drift's prior holds back about 5 % of it over 4 s.
        assert!((e.drift + drift).abs() < 6e-6, "drift {}", e.drift);
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
