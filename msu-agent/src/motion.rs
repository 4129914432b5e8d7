//! The robot's motion between the arrivals of a cycle, for the fix solver's
//! motion compensation ([`ickon_fusion::tdoa::solve_moving`]).
//!
//! A robot at 0.3 m/s moves about 12 cm between the first and the last
//! arrival of a cycle; solving as if it stood still turns that into errors
//! across a corridor. The wheels measure the motion between two arrivals
//! to a few millimetres, but in their own frame: the odometry's heading
//! starts anywhere and drifts. So this module keeps
//! - the odometry track (time, position and heading in the odometry frame,
//!   integrated from the encoder ticks with the arc of the CDA paper), a few
//!   seconds of it, and
//! - the rotation from the odometry frame to the site frame, fitted to the
//!   solver's own recent fixes (a least-squares rotation between the fixes
//!   and the odometry positions at their times, both centred). It needs no
//!   estimator: the raw fixes stay the same whatever fuses them.
//!
//! Until that rotation is trusted (the fixes must span enough ground for
//! their noise to leave the angle well determined), and whenever the track
//! does not cover the cycle or claims an impossible motion, the solver gets
//! no displacements and solves as before.

use std::collections::VecDeque;

use ickon_fusion::estimator::{IncrementTracker, Input, arc_step};
use nalgebra::Vector3;

/// Odometry samples kept: 10 s at the robot's 50 Hz, far more than a cycle
/// (under a second) needs, bounded whatever the sender does.
const MAX_TRACK: usize = 512;
/// Fixes the rotation is fitted to: 8-12 s of fixes at a full schedule's
/// 2.6-3.8 cycles/s (`warehouse`, `lab`).
const MAX_FIXES: usize = 32;
/// Oldest fix kept for the rotation, seconds: the odometry's own heading
/// drifts (1.5 % of every turn with the paper's wheel-base error), so old
/// fixes would fit a rotation that no longer holds.
const MAX_FIX_AGE_S: f64 = 15.0;
/// Largest standard deviation of the fitted rotation for it to be used,
/// radians (3 deg): a cycle's 12 cm of motion is then placed within 6 mm,
/// well under a raw fix's own noise. The rotation's standard deviation is
/// about the fixes' RMS sigma over their spread times `sqrt(n)`; with
/// `paper`'s 0.15 m fixes that takes some 20 fixes spread over 0.6 m, with
/// noise-free fixes three fixes a few centimetres apart.
const MAX_ROTATION_SIGMA_RAD: f64 = 0.052;
/// Fewest fixes for a rotation.
const MIN_FIXES: usize = 3;
/// Fastest a wheeled indoor robot drives, m/s (a Pioneer 3-DX: 1.2), with a
/// margin: a track claiming more between two arrivals is not believed.
const MAX_SPEED_M_S: f64 = 2.0;

/// One sample of the odometry track.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TrackPoint {
    t_s: f64,
    x_m: f64,
    y_m: f64,
    theta_rad: f64,
}

/// A fix kept for the rotation: time, site position, odometry position at
/// that time, the fix's standard deviation (metres).
type FixPair = (f64, [f64; 2], [f64; 2], f64);

/// The odometry track and its rotation into the site frame.
#[derive(Debug, Clone, Default)]
pub struct CycleMotion {
    increments: IncrementTracker,
    track: VecDeque<TrackPoint>,
    /// Recent fixes: time, site position, odometry position at that time,
    /// standard deviation.
    fixes: VecDeque<FixPair>,
}

impl CycleMotion {
    /// A motion record with no odometry yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one odometry or encoder input (anything else is ignored).
    pub fn odometry(&mut self, input: &Input) {
        let Some(inc) = self.increments.step(input) else {
            if matches!(input, Input::Encoders(_) | Input::Odometry(_)) && self.track.is_empty() {
                self.track.push_back(TrackPoint {
                    t_s: input.t_s(),
                    x_m: 0.0,
                    y_m: 0.0,
                    theta_rad: 0.0,
                });
            }
            return;
        };
        let last = self.track.back().copied().unwrap_or(TrackPoint {
            t_s: inc.t_s - inc.dt_s,
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
        });
        if !(inc.t_s.is_finite() && inc.t_s >= last.t_s) {
            // Out of order: the track must stay ordered in time; a late
            // sample's step is lost to the compensation only.
            return;
        }
        let (x_m, y_m, theta_rad) = arc_step(
            last.x_m,
            last.y_m,
            last.theta_rad,
            inc.distance_m,
            inc.dtheta_rad,
        );
        if ![x_m, y_m, theta_rad].iter().all(|v| v.is_finite()) {
            return;
        }
        if self.track.len() >= MAX_TRACK {
            self.track.pop_front();
        }
        self.track.push_back(TrackPoint {
            t_s: inc.t_s,
            x_m,
            y_m,
            theta_rad,
        });
    }

    /// The odometry position at `t_s`, interpolated; `None` outside the
    /// track (a cycle the odometry does not cover).
    fn at(&self, t_s: f64) -> Option<[f64; 2]> {
        let (first, last) = (self.track.front()?, self.track.back()?);
        if !(first.t_s <= t_s && t_s <= last.t_s) {
            return None;
        }
        let k = self.track.partition_point(|p| p.t_s <= t_s);
        let b = self.track.get(k).unwrap_or(last);
        let a = self.track.get(k.saturating_sub(1)).unwrap_or(first);
        let w = if b.t_s > a.t_s {
            (t_s - a.t_s) / (b.t_s - a.t_s)
        } else {
            0.0
        };
        Some([a.x_m + w * (b.x_m - a.x_m), a.y_m + w * (b.y_m - a.y_m)])
    }

    /// How far apart the robot was at `from_s` and at `to_s` by the
    /// odometry (the straight distance, which needs no rotation into the
    /// site frame), with both times clamped to the track; `None` without a
    /// track.
    pub fn travelled_m(&self, from_s: f64, to_s: f64) -> Option<f64> {
        let (first, last) = (self.track.front()?.t_s, self.track.back()?.t_s);
        let clamp = |t: f64| {
            if t.is_finite() {
                t.clamp(first, last)
            } else {
                last
            }
        };
        let (a, b) = (self.at(clamp(from_s))?, self.at(clamp(to_s))?);
        Some((a[0] - b[0]).hypot(a[1] - b[1]))
    }

    /// Records a fix (site frame, at its measurement time `t_s`, standard
    /// deviation `sigma_m`) for the rotation; ignored when the odometry does
    /// not cover its time.
    pub fn fix(&mut self, t_s: f64, xy_m: [f64; 2], sigma_m: f64) {
        let Some(o) = self.at(t_s) else {
            return;
        };
        if !(xy_m.iter().all(|v| v.is_finite()) && sigma_m.is_finite() && sigma_m >= 0.0) {
            return;
        }
        if self.fixes.back().is_some_and(|f| t_s <= f.0) {
            // A clock stepped back: the old fixes belong to another time line.
            self.fixes.clear();
        }
        while self.fixes.len() >= MAX_FIXES
            || self
                .fixes
                .front()
                .is_some_and(|f| t_s - f.0 > MAX_FIX_AGE_S)
        {
            self.fixes.pop_front();
        }
        self.fixes.push_back((t_s, xy_m, o, sigma_m));
    }

    /// The rotation from the odometry frame to the site frame, radians,
    /// once the recent fixes determine it.
    fn rotation_rad(&self) -> Option<f64> {
        let n = self.fixes.len();
        if n < MIN_FIXES {
            return None;
        }
        let mean = |pick: fn(&FixPair) -> [f64; 2]| {
            let s = self
                .fixes
                .iter()
                .map(pick)
                .fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
            [s[0] / n as f64, s[1] / n as f64]
        };
        let (mf, mo) = (mean(|f| f.1), mean(|f| f.2));
        let (mut dot, mut cross, mut spread, mut var) = (0.0, 0.0, 0.0, 0.0);
        for (_, f, o, sigma) in &self.fixes {
            var += sigma * sigma;
            let (fx, fy) = (f[0] - mf[0], f[1] - mf[1]);
            let (ox, oy) = (o[0] - mo[0], o[1] - mo[1]);
            dot += ox * fx + oy * fy;
            cross += ox * fy - oy * fx;
            spread += ox * ox + oy * oy;
        }
        // spread = sum of squared distances from the centre = n * rms^2.
        let sigma_rad = (var / n as f64).sqrt() / spread.sqrt().max(1e-12);
        (sigma_rad <= MAX_ROTATION_SIGMA_RAD).then(|| cross.atan2(dot))
    }

    /// The receiver's displacement at each of `arrival_times_s` from where
    /// it was at `reference_s`, in the site frame; `None` when the motion
    /// is not known well enough to compensate (no trusted rotation, the
    /// track does not cover the cycle, or it claims an impossible speed).
    pub fn displacements(
        &self,
        arrival_times_s: &[f64],
        reference_s: f64,
    ) -> Option<Vec<Vector3<f64>>> {
        let phi = self.rotation_rad()?;
        let (s, c) = phi.sin_cos();
        let r = self.at(reference_s)?;
        arrival_times_s
            .iter()
            .map(|t| {
                let p = self.at(*t)?;
                let (dx, dy) = (p[0] - r[0], p[1] - r[1]);
                let m = Vector3::new(c * dx - s * dy, s * dx + c * dy, 0.0);
                let possible = MAX_SPEED_M_S * (t - reference_s).abs() + 1e-3;
                (m.norm() <= possible).then_some(m)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_fusion::estimator::{EncoderSample, WheelGeometry};

    const GEOMETRY: WheelGeometry = WheelGeometry {
        wheel_base_m: 0.33,
        left_m_per_tick: 1e-4,
        right_m_per_tick: 1e-4,
    };

    fn ticks(t_s: f64, left: i64, right: i64) -> Input {
        Input::Encoders(EncoderSample {
            t_s,
            left_ticks: left,
            right_ticks: right,
            geometry: GEOMETRY,
        })
    }

    /// Drives straight at 0.3 m/s for `secs` along the odometry's +x, which
    /// is the site's `heading`; a fix every 0.4 s at the true position.
    fn drive(heading: f64, secs: f64) -> CycleMotion {
        let mut m = CycleMotion::new();
        let steps = (secs * 50.0) as i64;
        for k in 0..=steps {
            let t = k as f64 * 0.02;
            // 0.3 m/s = 60 ticks per 0.02 s.
            m.odometry(&ticks(t, 60 * k, 60 * k));
            if k % 20 == 0 && k > 0 {
                let d = 0.3 * t;
                m.fix(t, [2.0 + d * heading.cos(), 1.0 + d * heading.sin()], 0.15);
            }
        }
        m
    }

    #[test]
    fn the_distance_driven_needs_no_rotation_and_is_clamped_to_the_track() {
        let m = drive(2.0, 4.0);
        let d = m.travelled_m(1.0, 2.5).unwrap();
        assert!((d - 0.45).abs() < 1e-9, "{d}");
        // Beyond the track's end (4 s): what the track covers.
        let d = m.travelled_m(3.0, 9.0).unwrap();
        assert!((d - 0.3).abs() < 1e-9, "{d}");
        assert!(CycleMotion::new().travelled_m(0.0, 1.0).is_none());
    }

    #[test]
    fn displacements_are_rotated_into_the_site_frame_once_the_fixes_span_enough_ground() {
        let heading = 2.0_f64;
        let short = drive(heading, 2.0);
        assert!(
            short.displacements(&[1.5, 1.9], 1.7).is_none(),
            "too little ground"
        );
        let m = drive(heading, 12.0);
        let d = m.displacements(&[11.5, 11.9], 11.7).unwrap();
        let expect = 0.3 * 0.2;
        for (v, sign) in d.iter().zip([-1.0, 1.0]) {
            assert!((v.x - sign * expect * heading.cos()).abs() < 1e-9, "{v:?}");
            assert!((v.y - sign * expect * heading.sin()).abs() < 1e-9, "{v:?}");
        }
    }

    #[test]
    fn a_cycle_outside_the_track_or_an_impossible_jump_gives_no_displacements() {
        let mut m = drive(0.5, 12.0);
        assert!(m.displacements(&[12.5], 12.1).is_none(), "beyond the track");
        // A forged tick count: 100 m in 20 ms.
        m.odometry(&ticks(12.02, 1_000_000_000, 1_000_000_000));
        assert!(m.displacements(&[12.01, 12.02], 11.9).is_none());
    }

    #[test]
    fn the_track_stays_bounded_and_ordered_under_any_input() {
        let mut m = CycleMotion::new();
        for k in 0..5_000_i64 {
            // Times going back and forth, ticks anywhere.
            let t = if k % 3 == 0 {
                -(k as f64)
            } else {
                k as f64 * 0.01
            };
            m.odometry(&ticks(t, k.wrapping_mul(7_919), -k));
            m.fix(t, [f64::NAN, 1.0], 0.1);
            m.fix(t, [1.0, 2.0], 0.1);
        }
        assert!(m.track.len() <= MAX_TRACK && m.fixes.len() <= MAX_FIXES);
        assert!(
            m.track
                .iter()
                .zip(m.track.iter().skip(1))
                .all(|(a, b)| a.t_s <= b.t_s)
        );
    }
}
