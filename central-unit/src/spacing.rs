//! How far apart two transmitters must fire, from the geometry (issue 20's
//! "tighter slots"), and the packing of a set of transmitters into one
//! cycle.
//!
//! Two transmitters **conflict** when they share a carrier channel and some
//! point of the floor (MSU height, sampled every [`GRID_M`]) hears both:
//! within [`AUDIBLE_RANGE_M`] and in line of sight. When `j` fires after
//! `i`, its burst must reach every such point at least the burst length
//! plus the decoder window plus the reverberation guard after `i`'s:
//!
//! `need(i -> j) = max_p (d_i(p) - d_j(p)) / c + burst + window + guard`
//!
//! instead of one slot of the longest flight of any cell for every
//! emission. Transmitters on different channels, or never heard together,
//! may fire at the same instant.
//!
//! [`SpacingTable::pack`] places a set of transmitters greedily (most
//! conflicts first, then site order; each at the earliest time that keeps
//! every spacing with those placed), and the cycle period is the least
//! that keeps the spacings into the next cycle too. Deterministic: the
//! same site and set give the same offsets on every machine.

use ickon_proto::site::Site;
use ickon_proto::time::Duration;

use crate::schedule::{AUDIBLE_RANGE_M, GRID_M, sample_points};

/// The spacings between the transmitters of some cells.
#[derive(Debug, Clone, PartialEq)]
pub struct SpacingTable {
    /// Transmitter ids, site order.
    pub tx_ids: Vec<u32>,
    /// The cell of each.
    pub cells: Vec<String>,
    /// `need[i][j]`: least time from `i`'s emission to `j`'s when `j` fires
    /// after `i`; `None` when they do not conflict.
    need: Vec<Vec<Option<Duration>>>,
}

/// Where each transmitter of a set fires in a cycle, and the cycle period.
#[derive(Debug, Clone, PartialEq)]
pub struct Packing {
    /// `(index into the table, offset from the cycle start)`, by offset then index.
    pub offsets: Vec<(usize, Duration)>,
    /// The least cycle period that keeps every spacing into the next cycle.
    pub period: Duration,
}

impl SpacingTable {
    /// The table of the transmitters of `cells` (ids) on `site`.
    pub fn new(site: &Site, cells: &[String]) -> Self {
        let txs: Vec<_> = site
            .transmitters
            .iter()
            .filter(|t| cells.contains(&t.cell))
            .collect();
        let n = txs.len();
        let c = site.speed_of_sound_m_s;
        let h = site.msu.height_m;
        // Largest d_i - d_j over points hearing both, metres.
        let mut ahead = vec![vec![f64::NEG_INFINITY; n]; n];
        let mut audible: Vec<(usize, f64)> = Vec::with_capacity(n);
        for cell in &site.cells {
            for p in sample_points(cell, GRID_M) {
                let at = [p[0], p[1], h];
                audible.clear();
                for (k, t) in txs.iter().enumerate() {
                    let d = distance3(t.position_m, at);
                    if d <= AUDIBLE_RANGE_M && site.line_of_sight(t.position_m, at) {
                        audible.push((k, d));
                    }
                }
                for &(i, di) in &audible {
                    for &(j, dj) in &audible {
                        if txs[i].channel == txs[j].channel {
                            ahead[i][j] = ahead[i][j].max(di - dj);
                        }
                    }
                }
            }
        }
        let fixed_s = site.burst_length_s + site.decoder_window_s + site.guard_time_s;
        let need = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let m = if i == j { 0.0 } else { ahead[i][j] };
                        (m.is_finite() || i == j)
                            .then(|| Duration::from_secs_f64(m.max(0.0) / c + fixed_s))
                    })
                    .collect()
            })
            .collect();
        Self {
            tx_ids: txs.iter().map(|t| t.id).collect(),
            cells: txs.iter().map(|t| t.cell.clone()).collect(),
            need,
        }
    }

    /// Index of transmitter `tx_id`.
    pub fn index_of(&self, tx_id: u32) -> Option<usize> {
        self.tx_ids.iter().position(|&t| t == tx_id)
    }

    /// Least time from `i`'s emission to `j`'s when `j` comes after, if they conflict.
    pub fn need(&self, i: usize, j: usize) -> Option<Duration> {
        self.need.get(i).and_then(|r| r.get(j)).copied().flatten()
    }

    /// Packs the transmitters `set` (indices; duplicates and unknown ones ignored).
    pub fn pack(&self, set: &[usize]) -> Packing {
        let mut set: Vec<usize> = set
            .iter()
            .copied()
            .filter(|&i| i < self.tx_ids.len())
            .collect();
        set.sort_unstable();
        set.dedup();
        let degree = |i: usize| {
            set.iter()
                .filter(|&&j| j != i && self.need(i, j).is_some())
                .count()
        };
        let mut order = set.clone();
        order.sort_by_key(|&i| (std::cmp::Reverse(degree(i)), i));
        let mut placed: Vec<(usize, Duration)> = Vec::with_capacity(set.len());
        for &i in &order {
            let fits = |t: Duration| {
                placed
                    .iter()
                    .all(|&(j, tj)| match (self.need(j, i), self.need(i, j)) {
                        (Some(after), Some(before)) => t >= tj + after || t + before <= tj,
                        _ => true,
                    })
            };
            let mut candidates: Vec<Duration> = std::iter::once(Duration::ZERO)
                .chain(
                    placed
                        .iter()
                        .filter_map(|&(j, tj)| self.need(j, i).map(|n| tj + n)),
                )
                .collect();
            candidates.sort();
            let t = candidates
                .into_iter()
                .find(|&t| fits(t))
                .unwrap_or(Duration::ZERO);
            placed.push((i, t));
        }
        let mut period = Duration::ZERO;
        for &(i, ti) in &placed {
            if let Some(own) = self.need(i, i) {
                period = period.max(ti + own);
            }
            for &(j, tj) in &placed {
                // j fires no earlier than i: i of the next cycle must follow j.
                if i != j && tj >= ti {
                    if let Some(n) = self.need(j, i) {
                        period = period.max(tj - ti + n);
                    }
                }
            }
        }
        placed.sort_by_key(|&(i, t)| (t, i));
        Packing {
            offsets: placed,
            period,
        }
    }

    /// Every transmitter of the table, packed.
    pub fn pack_all(&self) -> Packing {
        self.pack(&(0..self.tx_ids.len()).collect::<Vec<_>>())
    }
}

fn distance3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests;
