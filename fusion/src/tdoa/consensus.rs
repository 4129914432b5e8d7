//! Consensus over small subsets: the fallback of [`super::solve`] when
//! leave-one-out cannot clean a cycle.
//!
//! Leave-one-out starts from the fix of every signal. Behind racks a cycle
//! can carry four or more reflections; that fix is then pulled so far that
//! the wrong signals look like the outliers, or the cap of rejections is
//! reached with reflections still inside. Here every small subset (one
//! signal more than the minimum, so that the closed form has one root in
//! general) proposes a position, and the position that most signals agree
//! with wins: the signals whose pseudo-range residuals fall in one window
//! of twice the gate. Reflections are late, so a signal *earlier* than that
//! window is evidence against the position and cancels one agreeing
//! signal. The agreeing set is then solved as a whole and has to pass the
//! gate; it must hold two signals more than the minimum, since a subset
//! one over the minimum fits nearly any data, and more than half of the
//! cycle's signals, so that outliers agreeing by chance are out-voted.

use nalgebra::Vector3;

use super::SolverConfig;
use super::closed_form::closed_form_subset;
use super::signal::{Signal, Subset};

/// Most subsets tried in one cycle: all of them up to 16 signals
/// (`C(16, 4) = 1820`); beyond, a fixed pseudo-random choice of this many.
const MAX_SUBSETS: usize = 2048;

/// The largest agreeing set over the subsets of `set`, if it holds at least
/// `mode.min_signals() + 2` signals and more than half of `set`. Deterministic: the same signals give
/// the same set.
pub(crate) fn agreeing_set(
    signals: &[Signal],
    set: Subset,
    config: &SolverConfig,
    gate_m: f64,
) -> Option<Subset> {
    let mode = config.mode;
    let size = mode.min_signals() + 1;
    let need = mode.min_signals() + 2;
    let indices: Vec<usize> = set.iter().collect();
    if indices.len() < need {
        return None;
    }
    let inside = |p: &Vector3<f64>| config.allowed_area_m.is_none_or(|a| a.contains(p, mode));
    let mut best: Option<(i64, f64, Subset)> = None;
    let mut residuals = Vec::with_capacity(indices.len());
    for_each_subset(indices.len(), size, |chosen| {
        let subset = chosen
            .iter()
            .fold(Subset::empty(), |s, &k| s.with(indices[k]));
        let Ok(cf) = closed_form_subset(signals, subset, mode) else {
            return;
        };
        for candidate in cf.candidates().filter(|c| inside(&c.position_m)) {
            residuals.clear();
            residuals.extend(indices.iter().map(|&i| {
                (
                    signals[i].pseudo_range_m - (candidate.position_m - signals[i].tx_m).norm(),
                    i,
                )
            }));
            let (score, spread_m, agreeing) = best_window(&mut residuals, gate_m, config.late_only);
            let better = best
                .as_ref()
                .is_none_or(|(s, w, _)| (score, -spread_m) > (*s, -*w));
            if better {
                best = Some((score, spread_m, agreeing));
            }
        }
    });
    // A majority as well: reflections and wrong ids are the exception in a
    // cycle, and chance agreement among outliers is then out-voted.
    best.map(|(_, _, s)| s)
        .filter(|s| s.len() >= need && 2 * s.len() > indices.len())
}

/// The window of width `2 gate` over the sorted residuals that scores best:
/// signals inside it, less (when only late arrivals can be wrong) those
/// before it. Returns the score, the window's own spread (smaller is
/// better among equal scores) and its signals.
fn best_window(residuals: &mut [(f64, usize)], gate_m: f64, late_only: bool) -> (i64, f64, Subset) {
    residuals.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = (i64::MIN, f64::INFINITY, 0, 0);
    let mut end = 0;
    for start in 0..residuals.len() {
        end = end.max(start);
        while end + 1 < residuals.len() && residuals[end + 1].0 - residuals[start].0 <= 2.0 * gate_m
        {
            end += 1;
        }
        let inside = (end - start + 1) as i64;
        let early = if late_only { start as i64 } else { 0 };
        let score = inside - early;
        let spread_m = residuals[end].0 - residuals[start].0;
        if (score, -spread_m) > (best.0, -best.1) {
            best = (score, spread_m, start, end);
        }
    }
    let (score, spread_m, start, end) = best;
    let agreeing = residuals[start..=end]
        .iter()
        .fold(Subset::empty(), |s, &(_, i)| s.with(i));
    (score, spread_m, agreeing)
}

/// Calls `visit` with every `k`-subset of `0..n` (as sorted positions) when
/// there are at most [`MAX_SUBSETS`], else with [`MAX_SUBSETS`] of them
/// drawn by a fixed generator.
fn for_each_subset(n: usize, k: usize, mut visit: impl FnMut(&[usize])) {
    if k == 0 || k > n {
        return;
    }
    if binomial(n, k) <= MAX_SUBSETS as u128 {
        let mut chosen: Vec<usize> = (0..k).collect();
        loop {
            visit(&chosen);
            // Next combination in lexicographic order.
            let Some(i) = (0..k).rev().find(|&i| chosen[i] < n - k + i) else {
                return;
            };
            chosen[i] += 1;
            for j in i + 1..k {
                chosen[j] = chosen[j - 1] + 1;
            }
        }
    }
    // SplitMix64 from a fixed seed: the same cycle gives the same subsets
    // on every machine.
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15 ^ n as u64;
    let mut next = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let mut chosen = Vec::with_capacity(k);
    for _ in 0..MAX_SUBSETS {
        chosen.clear();
        while chosen.len() < k {
            let i = (next() % n as u64) as usize;
            if !chosen.contains(&i) {
                chosen.push(i);
            }
        }
        chosen.sort_unstable();
        visit(&chosen);
    }
}

/// `C(n, k)`, saturating.
fn binomial(n: usize, k: usize) -> u128 {
    (0..k as u128).fold(1u128, |acc, i| acc.saturating_mul(n as u128 - i) / (i + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_subset_is_visited_once_when_they_are_few() {
        let mut seen = std::collections::HashSet::new();
        for_each_subset(7, 4, |c| {
            assert!(c.windows(2).all(|w| w[0] < w[1]));
            assert!(seen.insert(c.to_vec()));
        });
        assert_eq!(seen.len(), 35);
    }

    #[test]
    fn many_signals_are_sampled_within_the_budget_and_the_same_each_time() {
        let collect = || {
            let mut all = Vec::new();
            for_each_subset(40, 4, |c| all.push(c.to_vec()));
            all
        };
        let (a, b) = (collect(), collect());
        assert_eq!(a.len(), MAX_SUBSETS);
        assert_eq!(a, b);
        assert!(a.iter().all(|c| c.len() == 4 && c.iter().all(|&i| i < 40)));
    }

    #[test]
    fn the_binomial_matches_small_cases() {
        assert_eq!(binomial(16, 4), 1820);
        assert_eq!(binomial(5, 5), 1);
        assert_eq!(binomial(64, 4), 635_376);
    }

    #[test]
    fn a_window_prefers_the_early_cluster_when_only_late_signals_can_be_wrong() {
        // Three direct signals near 0, three reflections near 1 m.
        let mut r = vec![
            (0.0, 0),
            (0.01, 1),
            (-0.01, 2),
            (1.0, 3),
            (1.01, 4),
            (0.99, 5),
        ];
        let (score, _, set) = best_window(&mut r, 0.05, true);
        assert_eq!(score, 3);
        assert_eq!(set.iter().collect::<Vec<_>>(), vec![0, 1, 2]);
        // An early signal before the late cluster counts against it.
        let mut r = vec![(0.0, 0), (1.0, 1), (1.01, 2)];
        let (score, _, set) = best_window(&mut r, 0.05, true);
        assert_eq!((score, set.len()), (1, 1));
    }
}
