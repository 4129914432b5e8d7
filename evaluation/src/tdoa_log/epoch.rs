//! One epoch of arrivals turned into what the estimators take: range
//! differences for the filters (in row order, each at its row's time) and
//! the per-epoch least-squares fix of the MSU's solver.

use ickon_fusion::estimator::RangeDifferenceSample;
use ickon_fusion::tdoa::{
    Aabb, ErrorKind, Mode, PairMeasurement, RefineConfig, Signal, SolverConfig, refine_pairs, solve,
};
use nalgebra::{Matrix3, Vector3};

use super::format::{Anchors, Arrival, Kind};

/// Why an epoch gave no least-squares fix.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Unsolved {
    /// Fewer arrivals than the dimension needs (3 in 2D, 4 in 3D).
    pub too_few_arrivals: u64,
    /// The solver found no position (degenerate geometry, no consistent
    /// subset, outside the area).
    pub no_fix: u64,
    /// The epoch names one anchor twice, or holds more arrivals than the
    /// solver takes.
    pub invalid: u64,
    /// 2D differences against several references (the pairwise solver is
    /// 3D only).
    pub mixed_references_2d: u64,
}

impl Unsolved {
    /// All of them.
    pub fn total(&self) -> u64 {
        self.too_few_arrivals + self.no_fix + self.invalid + self.mixed_references_2d
    }
}

/// How an epoch's values become metres.
#[derive(Debug, Clone, Copy)]
pub struct Units {
    /// Propagation speed, m/s (needed by time kinds only).
    pub speed_m_s: Option<f64>,
    /// Standard deviation of a row without its own, metres.
    pub default_sigma_m: f64,
}

/// Slowest and fastest speed of sound in air the ground robot's air
/// states describe, m/s: dry air from -40 to 85 degC (306 and 379 m/s, the
/// range a cell board's air sensor reads), with room for humidity (up to
/// about half a percent faster).
const SOUND_IN_AIR_M_S: std::ops::RangeInclusive<f64> = 300.0..=385.0;

impl Units {
    /// Whether the measurements travel as sound through air: the log names
    /// a propagation speed within that of sound in air. Only then does the
    /// air (its temperature, its drafts) change them, and the ground
    /// filter learns the local speed of sound; a radio log, or one of
    /// distances with no speed named, is replayed without those states.
    pub fn carried_by_air(&self) -> bool {
        self.speed_m_s
            .is_some_and(|c| SOUND_IN_AIR_M_S.contains(&c))
    }

    /// The row's value in metres (`None`: a time without a speed).
    pub fn metres(&self, a: &Arrival) -> Option<f64> {
        if a.kind.is_time() {
            Some(a.value * self.speed_m_s?)
        } else {
            Some(a.value)
        }
    }

    /// The row's standard deviation in metres.
    pub fn sigma_m(&self, a: &Arrival) -> f64 {
        match (a.sigma, a.kind.is_time()) {
            (Some(s), true) => s * self.speed_m_s.unwrap_or(1.0),
            (Some(s), false) => s,
            (None, _) => self.default_sigma_m,
        }
    }
}

/// The range differences of an epoch for the filters: differences as
/// given; arrival times and ranges against the epoch's first row (their
/// common offset cancels), with both rows' variances.
pub fn samples(rows: &[Arrival], anchors: &Anchors, units: &Units) -> Vec<RangeDifferenceSample> {
    let at = |k: usize| anchors.list[k].position_m;
    let mut out = Vec::with_capacity(rows.len());
    let Some(first) = rows.first() else {
        return out;
    };
    if first.kind.is_difference() {
        for a in rows {
            let (Some(reference), Some(d_m)) = (a.reference, units.metres(a)) else {
                continue;
            };
            out.push(sample(
                a.t_s,
                at(reference),
                at(a.anchor),
                d_m,
                units.sigma_m(a),
            ));
        }
    } else if let Some(r0) = units.metres(first) {
        let s0 = units.sigma_m(first);
        for a in &rows[1..] {
            let Some(r) = units.metres(a) else { continue };
            let sigma = (units.sigma_m(a).powi(2) + s0 * s0).sqrt();
            out.push(sample(a.t_s, at(first.anchor), at(a.anchor), r - r0, sigma));
        }
    }
    out
}

/// The range differences of an epoch as the MSU hands a cycle to the
/// ground filter: arrival times and ranges as differences of consecutive
/// rows (in time order), each stamped at its later row and carrying the
/// earlier row's time; differences as given.
///
/// The ground filter sums consecutive differences back into the cycle's
/// arrivals, each related to the robot's position at its own time, and
/// blames a reflection on the one arrival that was late. Differences
/// against the epoch's first row break that chain at every difference:
/// a first arrival heard by a reflection then biases all of them, and the
/// filter, gating each, loses the robot (a figure-eight passing a
/// neighbouring cell whose transmitter fires first).
pub fn chain_samples(
    rows: &[Arrival],
    anchors: &Anchors,
    units: &Units,
) -> Vec<RangeDifferenceSample> {
    if rows.first().is_none_or(|a| a.kind.is_difference()) {
        return samples(rows, anchors, units);
    }
    let at = |k: usize| anchors.list[k].position_m;
    let mut out = Vec::with_capacity(rows.len());
    let mut previous: Option<(&Arrival, f64)> = None;
    for a in rows {
        let Some(r) = units.metres(a) else { continue };
        if let Some((p, r0)) = previous {
            let sigma = (units.sigma_m(a).powi(2) + units.sigma_m(p).powi(2)).sqrt();
            let mut s = sample(a.t_s, at(p.anchor), at(a.anchor), r - r0, sigma);
            s.a_t_s = Some(p.t_s);
            out.push(s);
        }
        previous = Some((a, r));
    }
    out
}

fn sample(t_s: f64, a_m: [f64; 3], b_m: [f64; 3], d_m: f64, sigma_m: f64) -> RangeDifferenceSample {
    RangeDifferenceSample {
        a_t_s: None,
        t_s,
        a_m,
        b_m,
        d_m,
        sigma_m,
        clocks: None,
        speed_rel_sigma: None,
    }
}

/// The per-epoch least-squares solver.
pub struct EpochSolver {
    config: SolverConfig,
    dim: usize,
    last_m: Vector3<f64>,
    at_emission: bool,
    /// Epochs that gave no fix, by reason.
    pub unsolved: Unsolved,
    /// Epochs that gave one.
    pub solved: u64,
}

impl EpochSolver {
    /// The MSU's solver ([`SolverConfig::default`]: leave-one-out of late
    /// arrivals at 4 sigma, consensus fallback) in `dim` dimensions, its
    /// fixes kept in `area`. With `at_emission` (fixed receivers hearing a
    /// mobile emitter), a fix from arrival times is stamped at the
    /// emission time it solves for, where the emitter was; otherwise at
    /// the mean arrival time, where a mobile receiver was.
    pub fn new(
        dim: usize,
        plane_z_m: f64,
        area: ([f64; 3], [f64; 3]),
        start_m: [f64; 3],
        at_emission: bool,
    ) -> Self {
        let mode = if dim == 2 {
            Mode::TwoD {
                height_m: plane_z_m,
            }
        } else {
            Mode::ThreeD
        };
        Self {
            config: SolverConfig {
                mode,
                allowed_area_m: Some(Aabb {
                    min_m: Vector3::from(area.0),
                    max_m: Vector3::from(area.1),
                }),
                ..SolverConfig::default()
            },
            dim,
            last_m: Vector3::from(start_m),
            at_emission,
            unsolved: Unsolved::default(),
            solved: 0,
        }
    }

    /// The epoch's fix `(t_s, position_m, covariance_m2)`, stamped as
    /// [`Self::new`] says.
    pub fn solve(
        &mut self,
        rows: &[Arrival],
        anchors: &Anchors,
        units: &Units,
    ) -> Option<(f64, [f64; 3], Matrix3<f64>)> {
        let (mut p, cov, emitted_s) = self.try_solve(rows, anchors, units)?;
        if self.dim == 2 {
            // A 2D position is (x, y): the plane's height is given, not solved.
            p[2] = 0.0;
        }
        self.solved += 1;
        self.last_m = Vector3::from(p);
        let mean_s = rows.iter().map(|a| a.t_s).sum::<f64>() / rows.len() as f64;
        match emitted_s {
            Some(t) if self.at_emission => Some((t, p, cov)),
            _ => Some((mean_s, p, cov)),
        }
    }

    /// The fix and, from arrival times, the emission time it implies.
    fn try_solve(
        &mut self,
        rows: &[Arrival],
        anchors: &Anchors,
        units: &Units,
    ) -> Option<([f64; 3], Matrix3<f64>, Option<f64>)> {
        let first = rows.first()?;
        let mut ids: Vec<usize> = rows.iter().map(|a| a.anchor).collect();
        let one_reference = first
            .reference
            .filter(|&r| rows.iter().all(|a| a.reference == Some(r)));
        match one_reference {
            Some(r) => ids.push(r),
            None => ids.extend(rows.iter().filter_map(|a| a.reference)),
        }
        let distinct = {
            let mut d = ids.clone();
            d.sort_unstable();
            d.dedup();
            d.len()
        };
        if distinct < self.dim + 1 {
            self.unsolved.too_few_arrivals += 1;
            return None;
        }
        if distinct < ids.len() && (!first.kind.is_difference() || one_reference.is_some()) {
            self.unsolved.invalid += 1;
            return None;
        }
        let sigma = rows.iter().map(|a| units.sigma_m(a)).sum::<f64>() / rows.len() as f64;
        let position = |k: usize| Vector3::from(anchors.list[k].position_m);
        if first.kind.is_difference() && one_reference.is_none() {
            if self.dim == 2 {
                self.unsolved.mixed_references_2d += 1;
                return None;
            }
            let pairs: Vec<PairMeasurement> = rows
                .iter()
                .filter_map(|a| {
                    Some(PairMeasurement {
                        a_m: position(a.reference?),
                        b_m: position(a.anchor),
                        d_m: units.metres(a)?,
                    })
                })
                .collect();
            let config = RefineConfig {
                sigma_m: sigma,
                ..RefineConfig::default()
            };
            return match refine_pairs(&pairs, self.last_m, &config) {
                Ok(s) => Some((s.position_m.into(), s.covariance_m2, None)),
                Err(_) => {
                    self.unsolved.no_fix += 1;
                    None
                }
            };
        }
        let mut signals: Vec<Signal> = Vec::with_capacity(rows.len() + 1);
        if let Some(r) = one_reference {
            signals.push(Signal {
                tx_id: r as u32,
                tx_m: position(r),
                pseudo_range_m: 0.0,
                t_s: first.t_s,
            });
        }
        for a in rows {
            signals.push(Signal {
                tx_id: a.anchor as u32,
                tx_m: position(a.anchor),
                pseudo_range_m: units.metres(a)?,
                t_s: a.t_s,
            });
        }
        let config = SolverConfig {
            sigma_range_m: sigma,
            ..self.config
        };
        match solve(&signals, &config) {
            Ok(fix) => {
                let emitted_s = match (first.kind, units.speed_m_s) {
                    (Kind::ToaS, Some(c)) => Some(fix.bias_m / c),
                    _ => None,
                };
                Some((fix.position_m.into(), fix.covariance_m2, emitted_s))
            }
            Err(e) if e.kind() == ErrorKind::BadInput => {
                self.unsolved.invalid += 1;
                None
            }
            Err(_) => {
                self.unsolved.no_fix += 1;
                None
            }
        }
    }
}

/// Whether `kind` may join an epoch that began with `first`: arrival
/// times and ranges (pseudo-ranges) do not mix with differences.
pub fn same_family(first: Kind, kind: Kind) -> bool {
    first.is_difference() == kind.is_difference()
}

#[cfg(test)]
mod chain_tests {
    use std::collections::HashMap;

    use super::*;
    use crate::tdoa_log::format::{Anchor, Role};

    /// Three anchors and an epoch of arrival times at a mobile whose
    /// pseudo-ranges are `rho`, the first one `late_m` long by a reflection.
    fn epoch(late_m: f64) -> (Anchors, Vec<Arrival>) {
        let at = [[0.0, 0.0, 3.0], [5.0, 0.0, 3.0], [0.0, 5.0, 3.0]];
        let anchors = Anchors {
            list: at
                .iter()
                .enumerate()
                .map(|(k, &position_m)| Anchor {
                    id: k.to_string(),
                    position_m,
                })
                .collect(),
            by_id: HashMap::new(),
            dim: 2,
            role: Role::Transmitter,
            plane_z_m: 0.0,
        };
        let rho = [2.0 + late_m, 3.0, 4.5];
        let rows = rho
            .iter()
            .enumerate()
            .map(|(k, &r)| Arrival {
                line: k as u64,
                epoch: 0,
                t_s: 0.1 * k as f64,
                anchor: k,
                reference: None,
                kind: Kind::RangeM,
                value: r,
                sigma: Some(0.03),
            })
            .collect();
        (anchors, rows)
    }

    #[test]
    fn a_reflected_first_arrival_spoils_one_link_of_the_chain_not_every_difference() {
        let units = Units {
            speed_m_s: None,
            default_sigma_m: 0.1,
        };
        let (anchors, clean) = epoch(0.0);
        let (_, reflected) = epoch(0.7);
        let chain = chain_samples(&reflected, &anchors, &units);
        let clean_chain = chain_samples(&clean, &anchors, &units);
        assert_eq!(chain.len(), 2);
        // Consecutive pairs, each carrying its earlier arrival's time.
        assert_eq!(
            (chain[1].a_m, chain[1].b_m),
            (anchors.list[1].position_m, anchors.list[2].position_m)
        );
        assert_eq!(chain[1].a_t_s, Some(0.1));
        assert!((chain[1].t_s - 0.2).abs() < 1e-12);
        assert!((chain[0].d_m - (clean_chain[0].d_m - 0.7)).abs() < 1e-12);
        assert!((chain[1].d_m - clean_chain[1].d_m).abs() < 1e-12);
        assert!((chain[1].sigma_m - 0.03 * std::f64::consts::SQRT_2).abs() < 1e-12);
        // Against the first row, the reflection is in every difference.
        let star = samples(&reflected, &anchors, &units);
        let clean_star = samples(&clean, &anchors, &units);
        assert!(
            star.iter()
                .zip(&clean_star)
                .all(|(a, b)| (a.d_m - b.d_m + 0.7).abs() < 1e-12)
        );
    }

    #[test]
    fn only_a_speed_of_sound_in_air_brings_the_air_states() {
        let units = |speed_m_s| Units {
            speed_m_s,
            default_sigma_m: 0.01,
        };
        // Sound in a hall, cold to warm; radio; sound in water; a log of
        // distances that names no speed.
        assert!(units(Some(343.0)).carried_by_air());
        assert!(units(Some(306.0)).carried_by_air());
        assert!(units(Some(379.0)).carried_by_air());
        assert!(!units(Some(299_792_458.0)).carried_by_air());
        assert!(!units(Some(1480.0)).carried_by_air());
        assert!(!units(None).carried_by_air());
    }
}
