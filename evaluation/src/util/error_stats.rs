//! The 3D errors of one estimator, summarised in bounded memory: every
//! error kept (the percentiles exact) up to [`EXACT_LIMIT`], and beyond,
//! a histogram of logarithmic bins (the percentiles within
//! [`BIN_RATIO`]'s half-step, 0.025 %), so that a replay of any length
//! holds a fixed amount per estimator. Sums and the maximum stay exact.

/// Errors kept one by one before the histogram takes over (8 MB).
pub const EXACT_LIMIT: usize = 1 << 20;
/// Ratio of a bin's upper to its lower edge.
pub const BIN_RATIO: f64 = 1.0005;
/// Lower edge of the first logarithmic bin, metres: smaller errors share
/// bin 0 (a hundredth of a millimetre, below any positioning system's).
const MIN_M: f64 = 1e-5;
/// Bins: up to 10 km (larger errors share the last, the maximum is exact).
const N_BINS: usize = 41_450;

/// The errors seen so far.
#[derive(Debug, Clone, Default)]
pub struct ErrorStats {
    exact: Vec<f64>,
    bins: Option<Vec<u64>>,
    n: u64,
    sum: f64,
    sum2: f64,
    max: f64,
}

impl ErrorStats {
    /// Adds one error, metres (not negative).
    pub fn push(&mut self, e_m: f64) {
        self.n += 1;
        self.sum += e_m;
        self.sum2 += e_m * e_m;
        self.max = self.max.max(e_m);
        match &mut self.bins {
            Some(b) => b[bin(e_m)] += 1,
            None if self.exact.len() < EXACT_LIMIT => self.exact.push(e_m),
            None => {
                let mut b = vec![0_u64; N_BINS];
                for v in self.exact.drain(..).chain([e_m]) {
                    b[bin(v)] += 1;
                }
                self.exact.shrink_to_fit();
                self.bins = Some(b);
            }
        }
    }

    /// Errors seen.
    pub fn len(&self) -> u64 {
        self.n
    }

    /// Sum of the errors, and of their squares.
    pub fn sums(&self) -> (f64, f64) {
        (self.sum, self.sum2)
    }

    /// The largest error.
    pub fn max(&self) -> f64 {
        self.max
    }

    /// The errors of ranks `ranks` (from 0, ascending) in sorted order.
    pub fn at_ranks(&self, ranks: &[u64]) -> Vec<f64> {
        match &self.bins {
            None => {
                let mut sorted = self.exact.clone();
                sorted.sort_by(f64::total_cmp);
                ranks.iter().map(|&r| sorted[r as usize]).collect()
            }
            Some(b) => ranks
                .iter()
                .map(|&r| {
                    let mut seen = 0;
                    let k = b
                        .iter()
                        .position(|&c| {
                            seen += c;
                            seen > r
                        })
                        .unwrap_or(N_BINS - 1);
                    middle(k).min(self.max)
                })
                .collect(),
        }
    }
}

fn bin(e_m: f64) -> usize {
    if e_m.is_nan() || e_m <= MIN_M {
        return 0;
    }
    let k = ((e_m / MIN_M).ln() / BIN_RATIO.ln()).floor();
    (k as usize + 1).min(N_BINS - 1)
}

/// The geometric middle of bin `k`.
fn middle(k: usize) -> f64 {
    if k == 0 {
        return MIN_M / 2.0;
    }
    MIN_M * BIN_RATIO.powf(k as f64 - 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beyond_the_exact_limit_the_percentiles_stay_within_a_bin() {
        // Errors 1 mm .. 1 m, uniformly: the rank r has 1 mm + r * step.
        let n = 3 * EXACT_LIMIT as u64;
        let step = 0.999 / n as f64;
        let mut s = ErrorStats::default();
        for k in 0..n {
            s.push(0.001 + k as f64 * step);
        }
        assert!(s.bins.is_some() && s.exact.is_empty());
        assert_eq!(s.len(), n);
        let ranks = [n / 2, (0.95 * n as f64) as u64, n - 1];
        for (r, got) in ranks.iter().zip(s.at_ranks(&ranks)) {
            let want = 0.001 + *r as f64 * step;
            assert!(
                (got - want).abs() <= 3e-4 * want,
                "rank {r}: {got} vs {want}"
            );
        }
        assert!((s.max() - (0.001 + (n - 1) as f64 * step)).abs() < 1e-12);
    }

    #[test]
    fn below_the_limit_the_percentiles_are_exact() {
        let mut s = ErrorStats::default();
        for v in [3.0, 1.0, 2.0] {
            s.push(v);
        }
        assert_eq!(s.at_ranks(&[0, 1, 2]), vec![1.0, 2.0, 3.0]);
        assert_eq!(s.sums(), (6.0, 14.0));
    }
}
