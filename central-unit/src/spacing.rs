//! How far apart two transmitters must fire, from the geometry, and the packing of a set of transmitters into one
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
//! that keeps the spacings into the next cycle too. It also places them
//! in sweeps across the floor in [`SWEEP_DIRECTIONS`] directions and keeps
//! the shortest cycle. Deterministic: the same site and set give the same
//! offsets on every machine.

use ickon_proto::site::Site;
use ickon_proto::time::Duration;

use crate::audibility::{AUDIBLE_RANGE_M, GRID_M, sample_points};
use crate::point_index::PointIndex;

/// Spacings needed between every pair of transmitters: `need[i][j]` is the
/// least time from `i`'s emission to `j`'s when `j` fires after `i`;
/// `None` when they do not conflict.
pub type NeedMatrix = Vec<Vec<Option<Duration>>>;

/// The spacings between the transmitters of some cells.
#[derive(Debug, Clone, PartialEq)]
pub struct SpacingTable {
    /// Transmitter ids, site order.
    pub tx_ids: Vec<u32>,
    /// The cell of each.
    pub cells: Vec<String>,
    /// The spacings over the whole floor.
    need: NeedMatrix,
    /// The floor sample points (MSU height is the site's), bucketed: a
    /// robot's region without a scan of the floor.
    points: PointIndex,
    /// At each point, the transmitters audible there and their distance, metres.
    heard: Vec<Vec<(usize, f64)>>,
    channels: Vec<u8>,
    positions: Vec<[f64; 3]>,
    fixed: Duration,
    speed_m_s: f64,
    burst_s: f64,
    window_s: f64,
    height_m: f64,
}

/// The room's reverberation at the carrier, as the spacing of a firing
/// plan takes it into account instead of the site's fixed guard time: the
/// same model as the simulator's world (`ickon_sim::collision`). A burst
/// that travelled `d` metres arrives at `-20 log10(d) - absorption d` dB;
/// it leaves a tail `tail_db` under its own level when it ends, dying at
/// `decay_db_per_ms`; a later burst is detected only `detection_snr_db`
/// above that tail.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reverb {
    /// Air absorption at the carrier, dB per metre.
    pub absorption_db_per_m: f64,
    /// The tail's level when the burst ends, relative to the burst, dB.
    pub tail_db: f64,
    /// How fast the tail dies, dB per millisecond (60 / the room's
    /// reverberation time in ms).
    pub decay_db_per_ms: f64,
    /// How far above the tail a burst must be to be detected, dB.
    pub detection_snr_db: f64,
    /// Added to every spacing, seconds: what the sampled floor and the
    /// clocks leave uncertain (see [`Reverb::default`]).
    pub margin_s: f64,
}

impl Default for Reverb {
    /// The room of `paper`'s profile: 40 kHz at 20 degC and 50 % humidity
    /// (1.3 dB/m), a reverberation time of 20 ms (3 dB/ms), the tail 10 dB
    /// under the burst and detection 10 dB above it. The margin: a robot
    /// between two sample points is at most half a grid diagonal (0.18 m)
    /// from one, which moves a difference of two flight times by up to
    /// 0.35 m / c = 1.03 ms; and 0.5 ms for the cells' synchronisation and
    /// the arrivals' jitter (several sigmas of both).
    fn default() -> Self {
        Self {
            absorption_db_per_m: 1.3,
            tail_db: -10.0,
            decay_db_per_ms: 3.0,
            detection_snr_db: 10.0,
            margin_s: GRID_M * std::f64::consts::SQRT_2 / 343.0 + 0.5e-3,
        }
    }
}

impl Reverb {
    /// Level of a burst after `path_m` metres, dB relative to 1 m.
    pub fn level_db(&self, path_m: f64) -> f64 {
        let d = path_m.max(0.1);
        -20.0 * d.log10() - self.absorption_db_per_m * d
    }

    /// How long after the end of a burst heard at `earlier_db` the tail
    /// has fallen far enough under a burst heard at `later_db`, seconds (a
    /// model that is not a number, or a tail that never dies, gives a
    /// second: longer than any cycle).
    pub fn guard_s(&self, earlier_db: f64, later_db: f64) -> f64 {
        let excess = earlier_db + self.tail_db + self.detection_snr_db - later_db;
        let guard = (excess / self.decay_db_per_ms).max(0.0) * 1e-3;
        if self.decay_db_per_ms > 0.0 && guard.is_finite() {
            guard.min(1.0)
        } else {
            1.0
        }
    }
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
        let h = site.msu.height_m;
        let mut points = Vec::new();
        let mut heard = Vec::new();
        for cell in &site.cells {
            for p in sample_points(cell, GRID_M) {
                let at = [p[0], p[1], h];
                let here: Vec<(usize, f64)> = txs
                    .iter()
                    .enumerate()
                    .filter_map(|(k, t)| {
                        let d = distance3(t.position_m, at);
                        (d <= AUDIBLE_RANGE_M && site.line_of_sight(t.position_m, at))
                            .then_some((k, d))
                    })
                    .collect();
                points.push(p);
                heard.push(here);
            }
        }
        let mut table = Self {
            tx_ids: txs.iter().map(|t| t.id).collect(),
            cells: txs.iter().map(|t| t.cell.clone()).collect(),
            need: Vec::new(),
            points: PointIndex::new(&points),
            heard,
            channels: txs.iter().map(|t| t.channel).collect(),
            positions: txs.iter().map(|t| t.position_m).collect(),
            fixed: Duration::from_secs_f64(
                site.burst_length_s + site.decoder_window_s + site.guard_time_s,
            ),
            speed_m_s: site.speed_of_sound_m_s,
            burst_s: site.burst_length_s,
            window_s: site.decoder_window_s,
            height_m: h,
        };
        table.need = table.needs_over(0..table.points.len());
        table
    }

    /// The spacings needed where only the sample points `points` (indices)
    /// matter: bursts that never meet at any of them do not conflict.
    pub fn needs_over(&self, points: impl Iterator<Item = usize>) -> NeedMatrix {
        let n = self.tx_ids.len();
        // Largest d_i - d_j over points hearing both, metres.
        let mut ahead = vec![vec![f64::NEG_INFINITY; n]; n];
        for p in points {
            let Some(here) = self.heard.get(p) else {
                continue;
            };
            for &(i, di) in here {
                for &(j, dj) in here {
                    if self.channels[i] == self.channels[j] {
                        ahead[i][j] = ahead[i][j].max(di - dj);
                    }
                }
            }
        }
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let m = if i == j { 0.0 } else { ahead[i][j] };
                        (m.is_finite() || i == j).then(|| {
                            self.fixed + Duration::from_secs_f64(m.max(0.0) / self.speed_m_s)
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// The spacings of the transmitters `set` (indices) where only the
    /// sample points `points` matter, from the flight times and the room's
    /// reverberation `reverb` at each point instead of the site's guard
    /// time: when `j` follows `i`, at every point hearing both, `j`'s burst
    /// must arrive after `i`'s has ended and its decoder window passed
    /// (else they collide), and after `i`'s tail has fallen under it:
    ///
    /// `need(i -> j) = max_p (d_i - d_j) / c + burst + max(window, guard_p(i, j)) + margin`
    ///
    /// Pairs outside `set`, or never heard together at `points`, do not conflict.
    pub fn needs_among(
        &self,
        set: &[usize],
        points: impl Iterator<Item = usize>,
        reverb: &Reverb,
    ) -> NeedMatrix {
        let n = self.tx_ids.len();
        let mut member = vec![false; n];
        for &k in set {
            if let Some(m) = member.get_mut(k) {
                *m = true;
            }
        }
        // Largest required onset difference (j after i) over the points, seconds.
        let mut ahead = vec![vec![f64::NEG_INFINITY; n]; n];
        let mut here: Vec<(usize, f64, f64)> = Vec::new();
        for p in points {
            let Some(heard) = self.heard.get(p) else {
                continue;
            };
            here.clear();
            here.extend(
                heard
                    .iter()
                    .filter(|&&(k, _)| member[k])
                    .map(|&(k, d)| (k, d, reverb.level_db(d))),
            );
            for &(i, di, li) in &here {
                for &(j, dj, lj) in &here {
                    if i == j || self.channels[i] != self.channels[j] {
                        continue;
                    }
                    let hold = self.window_s.max(reverb.guard_s(li, lj));
                    let need = (di - dj) / self.speed_m_s + self.burst_s + hold;
                    ahead[i][j] = ahead[i][j].max(need);
                }
            }
        }
        let own = Duration::from_secs_f64(self.burst_s + self.window_s + reverb.margin_s);
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        if i == j {
                            return member[i].then_some(own);
                        }
                        let m = ahead[i][j];
                        m.is_finite()
                            .then(|| Duration::from_secs_f64(m.max(0.0) + reverb.margin_s))
                    })
                    .collect()
            })
            .collect()
    }

    /// How many sample points the table holds (indices `0..point_count`).
    pub fn point_count(&self) -> usize {
        self.points.len()
    }

    /// The sample points within `radius_m` of `centre` (indices, in no
    /// particular order), from the bucketed floor: time in proportion to
    /// the points near the disc, not to the floor.
    pub fn points_within(&self, centre: [f64; 2], radius_m: f64) -> Vec<usize> {
        self.points.within(centre, radius_m)
    }

    /// The sample point nearest to `at` and its distance, metres (`None`
    /// on a site without floor or for a place that is not a number).
    pub fn nearest_point(&self, at: [f64; 2]) -> Option<(usize, f64)> {
        self.points.nearest(at)
    }

    /// The transmitters audible at sample point `point` and their distance, metres.
    pub fn heard_at(&self, point: usize) -> &[(usize, f64)] {
        self.heard.get(point).map_or(&[], Vec::as_slice)
    }

    /// Position of transmitter `i`, metres.
    pub fn position(&self, i: usize) -> [f64; 3] {
        self.positions.get(i).copied().unwrap_or([f64::NAN; 3])
    }

    /// Height of the MSUs the table was sampled for, metres.
    pub fn msu_height_m(&self) -> f64 {
        self.height_m
    }

    /// Index of transmitter `tx_id`.
    pub fn index_of(&self, tx_id: u32) -> Option<usize> {
        self.tx_ids.iter().position(|&t| t == tx_id)
    }

    /// Least time from `i`'s emission to `j`'s when `j` comes after, if they conflict.
    pub fn need(&self, i: usize, j: usize) -> Option<Duration> {
        need_of(&self.need, i, j)
    }

    /// Packs the transmitters `set` (indices; duplicates and unknown ones ignored).
    pub fn pack(&self, set: &[usize]) -> Packing {
        self.pack_with(set, &self.need, &|_| 0.0)
    }

    /// Packs `set` under the spacings `need`; among equally constrained
    /// transmitters, those with the smaller `order` key go first.
    ///
    /// The greedy ranking (most conflicts first, then `order`, then site
    /// order) is tried, and then [`SWEEP_DIRECTIONS`] sweeps of the floor
    /// (transmitters by their position along a direction); the packing with
    /// the shortest period is kept, the earlier one on a tie. A sweep keeps
    /// neighbours next to each other, so that most spacings are those of
    /// transmitters close together; which sweep is shortest depends on
    /// where the robots are.
    pub fn pack_with(
        &self,
        set: &[usize],
        need: &NeedMatrix,
        order: &dyn Fn(usize) -> f64,
    ) -> Packing {
        let need = |i: usize, j: usize| need_of(need, i, j);
        let mut set: Vec<usize> = set
            .iter()
            .copied()
            .filter(|&i| i < self.tx_ids.len())
            .collect();
        set.sort_unstable();
        set.dedup();
        let greedy = greedy_ranking(&set, &need, order);
        let Some(mut best) = place(&greedy, &need, None) else {
            return Packing {
                offsets: Vec::new(),
                period: Duration::ZERO,
            };
        };
        for k in 0..SWEEP_DIRECTIONS {
            let angle = std::f64::consts::TAU * k as f64 / SWEEP_DIRECTIONS as f64;
            let (sin, cos) = angle.sin_cos();
            let along = |i: usize| self.positions[i][0] * cos + self.positions[i][1] * sin;
            let mut sweep = set.clone();
            sweep.sort_by(|&a, &b| along(a).total_cmp(&along(b)).then(a.cmp(&b)));
            if let Some(shorter) = place(&sweep, &need, Some(best.period)) {
                best = shorter;
            }
        }
        best
    }

    /// Every transmitter of the table, packed.
    pub fn pack_all(&self) -> Packing {
        self.pack(&(0..self.tx_ids.len()).collect::<Vec<_>>())
    }
}

/// How many directions [`SpacingTable::pack_with`] sweeps the floor in,
/// evenly spread over the full turn: the site's axes and diagonals. More
/// directions were tried on `warehouse` with 16 robots (12, 16, 24 and 48:
/// the same cycle rate within 1 %, at up to 20 % more of the evaluation's
/// time).
pub const SWEEP_DIRECTIONS: usize = 8;

/// `set` (no duplicates) most conflicts first, then by `order`, then by index.
fn greedy_ranking(
    set: &[usize],
    need: &dyn Fn(usize, usize) -> Option<Duration>,
    order: &dyn Fn(usize) -> f64,
) -> Vec<usize> {
    let degree = |i: usize| {
        set.iter()
            .filter(|&&j| j != i && need(i, j).is_some())
            .count()
    };
    let mut ranked: Vec<(std::cmp::Reverse<usize>, f64, usize)> = set
        .iter()
        .map(|&i| (std::cmp::Reverse(degree(i)), order(i), i))
        .collect();
    ranked.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    ranked.into_iter().map(|r| r.2).collect()
}

/// Places `ranked` in turn, each at the earliest time that keeps every
/// spacing with those placed, and finds the least period. `None` when
/// `ranked` is empty, or as soon as the period reaches `shorter_than`.
fn place(
    ranked: &[usize],
    need: &dyn Fn(usize, usize) -> Option<Duration>,
    shorter_than: Option<Duration>,
) -> Option<Packing> {
    if ranked.is_empty() {
        return None;
    }
    let mut placed: Vec<(usize, Duration)> = Vec::with_capacity(ranked.len());
    let mut period = Duration::ZERO;
    for &i in ranked {
        let fits = |t: Duration| {
            placed
                .iter()
                .all(|&(j, tj)| match (need(j, i), need(i, j)) {
                    (Some(after), Some(before)) => t >= tj + after || t + before <= tj,
                    _ => true,
                })
        };
        let mut candidates: Vec<Duration> = std::iter::once(Duration::ZERO)
            .chain(
                placed
                    .iter()
                    .filter_map(|&(j, tj)| need(j, i).map(|n| tj + n)),
            )
            .collect();
        candidates.sort();
        let ti = candidates
            .into_iter()
            .find(|&t| fits(t))
            .unwrap_or(Duration::ZERO);
        // The period only grows as transmitters are placed, so a ranking
        // that reaches the best one found so far can stop here.
        if let Some(own) = need(i, i) {
            period = period.max(ti + own);
        }
        for &(j, tj) in &placed {
            // Whichever fires later, the earlier one of the next cycle must follow it.
            let (first, t_first, last, t_last) = if tj >= ti {
                (i, ti, j, tj)
            } else {
                (j, tj, i, ti)
            };
            if let Some(n) = need(last, first) {
                period = period.max(t_last - t_first + n);
            }
        }
        if shorter_than.is_some_and(|bound| period >= bound) {
            return None;
        }
        placed.push((i, ti));
    }
    placed.sort_by_key(|&(i, t)| (t, i));
    Some(Packing {
        offsets: placed,
        period,
    })
}

fn need_of(need: &NeedMatrix, i: usize, j: usize) -> Option<Duration> {
    need.get(i).and_then(|r| r.get(j)).copied().flatten()
}

fn distance3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests;
