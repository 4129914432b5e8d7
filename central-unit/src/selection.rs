//! Firing for what each robot needs: of the transmitters a robot can hear
//! from everywhere it may be, a few in good geometry, shared between
//! robots where one serves several, instead of everything in earshot.
//!
//! **Criterion.** Every tracked robot gets at least [`NeedsConfig::signals`]
//! transmitters audible in line of sight (within the fire range) from every
//! sample point of its uncertainty region, and the horizontal dilution of
//! precision of those seen from the region's centre is at most
//! [`NeedsConfig::max_hdop`], when its candidates allow it.
//!
//! **Choice.** Robots are served most constrained first (fewest
//! candidates). A robot short of signals takes, among its candidates not
//! yet chosen, the one that the most robots still short of signals can
//! use (one transmitter, one slot, several robots served), then one that
//! is **due** (silent for [`NeedsConfig::rotation`]: every transmitter some
//! robot can hear is fired at least that often, for the survey calibration
//! and the filters' per-transmitter states), then the nearest (short
//! flights, short slots, loud bursts). Transmitters already chosen for
//! others count for it. A robot whose geometry is still above the bound
//! then takes the candidate that lowers its HDOP most, until it is under
//! the bound or no candidate helps.
//!
//! Pure and deterministic: the same views, history and `now` give the same
//! set on every machine.

use ickon_fusion::tdoa::{Mode, dop};
use ickon_proto::time::{Duration, Time};
use nalgebra::Vector3;

use crate::spacing::SpacingTable;

/// What each robot needs from a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedsConfig {
    /// Transmitters each robot hears in a cycle, at least. 4: the MSU
    /// solves `x, y` and the common offset with the height known (3
    /// signals), and one more lets the fix survive one lost burst (`paper`
    /// drops 5 % and the residual gate rejects reflections) or, when all
    /// arrive, lets the residuals expose a reflection.
    pub signals: usize,
    /// Largest horizontal dilution of precision of a robot's set. 3: a fix
    /// then has a horizontal sigma of at most three range sigmas (5 cm with
    /// the receivers' 50 us, 17 mm), under the filter's 7 cm residual gate,
    /// so a correct fix is not mistaken for a reflection; the MSU's own
    /// gate (0.5 m) refuses only degenerate geometry.
    pub max_hdop: f64,
    /// Every transmitter some robot can hear fires at least this often.
    /// 1 s: the survey calibration and the filters learn each
    /// transmitter's and each cell's systematic errors over tens of
    /// seconds, so once a second keeps every one of them fed.
    pub rotation: Duration,
}

impl Default for NeedsConfig {
    fn default() -> Self {
        Self {
            signals: 4,
            max_hdop: 3.0,
            rotation: Duration::from_millis(1_000),
        }
    }
}

/// One tracked robot as the choice sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Need {
    /// Centre of its uncertainty region, metres.
    pub centre: [f64; 2],
    /// Transmitters (table indices) it hears from every point of its region.
    pub candidates: Vec<usize>,
}

/// When each transmitter of a table last fired: what the rotation needs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FiringHistory {
    last: Vec<Option<Time>>,
    previous: Vec<usize>,
}

impl FiringHistory {
    /// Notes that the transmitters `fired` (table indices) fire in the
    /// cycle starting at `at`.
    pub fn note(&mut self, fired: impl Iterator<Item = usize>, at: Time) {
        self.previous.clear();
        for k in fired {
            if k >= self.last.len() {
                self.last.resize(k + 1, None);
            }
            self.last[k] = Some(at);
            self.previous.push(k);
        }
    }

    /// The transmitters of the cycle noted last: the next cycle's bursts
    /// must keep their spacings from these too.
    pub fn previous(&self) -> &[usize] {
        &self.previous
    }

    /// Whether transmitter `k` has been silent for `rotation` at `now`
    /// (never fired: due).
    pub fn due(&self, k: usize, now: Time, rotation: Duration) -> bool {
        match self.last.get(k).copied().flatten() {
            Some(t) => now.since(t) >= rotation,
            None => true,
        }
    }

    /// Forgets everything (the table changed).
    pub fn clear(&mut self) {
        self.last.clear();
        self.previous.clear();
    }
}

/// What the firing plans chose over a run: how many robots were served by
/// what they need and the HDOP of their sets.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct PlanStats {
    /// Cycles planned for what robots need.
    pub cycles: u64,
    /// Robots served over those cycles, added up.
    pub robots_served: u64,
    /// Their HDOPs added up (those with a geometry that gives a fix).
    pub hdop_sum: f64,
    /// Served robots whose set gave no fix geometry (infinite HDOP).
    pub no_geometry: u64,
    /// The largest finite HDOP of a served robot.
    pub hdop_worst: f64,
}

impl PlanStats {
    /// Notes one cycle's plan, the HDOP of each robot it served.
    pub fn note(&mut self, hdops: &[f64]) {
        if hdops.is_empty() {
            return;
        }
        self.cycles += 1;
        for &h in hdops {
            self.robots_served += 1;
            if h.is_finite() {
                self.hdop_sum += h;
                self.hdop_worst = self.hdop_worst.max(h);
            } else {
                self.no_geometry += 1;
            }
        }
    }

    /// Mean HDOP of the served robots' sets with a fix geometry (`None`: none).
    pub fn mean_hdop(&self) -> Option<f64> {
        let n = self.robots_served - self.no_geometry;
        (n > 0).then(|| self.hdop_sum / n as f64)
    }
}

/// The transmitters (table indices, ascending) that give every robot of
/// `needs` what [`NeedsConfig`] asks, and each robot's HDOP with them
/// (infinite when fewer than three of its candidates were chosen).
pub fn choose(
    table: &SpacingTable,
    needs: &[Need],
    config: &NeedsConfig,
    history: &FiringHistory,
    height_m: f64,
    now: Time,
) -> (Vec<usize>, Vec<f64>) {
    let n = table.tx_ids.len();
    let mut chosen = vec![false; n];
    let mut order: Vec<usize> = (0..needs.len()).collect();
    order.sort_by_key(|&r| (needs[r].candidates.len(), r));
    // How many chosen transmitters each robot has among its candidates.
    let mut have: Vec<usize> = vec![0; needs.len()];
    // Which robots can use each transmitter.
    let mut users: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (r, need) in needs.iter().enumerate() {
        for &k in &need.candidates {
            if let Some(u) = users.get_mut(k) {
                u.push(r);
            }
        }
    }
    let take = |k: usize, chosen: &mut Vec<bool>, have: &mut Vec<usize>| {
        chosen[k] = true;
        for &r in &users[k] {
            have[r] += 1;
        }
    };
    for &r in &order {
        let need = &needs[r];
        let centre = need.centre;
        while have[r] < config.signals {
            let best = need
                .candidates
                .iter()
                .copied()
                .filter(|&k| k < n && !chosen[k])
                .map(|k| {
                    let shared = users[k]
                        .iter()
                        .filter(|&&o| have[o] < config.signals)
                        .count();
                    let due = history.due(k, now, config.rotation);
                    (k, shared, due, horizontal_m(table, k, centre))
                })
                .max_by(|a, b| {
                    a.1.cmp(&b.1)
                        .then(a.2.cmp(&b.2))
                        .then(b.3.total_cmp(&a.3))
                        .then(b.0.cmp(&a.0))
                });
            let Some((k, ..)) = best else {
                break;
            };
            take(k, &mut chosen, &mut have);
        }
        loop {
            let mine: Vec<usize> = need
                .candidates
                .iter()
                .copied()
                .filter(|&k| k < n && chosen[k])
                .collect();
            let now_hdop = hdop(table, &mine, centre, height_m);
            if now_hdop <= config.max_hdop {
                break;
            }
            let better = need
                .candidates
                .iter()
                .copied()
                .filter(|&k| k < n && !chosen[k])
                .map(|k| {
                    let mut with = mine.clone();
                    with.push(k);
                    (k, hdop(table, &with, centre, height_m))
                })
                .filter(|&(_, h)| h < now_hdop)
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            let Some((k, _)) = better else {
                break;
            };
            take(k, &mut chosen, &mut have);
        }
    }
    let set: Vec<usize> = (0..n).filter(|&k| chosen[k]).collect();
    let hdops = needs
        .iter()
        .map(|need| {
            let mine: Vec<usize> = need
                .candidates
                .iter()
                .copied()
                .filter(|&k| k < n && chosen[k])
                .collect();
            hdop(table, &mine, need.centre, height_m)
        })
        .collect();
    (set, hdops)
}

/// Horizontal distance from transmitter `k` to `at`, metres.
fn horizontal_m(table: &SpacingTable, k: usize, at: [f64; 2]) -> f64 {
    let p = table.position(k);
    (p[0] - at[0]).hypot(p[1] - at[1])
}

/// HDOP of the transmitters `set` seen from `at` at MSU height `height_m`
/// (infinite for a geometry that gives no fix).
pub fn hdop(table: &SpacingTable, set: &[usize], at: [f64; 2], height_m: f64) -> f64 {
    let txs: Vec<Vector3<f64>> = set
        .iter()
        .map(|&k| Vector3::from(table.position(k)))
        .collect();
    match dop(
        &txs,
        Vector3::new(at[0], at[1], height_m),
        Mode::TwoD { height_m },
    ) {
        Ok(d) if d.hdop.is_finite() => d.hdop,
        _ => f64::INFINITY,
    }
}

#[cfg(test)]
mod tests;
