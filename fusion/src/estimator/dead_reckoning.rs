//! Relative motion from odometry poses or encoder ticks, arc kinematics, and
//! first-order covariance propagation for dead reckoning.

use nalgebra::{Matrix2, Matrix3, Matrix3x2};

use super::input::{EncoderSample, Input, OdometrySample};
use crate::angle;

/// Motion between two consecutive relative-positioning samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Increment {
    /// Time of the newer sample, in seconds.
    pub t_s: f64,
    /// Time since the older sample, in seconds.
    pub dt_s: f64,
    /// Distance travelled by the robot's centre, signed (negative = reverse).
    pub distance_m: f64,
    /// Heading change reported by the relative unit, in radians.
    pub dtheta_rad: f64,
    /// Whether the increment came from encoder ticks (the CDA paper) rather than
    /// from odometry poses (the ICKON paper).
    pub from_encoders: bool,
}

/// Turns successive [`OdometrySample`]s or [`EncoderSample`]s into
/// [`Increment`]s. The first relative source seen is used and the other one
/// is ignored from then on, so that feeding both never counts motion twice.
#[derive(Debug, Clone, Default)]
pub struct IncrementTracker {
    last_odometry: Option<OdometrySample>,
    last_encoders: Option<EncoderSample>,
}

impl IncrementTracker {
    /// Consumes a relative-positioning input; returns the motion since the
    /// previous one of the same source, or `None` for the first sample, for
    /// inputs of another kind and for the source not in use.
    pub fn step(&mut self, input: &Input) -> Option<Increment> {
        match input {
            Input::Odometry(s) if self.last_encoders.is_none() => {
                let prev = self.last_odometry.replace(*s)?;
                Some(odometry_increment(&prev, s))
            }
            Input::Encoders(s) if self.last_odometry.is_none() => {
                let prev = self.last_encoders.replace(*s)?;
                Some(encoder_increment(&prev, s))
            }
            _ => None,
        }
    }

    /// Whether encoder ticks (not odometry poses) are the source in use.
    pub fn uses_encoders(&self) -> bool {
        self.last_encoders.is_some()
    }
}

/// The ICKON paper, eq. 9: `dd = sqrt(dx_b^2 + dy_b^2)`. The paper's distance is
/// unsigned; we give it the sign of the projection on the mean heading so
/// that a reversing robot is not corrected forwards.
fn odometry_increment(prev: &OdometrySample, s: &OdometrySample) -> Increment {
    let dx = s.x_m - prev.x_m;
    let dy = s.y_m - prev.y_m;
    let dtheta = angle::diff(s.theta_rad, prev.theta_rad);
    let mid = prev.theta_rad + 0.5 * dtheta;
    let along = dx * mid.cos() + dy * mid.sin();
    let magnitude = dx.hypot(dy);
    Increment {
        t_s: s.t_s,
        dt_s: s.t_s - prev.t_s,
        distance_m: if along < 0.0 { -magnitude } else { magnitude },
        dtheta_rad: dtheta,
        from_encoders: false,
    }
}

/// The CDA paper: `dist = (l + r) / 2`, and the encoder heading change
/// `alpha = (r - l) / W` used in eq. 1.
fn encoder_increment(prev: &EncoderSample, s: &EncoderSample) -> Increment {
    let g = &s.geometry;
    // i128 so that no pair of i64 counters can overflow the subtraction.
    let dl = (i128::from(s.left_ticks) - i128::from(prev.left_ticks)) as f64 * g.left_m_per_tick;
    let dr = (i128::from(s.right_ticks) - i128::from(prev.right_ticks)) as f64 * g.right_m_per_tick;
    Increment {
        t_s: s.t_s,
        dt_s: s.t_s - prev.t_s,
        distance_m: 0.5 * (dl + dr),
        dtheta_rad: (dr - dl) / g.wheel_base_m,
        from_encoders: true,
    }
}

/// Below this heading change an arc is treated as a straight segment (seed
/// 003 case 2, eq. 4-6), where the arc formulas divide by ~0.
const STRAIGHT_EPS_RAD: f64 = 1e-9;

/// The CDA paper, eq. 1-6: moves `(x, y, theta)` along the arc of length
/// `distance_m` that turns by `dtheta_rad`. The centre of the arc is
/// `C = p + rho (-sin theta, cos theta)` with `rho = distance / dtheta`
/// (the paper's `R + W/2`), and the new point `C + rho (sin theta', -cos theta')`
/// (eq. 2-3). Straight motion uses eq. 5-6. Returns the new pose, the heading
/// left unwrapped.
pub fn arc_step(
    x_m: f64,
    y_m: f64,
    theta_rad: f64,
    distance_m: f64,
    dtheta_rad: f64,
) -> (f64, f64, f64) {
    let theta_new = theta_rad + dtheta_rad;
    if dtheta_rad.abs() < STRAIGHT_EPS_RAD {
        return (
            x_m + distance_m * theta_new.cos(),
            y_m + distance_m * theta_new.sin(),
            theta_new,
        );
    }
    let rho = distance_m / dtheta_rad;
    let cx = x_m - rho * theta_rad.sin();
    let cy = y_m + rho * theta_rad.cos();
    (
        cx + rho * theta_new.sin(),
        cy - rho * theta_new.cos(),
        theta_new,
    )
}

/// First-order propagation of the pose covariance through a step of
/// `distance_m` along `theta_rad`, with independent noises on the distance
/// (`var_distance`) and on the heading change (`var_dtheta`).
pub(crate) fn propagate_covariance(
    p: &Matrix3<f64>,
    theta_rad: f64,
    distance_m: f64,
    var_distance: f64,
    var_dtheta: f64,
) -> Matrix3<f64> {
    let (s, c) = theta_rad.sin_cos();
    let f = Matrix3::new(
        1.0,
        0.0,
        -distance_m * s,
        0.0,
        1.0,
        distance_m * c,
        0.0,
        0.0,
        1.0,
    );
    let g = Matrix3x2::new(c, 0.0, s, 0.0, 0.0, 1.0);
    let n = Matrix2::new(var_distance, 0.0, 0.0, var_dtheta);
    let out = f * p * f.transpose() + g * n * g.transpose();
    (out + out.transpose()) * 0.5
}

/// Noise of dead reckoning per step, used to grow the reported covariance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeadReckoningNoise {
    /// Standard deviation of the travelled distance, as a fraction of it.
    pub distance_fraction: f64,
    /// Standard deviation of the heading change per metre travelled, in rad/m
    /// (slip grows with distance).
    pub heading_rad_per_m: f64,
    /// Standard deviation of the heading change per radian turned (scale
    /// error of the encoders or the gyro).
    pub heading_rad_per_rad: f64,
}

impl Default for DeadReckoningNoise {
    fn default() -> Self {
        Self {
            distance_fraction: 0.02,
            heading_rad_per_m: 1.0_f64.to_radians(),
            heading_rad_per_rad: 0.02,
        }
    }
}

impl DeadReckoningNoise {
    /// Variances `(distance, heading change)` for one step.
    pub(crate) fn variances(&self, distance_m: f64, dtheta_rad: f64) -> (f64, f64) {
        let sd = self.distance_fraction * distance_m.abs();
        let st =
            self.heading_rad_per_m * distance_m.abs() + self.heading_rad_per_rad * dtheta_rad.abs();
        (sd * sd, st * st)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn quarter_arc_ends_where_the_circle_says() {
        // Radius 1 m, quarter turn left from the origin heading +x: ends at (1, 1).
        let (x, y, th) = arc_step(0.0, 0.0, 0.0, FRAC_PI_2, FRAC_PI_2);
        assert!((x - 1.0).abs() < 1e-12 && (y - 1.0).abs() < 1e-12);
        assert!((th - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn straight_step_follows_heading() {
        let (x, y, _) = arc_step(1.0, 2.0, FRAC_PI_2, 0.5, 0.0);
        assert!((x - 1.0).abs() < 1e-12 && (y - 2.5).abs() < 1e-12);
    }

    #[test]
    fn encoder_ticks_give_distance_and_turn() {
        let geometry = super::super::WheelGeometry {
            wheel_base_m: 0.5,
            left_m_per_tick: 0.001,
            right_m_per_tick: 0.001,
        };
        let mut t = IncrementTracker::default();
        let e = |t_s, l, r| {
            Input::Encoders(EncoderSample {
                t_s,
                left_ticks: l,
                right_ticks: r,
                geometry,
            })
        };
        assert!(t.step(&e(0.0, 0, 0)).is_none());
        let inc = t.step(&e(0.1, 100, 200)).unwrap();
        assert!((inc.distance_m - 0.15).abs() < 1e-12);
        assert!((inc.dtheta_rad - 0.2).abs() < 1e-12);
        // Odometry is ignored once encoders are the source.
        let odo = Input::Odometry(OdometrySample {
            t_s: 0.2,
            x_m: 1.0,
            y_m: 0.0,
            theta_rad: 0.0,
        });
        assert!(t.step(&odo).is_none());
    }

    #[test]
    fn reversing_odometry_gives_negative_distance() {
        let mut t = IncrementTracker::default();
        let o = |t_s, x_m| {
            Input::Odometry(OdometrySample {
                t_s,
                x_m,
                y_m: 0.0,
                theta_rad: 0.0,
            })
        };
        t.step(&o(0.0, 1.0));
        let inc = t.step(&o(0.1, 0.9)).unwrap();
        assert!((inc.distance_m + 0.1).abs() < 1e-12);
    }
}
