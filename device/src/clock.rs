//! The board's clock against the host's, from clock exchanges.
//!
//! A board keeps its own time (nanoseconds since it started, on its own
//! crystal); the host arms bursts and reads arrivals in that time, so it
//! must know `board - host` and how it drifts. Each exchange gives `t1`
//! (request sent, host clock), `t2` and `t3` (request received and reply
//! sent, board clock) and `t4` (reply received, host clock): the offset at
//! the middle of the exchange is `((t2 - t1) + (t3 - t4)) / 2`, wrong by at
//! most half the round trip `(t4 - t1) - (t3 - t2)`. Queueing only adds
//! delay, so the exchanges with the smallest round trips are trusted: the
//! fit keeps the quicker half of the last [`KEPT`] exchanges and draws a
//! line through them weighted by the inverse square of their round trips.
//! Until they span [`MIN_DRIFT_SPAN_NS`], the drift is taken as zero and
//! the quickest exchange's offset is used.

use std::collections::VecDeque;

/// Exchanges kept for the fit (at the hosts' one exchange a second, half a minute).
pub const KEPT: usize = 32;

/// The span of host time the kept exchanges must cover before a drift is
/// fitted: under a second, a crystal's 20-100 ppm is under the round trip
/// of a serial line and cannot be told from it.
pub const MIN_DRIFT_SPAN_NS: i64 = 2_000_000_000;

/// A board cannot take longer than this between receiving a clock request
/// and answering it; a reply that says so is refused.
pub const MAX_TURNAROUND_NS: i128 = 100_000_000;

/// Drift beyond this is no crystal (a board that stepped its clock, or
/// nonsense): the fit falls back to no drift.
pub const MAX_DRIFT: f64 = 1e-3;

/// One exchange, as its four times.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockExchange {
    /// Request sent, host clock, nanoseconds.
    pub t1_host_ns: i64,
    /// Request received, board clock, nanoseconds.
    pub t2_board_ns: u64,
    /// Reply sent, board clock, nanoseconds.
    pub t3_board_ns: u64,
    /// Reply received, host clock, nanoseconds.
    pub t4_host_ns: i64,
}

/// Why an exchange was not taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ExchangeRefused {
    /// The reply came back before the request left, or the board answered
    /// before it was asked.
    #[error("times out of order")]
    OutOfOrder,
    /// The board says it took longer to answer than any board does.
    #[error("board turnaround of {0} ns")]
    SlowTurnaround(i128),
}

impl ClockExchange {
    fn offset_ns(&self) -> f64 {
        let (t1, t2, t3, t4) = self.wide();
        ((t2 - t1) + (t3 - t4)) as f64 / 2.0
    }

    fn delay_ns(&self) -> f64 {
        let (t1, t2, t3, t4) = self.wide();
        ((t4 - t1) - (t3 - t2)) as f64
    }

    fn wide(&self) -> (i128, i128, i128, i128) {
        (
            i128::from(self.t1_host_ns),
            i128::from(self.t2_board_ns),
            i128::from(self.t3_board_ns),
            i128::from(self.t4_host_ns),
        )
    }

    fn check(&self) -> Result<(), ExchangeRefused> {
        let (t1, t2, t3, t4) = self.wide();
        if t4 < t1 || t3 < t2 || (t4 - t1) < (t3 - t2) {
            return Err(ExchangeRefused::OutOfOrder);
        }
        if t3 - t2 > MAX_TURNAROUND_NS {
            return Err(ExchangeRefused::SlowTurnaround(t3 - t2));
        }
        Ok(())
    }
}

/// The fitted line `board - host = offset + drift (host - ref)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Fit {
    ref_host_ns: i64,
    offset_ns: f64,
    drift: f64,
    /// Half the smallest round trip of the exchanges fitted.
    bound_ns: f64,
}

/// The board's clock as the host knows it.
#[derive(Debug, Clone, Default)]
pub struct BoardClock {
    exchanges: VecDeque<ClockExchange>,
    fit: Option<Fit>,
}

impl BoardClock {
    /// No exchange yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one exchange and fits again.
    pub fn add(&mut self, x: ClockExchange) -> Result<(), ExchangeRefused> {
        x.check()?;
        if self.exchanges.len() == KEPT {
            self.exchanges.pop_front();
        }
        self.exchanges.push_back(x);
        self.fit = self.refit();
        Ok(())
    }

    /// Whether an exchange has been taken.
    pub fn is_known(&self) -> bool {
        self.fit.is_some()
    }

    /// `board - host` at host time `host_ns`, nanoseconds.
    pub fn offset_ns(&self, host_ns: i64) -> Option<f64> {
        self.fit.map(|f| {
            f.offset_ns + f.drift * (i128::from(host_ns) - i128::from(f.ref_host_ns)) as f64
        })
    }

    /// The drift of the board's clock against the host's (seconds per second).
    pub fn drift(&self) -> Option<f64> {
        self.fit.map(|f| f.drift)
    }

    /// Half the quickest round trip fitted: the bound of the offset's error
    /// from one exchange, nanoseconds.
    pub fn bound_ns(&self) -> Option<f64> {
        self.fit.map(|f| f.bound_ns)
    }

    /// Host time `host_ns` on the board's clock; `None` before the first
    /// exchange or when it would fall outside the board's clock.
    pub fn to_board(&self, host_ns: i64) -> Option<u64> {
        let board = host_ns as f64 + self.offset_ns(host_ns)?;
        (0.0..1.8e19)
            .contains(&board)
            .then_some(board.round() as u64)
    }

    /// Board time `board_ns` on the host's clock; `None` before the first
    /// exchange or when the time is absurd (outside the host's clock).
    pub fn to_host(&self, board_ns: u64) -> Option<i64> {
        let f = self.fit?;
        // board = host + o + d (host - r)  =>  host = (board - o + d r) / (1 + d)
        let host =
            (board_ns as f64 - f.offset_ns + f.drift * f.ref_host_ns as f64) / (1.0 + f.drift);
        (host.abs() < 9.0e18).then_some(host.round() as i64)
    }

    fn refit(&self) -> Option<Fit> {
        let mut quick: Vec<&ClockExchange> = self.exchanges.iter().collect();
        // Quickest first; of equally quick ones, the newest.
        quick.sort_by(|a, b| {
            a.delay_ns()
                .total_cmp(&b.delay_ns())
                .then(b.t1_host_ns.cmp(&a.t1_host_ns))
        });
        quick.truncate(quick.len().div_ceil(2));
        let quickest = *quick.first()?;
        let bound_ns = quickest.delay_ns() / 2.0;
        // Without a drift, the newest of the exchanges nearly as quick as
        // the quickest: an old offset is wrong by the drift times its age.
        let best = quick
            .iter()
            .filter(|x| x.delay_ns() <= quickest.delay_ns() * 1.5 + 10_000.0)
            .max_by_key(|x| x.t1_host_ns)
            .copied()
            .unwrap_or(quickest);
        let mid = |x: &ClockExchange| x.t1_host_ns / 2 + x.t4_host_ns / 2;
        let (first, last) = quick
            .iter()
            .map(|x| mid(x))
            .fold((i64::MAX, i64::MIN), |(lo, hi), t| (lo.min(t), hi.max(t)));
        let single = Fit {
            ref_host_ns: mid(best),
            offset_ns: best.offset_ns(),
            drift: 0.0,
            bound_ns,
        };
        if last.saturating_sub(first) < MIN_DRIFT_SPAN_NS {
            return Some(single);
        }
        // Weighted least squares of offset against host time.
        let ref_host_ns = last;
        let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for x in &quick {
            let w = 1.0 / (x.delay_ns().max(1_000.0)).powi(2);
            let t = (mid(x) - ref_host_ns) as f64;
            let y = x.offset_ns();
            sw += w;
            sx += w * t;
            sy += w * y;
            sxx += w * t * t;
            sxy += w * t * y;
        }
        let det = sw * sxx - sx * sx;
        if det <= 0.0 || !det.is_finite() {
            return Some(single);
        }
        let drift = (sw * sxy - sx * sy) / det;
        let offset_ns = (sy - drift * sx) / sw;
        if !drift.is_finite() || drift.abs() > MAX_DRIFT || !offset_ns.is_finite() {
            return Some(single);
        }
        Some(Fit {
            ref_host_ns,
            offset_ns,
            drift,
            bound_ns,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An exchange with a board running `offset_ns + drift * host` ahead,
    /// legs of `out_ns` and `back_ns`.
    fn exchange(host: i64, offset_ns: f64, drift: f64, out_ns: i64, back_ns: i64) -> ClockExchange {
        let board = |h: i64| (h as f64 + offset_ns + drift * h as f64) as u64;
        ClockExchange {
            t1_host_ns: host,
            t2_board_ns: board(host + out_ns),
            t3_board_ns: board(host + out_ns + 50_000),
            t4_host_ns: host + out_ns + 50_000 + back_ns,
        }
    }

    #[test]
    fn recovers_offset_and_drift_of_a_board() {
        let mut c = BoardClock::new();
        let (offset, drift) = (3.7e9, 40e-6);
        for i in 0..30i64 {
            // Every third exchange is queued 2 ms on its way out.
            let out = if i % 3 == 0 { 2_000_000 } else { 300_000 };
            c.add(exchange(
                1_000_000_000 * i + 5_000_000_000,
                offset,
                drift,
                out,
                300_000,
            ))
            .unwrap();
        }
        let host = 40_000_000_000;
        let truth = offset + drift * host as f64;
        assert!((c.offset_ns(host).unwrap() - truth).abs() < 2_000.0);
        assert!((c.drift().unwrap() - drift).abs() < 1e-6);
        let board = c.to_board(host).unwrap();
        assert!((c.to_host(board).unwrap() - host).abs() <= 1);
    }

    #[test]
    fn refuses_exchanges_out_of_order_or_slow() {
        let mut c = BoardClock::new();
        let mut x = exchange(1_000, 0.0, 0.0, 10, 10);
        x.t4_host_ns = 0;
        assert_eq!(c.add(x), Err(ExchangeRefused::OutOfOrder));
        let mut x = exchange(1_000, 0.0, 0.0, 10, 10);
        x.t3_board_ns = x.t2_board_ns + 5_000_000_000;
        x.t4_host_ns = x.t1_host_ns + 6_000_000_000;
        assert!(matches!(c.add(x), Err(ExchangeRefused::SlowTurnaround(_))));
        assert!(!c.is_known());
    }

    #[test]
    fn absurd_board_times_map_to_none_not_a_panic() {
        let mut c = BoardClock::new();
        c.add(exchange(1_000, 0.0, 0.0, 10, 10)).unwrap();
        assert!(c.to_host(u64::MAX).is_none());
        assert!(c.to_board(i64::MIN).is_none());
    }
}
