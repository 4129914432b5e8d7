//! Dead reckoning between absolute measurements: gyro and wheel
//! increments move the state on and grow its uncertainty.

use nalgebra::Vector3;

use super::TdoaEkf;
use crate::estimator::Input;
use crate::estimator::tdoa_ekf::ground_state::{
    self as gs, BIAS, RANGE_BIAS, Row, SOUND_SCALE, State, Step, TH, WIND_X, WIND_Y, X, Y,
};
use crate::estimator::tdoa_ekf::observation;
use crate::estimator::tdoa_ekf::standstill;

impl TdoaEkf {
    pub(super) fn gyro_sample(&mut self, t_s: f64, rate_rad_s: f64) {
        if let Some((t0, rate0)) = self.gyro.replace((t_s, rate_rad_s)) {
            let dt = t_s - t0;
            if dt > 0.0 && dt <= self.params.max_gyro_gap_s {
                self.gyro_turn_rad += rate0 * dt;
                self.gyro_time_s += dt;
            }
        }
    }

    pub(super) fn relative(&mut self, input: &Input) {
        let Some(inc) = self.increments.step(input) else {
            return;
        };
        let gyro_running = self.params.use_gyro
            && self
                .gyro
                .is_some_and(|(t, _)| (inc.t_s - t).abs() <= self.params.max_gyro_gap_s);
        let (dtheta, turn_time) = if gyro_running {
            (self.gyro_turn_rad, self.gyro_time_s)
        } else {
            (inc.dtheta_rad, inc.dt_s.max(0.0))
        };
        self.gyro_turn_rad = 0.0;
        self.gyro_time_s = 0.0;
        let standing = self.standstill.note(&inc);
        if gyro_running && standing && turn_time > 0.0 && self.heading_from_track.is_none() {
            // Nothing turned: the heading holds, and the gyro read its bias.
            self.increment(inc.t_s, 0.0, 0.0, 0.0, true);
            let var = self.params.sensors.var_gyro_turn(turn_time) / turn_time.powi(2);
            self.gyro_bias_at_rest(dtheta / turn_time, var);
            return;
        }
        self.increment(inc.t_s, inc.distance_m, dtheta, turn_time, gyro_running);
    }

    /// The gyro's mean rate `rate_rad_s` (variance `var`) over a stretch
    /// in which the robot stood still: a measurement of its bias
    /// ([`standstill`]), gated.
    fn gyro_bias_at_rest(&mut self, rate_rad_s: f64, var: f64) {
        let Some((x, p)) = &mut self.state else {
            return;
        };
        if !(rate_rad_s.is_finite() && var.is_finite() && var > 0.0) {
            return;
        }
        let mut h = Row::zeros();
        h[BIAS] = 1.0;
        let nu = rate_rad_s - x[BIAS];
        if let Ok((nx, np, _)) =
            observation::gated_update(x, p, &h, nu, var.sqrt(), standstill::GATE_SIGMAS)
        {
            *x = nx;
            *p = np;
        }
    }

    /// One dead-reckoning step ending at `t_s`: `distance_m` driven (signed)
    /// while the heading source turned by `dtheta_rad` over `turn_time_s`
    /// (bias included); `from_gyro` says whose noise applies. For callers
    /// that drive the filter directly from their own increments.
    pub fn increment(
        &mut self,
        t_s: f64,
        distance_m: f64,
        dtheta_rad: f64,
        turn_time_s: f64,
        from_gyro: bool,
    ) {
        if ![t_s, distance_m, dtheta_rad, turn_time_s]
            .iter()
            .all(|v| v.is_finite())
        {
            return;
        }
        let dt = if self.state_t_s.is_finite() {
            (t_s - self.state_t_s).max(0.0)
        } else {
            turn_time_s.max(0.0)
        };
        self.state_t_s = t_s;
        self.t_s = self.t_s.max(t_s);
        self.speed_m_s = if dt > 0.0 { distance_m / dt } else { 0.0 };
        let Some((x, p)) = &mut self.state else {
            return;
        };
        if let Some(track) = &mut self.heading_from_track {
            // Heading unknown: the robot may have driven anywhere within the
            // distance since the position was last measured. Growing the
            // variance by each step's square instead let a robot at 0.3 m/s
            // drift 8 cm between cycles while the filter claimed 1.5 cm: its
            // updates were gated out, the filter counted itself lost and
            // re-placed, and the heading's chord started again (a restarted
            // MSU took 5-10 s to find its heading).
            let before = self.unknown_heading_drift_m;
            self.unknown_heading_drift_m += distance_m.abs();
            let v = self.unknown_heading_drift_m.powi(2) - before.powi(2);
            p[(X, X)] += v;
            p[(Y, Y)] += v;
            if let Some(start) = track {
                start.turn_rad += dtheta_rad;
            }
            return;
        }
        let n = &self.params.sensors;
        let omega = if dt > 0.0 { dtheta_rad / dt } else { 0.0 };
        let (var_dtheta, walk) = if from_gyro {
            (n.var_gyro_turn(turn_time_s), n.gyro_bias_walk_deg_s_sqrt_s)
        } else {
            (
                n.var_wheel_turn(dtheta_rad, distance_m),
                n.wheel_bias_walk_deg_s_sqrt_s,
            )
        };
        let step = Step {
            distance_m,
            dtheta_rad,
            turn_time_s,
            var_distance: n.var_distance(distance_m, omega),
            var_dtheta,
            var_bias: walk.to_radians().powi(2) * dt,
        };
        if let Some((mut nx, mut np)) = gs::predict(x, p, &step) {
            np[(RANGE_BIAS, RANGE_BIAS)] += n.range_bias_walk_m_sqrt_s.powi(2) * dt;
            for (c, sigma_m) in self.clocks.used() {
                np[(c, c)] += n.var_clock_walk(sigma_m, dt);
            }
            if n.learns_local_wind() {
                let memory = n.local_air_memory(distance_m, dt);
                for k in [WIND_X, WIND_Y] {
                    gs::forget(&mut nx, &mut np, k, memory, n.local_wind_rel_sigma());
                }
            }
            if n.learns_local_air() {
                let memory = n.local_air_memory(distance_m, dt);
                gs::forget(
                    &mut nx,
                    &mut np,
                    SOUND_SCALE,
                    memory,
                    n.local_air_rel_sigma(),
                );
            }
            *x = nx;
            *p = np;
            self.project_on_floor();
        }
    }

    /// The receiver position at time `t_s`: the state's, moved on along
    /// the heading at the last step's speed.
    pub(super) fn position_at(&self, x: &State, t_s: f64) -> Vector3<f64> {
        let dt = if self.state_t_s.is_finite() {
            t_s - self.state_t_s
        } else {
            0.0
        };
        let (s, c) = x[TH].sin_cos();
        let ds = self.speed_m_s * dt;
        Vector3::new(x[X] + ds * c, x[Y] + ds * s, self.params.receiver_height_m)
    }
}
