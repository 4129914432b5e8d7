//! A position from the last fraction of a second of range differences
//! alone, trusted only when the window is consistent: enough measurements
//! from enough anchors, few rejected, small residuals, inside the flight
//! volume, and no second solution as good (the mirror of the range
//! differences) unless the motion says which one.
//!
//! The solver is the pairwise Gauss-Newton of [`crate::tdoa::refine_pairs`],
//! started from several points of the volume (its centre, its floor and its
//! ceiling, and the motion's hint) so that every local minimum the geometry
//! admits inside the volume is found, not only the nearest.

use std::collections::VecDeque;

use nalgebra::Vector3;

use super::volume::FlightVolume;
use crate::estimator::RangeDifferenceSample;
use crate::tdoa::{PairMeasurement, RefineConfig, refine_pairs};

/// What makes a window consistent.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WindowParams {
    /// Length of the window, seconds.
    pub window_s: f64,
    /// Residual gate of the one rejection pass, in the measurements' own
    /// standard deviations.
    pub gate_sigma: f64,
    /// Least share of the window's measurements that must fit.
    pub min_kept_share: f64,
    /// Least number of measurements that must fit.
    pub min_kept: usize,
    /// Least number of distinct anchors among those that fit.
    pub min_anchors: usize,
    /// Largest RMS of the fitting residuals, in standard deviations.
    pub max_rms_sigma: f64,
    /// Two solutions closer than this are the same one, metres.
    pub distinct_m: f64,
}

impl Default for WindowParams {
    /// 0.1 s (about 45 TDoA2 or 28 TDoA3 UWB measurements, while a flying
    /// tag moves a few centimetres); a 3-sigma gate; at least 70 % of the
    /// window and 12 measurements fit, from 5 anchors (one more than a 3D
    /// fix needs, so that one bad anchor shows); the fitting residuals
    /// within 1.5 sigma RMS (a consistent window has about 1); solutions
    /// within 0.3 m are one.
    fn default() -> Self {
        Self {
            window_s: 0.1,
            gate_sigma: 3.0,
            min_kept_share: 0.7,
            min_kept: 12,
            min_anchors: 5,
            max_rms_sigma: 1.5,
            distinct_m: 0.3,
        }
    }
}

/// The verdict on a window.
#[derive(Debug, Clone, PartialEq)]
pub enum WindowFix {
    /// One consistent solution (or the one the motion hint supports).
    Fix {
        /// Position, metres.
        position_m: Vector3<f64>,
        /// Standard deviation, the largest axis's, metres.
        sigma_m: f64,
    },
    /// Several consistent solutions inside the volume and no hint to
    /// choose: the mirror ambiguity of the geometry.
    Ambiguous {
        /// The candidates, metres.
        candidates_m: Vec<Vector3<f64>>,
    },
    /// No consistent solution in the window.
    Inconsistent,
}

/// The last `window_s` of measurements.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Window {
    params: WindowParams,
    samples: VecDeque<RangeDifferenceSample>,
}

impl Window {
    /// An empty window.
    pub fn new(params: WindowParams) -> Self {
        Self {
            params,
            samples: VecDeque::new(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &WindowParams {
        &self.params
    }

    /// Adds a measurement and forgets those older than the window.
    pub fn push(&mut self, m: RangeDifferenceSample) {
        let horizon = m.t_s - self.params.window_s;
        self.samples.push_back(m);
        while self.samples.front().is_some_and(|s| s.t_s < horizon) {
            self.samples.pop_front();
        }
    }

    /// Forgets everything.
    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// The window's verdict. `hint_m` is where the motion puts the
    /// receiver (the last trusted estimate); with it, of several
    /// consistent solutions the nearest wins.
    pub fn solve(&self, volume: &FlightVolume, hint_m: Option<Vector3<f64>>) -> WindowFix {
        let pairs: Vec<PairMeasurement> = self
            .samples
            .iter()
            .map(|s| PairMeasurement {
                a_m: Vector3::from(s.a_m),
                b_m: Vector3::from(s.b_m),
                d_m: s.d_m,
            })
            .collect();
        let sigma_m = self
            .samples
            .iter()
            .map(|s| s.sigma_m)
            .fold(0.0_f64, f64::max);
        if pairs.len() < self.params.min_kept || sigma_m.is_nan() || sigma_m <= 0.0 {
            return WindowFix::Inconsistent;
        }
        let c = volume.centre_m();
        let mut starts = vec![
            c,
            Vector3::new(c.x, c.y, volume.min_m[2]),
            Vector3::new(c.x, c.y, volume.max_m[2]),
        ];
        starts.extend(hint_m);
        let mut found: Vec<(Vector3<f64>, f64, f64)> = Vec::new();
        for start in starts {
            let Some((p, sigma, rms)) = self.consistent_from(&pairs, start, sigma_m) else {
                continue;
            };
            if !volume.contains(&p) {
                continue;
            }
            match found
                .iter_mut()
                .find(|f| (f.0 - p).norm() < self.params.distinct_m)
            {
                Some(f) if rms < f.2 => *f = (p, sigma, rms),
                Some(_) => {}
                None => found.push((p, sigma, rms)),
            }
        }
        match (found.len(), hint_m) {
            (0, _) => WindowFix::Inconsistent,
            (1, _) => WindowFix::Fix {
                position_m: found[0].0,
                sigma_m: found[0].1,
            },
            (_, Some(h)) => {
                let best = found
                    .iter()
                    .min_by(|a, b| (a.0 - h).norm().total_cmp(&(b.0 - h).norm()))
                    .copied()
                    .unwrap_or(found[0]);
                WindowFix::Fix {
                    position_m: best.0,
                    sigma_m: best.1,
                }
            }
            (_, None) => WindowFix::Ambiguous {
                candidates_m: found.iter().map(|f| f.0).collect(),
            },
        }
    }

    /// Solve, one rejection pass, solve again; the solution, its sigma and
    /// the RMS residual in sigmas when the window is consistent.
    fn consistent_from(
        &self,
        pairs: &[PairMeasurement],
        start: Vector3<f64>,
        sigma_m: f64,
    ) -> Option<(Vector3<f64>, f64, f64)> {
        let config = RefineConfig {
            sigma_m,
            ..RefineConfig::default()
        };
        let first = refine_pairs(pairs, start, &config).ok()?;
        let gate_m = self.params.gate_sigma * sigma_m;
        let kept: Vec<PairMeasurement> = pairs
            .iter()
            .zip(&first.residuals_m)
            .filter(|(_, r)| r.abs() <= gate_m)
            .map(|(p, _)| *p)
            .collect();
        let p = &self.params;
        if kept.len() < p.min_kept || (kept.len() as f64) < p.min_kept_share * pairs.len() as f64 {
            return None;
        }
        let mut anchors: Vec<[f64; 3]> = Vec::new();
        for k in &kept {
            for at in [k.a_m, k.b_m] {
                let at: [f64; 3] = at.into();
                if !anchors.contains(&at) {
                    anchors.push(at);
                }
            }
        }
        if anchors.len() < p.min_anchors {
            return None;
        }
        let second = refine_pairs(&kept, first.position_m, &config).ok()?;
        let n = second.residuals_m.len() as f64;
        let rms = (second.residuals_m.iter().map(|r| r * r).sum::<f64>() / n).sqrt() / sigma_m;
        if rms > p.max_rms_sigma {
            return None;
        }
        let cov = second.covariance_m2;
        let sigma = crate::estimator::kf::largest_axis_sigma(&cov, 0);
        Some((second.position_m, sigma, rms))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Anchors in the plane z = 1.5 and a receiver at (2, 3, 0.8): its
    /// mirror (2, 3, 2.2) fits every range difference as well.
    fn window_below_a_plane_of_anchors() -> Window {
        let anchors: Vec<[f64; 3]> = [
            (0.0, 0.0),
            (6.0, 0.0),
            (6.0, 6.0),
            (0.0, 6.0),
            (3.0, 0.0),
            (0.0, 3.0),
        ]
        .iter()
        .map(|&(x, y)| [x, y, 1.5])
        .collect();
        let p = Vector3::new(2.0, 3.0, 0.8);
        let mut w = Window::new(WindowParams::default());
        for k in 0..30 {
            let (a, b) = (anchors[k % 6], anchors[(k + 1) % 6]);
            let d = (p - Vector3::from(b)).norm() - (p - Vector3::from(a)).norm();
            w.push(RangeDifferenceSample {
                a_t_s: None,
                t_s: k as f64 * 0.002,
                a_m: a,
                b_m: b,
                d_m: d,
                sigma_m: 0.05,
                clocks: None,
                speed_rel_sigma: None,
            });
        }
        w
    }

    #[test]
    fn mirror_solutions_are_ambiguous_without_a_hint_and_the_nearest_wins_with_one() {
        let w = window_below_a_plane_of_anchors();
        let room = FlightVolume::new([-0.5, -0.5, 0.0], [6.5, 6.5, 3.0]).unwrap();
        match w.solve(&room, None) {
            WindowFix::Ambiguous { candidates_m } => {
                assert_eq!(candidates_m.len(), 2);
                let mut z: Vec<f64> = candidates_m.iter().map(|c| c.z).collect();
                z.sort_by(f64::total_cmp);
                assert!(
                    (z[0] - 0.8).abs() < 1e-3 && (z[1] - 2.2).abs() < 1e-3,
                    "{z:?}"
                );
            }
            other => panic!("{other:?}"),
        }
        let hint = Some(Vector3::new(2.5, 3.0, 1.0));
        match w.solve(&room, hint) {
            WindowFix::Fix { position_m, .. } => assert!((position_m.z - 0.8).abs() < 1e-3),
            other => panic!("{other:?}"),
        }
        // A room whose ceiling is the anchors' plane admits one.
        let low_room = FlightVolume::new([-0.5, -0.5, 0.0], [6.5, 6.5, 1.5]).unwrap();
        assert!(matches!(w.solve(&low_room, None), WindowFix::Fix { .. }));
    }

    #[test]
    fn too_few_or_inconsistent_measurements_give_no_fix() {
        let mut w = window_below_a_plane_of_anchors();
        let room = FlightVolume::new([-0.5, -0.5, 0.0], [6.5, 6.5, 1.5]).unwrap();
        // Half the window off by a metre: under 70 % fit.
        let t = 0.06;
        for k in 0..30 {
            w.push(RangeDifferenceSample {
                a_t_s: None,
                t_s: t,
                a_m: [0.0, 0.0, 1.5],
                b_m: [6.0, 0.0, 1.5],
                d_m: if k % 2 == 0 { 1.0 } else { -1.0 },
                sigma_m: 0.05,
                clocks: None,
                speed_rel_sigma: None,
            });
        }
        assert_eq!(w.solve(&room, None), WindowFix::Inconsistent);
        w.clear();
        assert_eq!(w.solve(&room, None), WindowFix::Inconsistent);
    }
}
