//! The IMU error-state filter: the accelerometer and gyro drive the
//! nominal state (position, velocity, attitude, accelerometer and gyro
//! biases, body shadow, the anchors' excess paths of `excess.rs`), each
//! range difference corrects its 24-dimensional error `[dp, dv, dtheta,
//! dba, dbg, ds, de_1..de_8]` (attitude error in the body frame), and the
//! correction is injected into the nominal state (Sola,
//! "Quaternion kinematics for the error-state Kalman filter", 2017,
//! section 7). The antenna sits at a lever arm from the IMU: the range
//! differences see `p + R l`.
//!
//! Run under [`crate::estimator::guard::Guarded`]: until the watch places
//! it, the position is not published. The attitude is levelled once, from
//! the accelerometer averaged over the first half second of the log (the
//! vehicle is on the ground then: gravity dominates its specific force,
//! whereas in flight a quadrotor's accelerometer sees the thrust axis and
//! tenths of a g of vibration and drag), with the configured yaw, and is
//! carried by the gyro from there.

use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};

use super::excess::{EXCESS_SLOTS, ExcessSlots};
use super::imu_params::ImuParams;
use super::shadow;
use crate::estimator::guard::{FlightVolume, GuardedFilter};
use crate::estimator::tdoa_ekf::{Outcome, Rejection, gated_update};
use crate::estimator::{InvalidParameter, RangeDifferenceSample};

/// The states the IMU moves (all but the excess paths).
const C: usize = 16;
type MC = SMatrix<f64, C, C>;
/// First excess-path state.
const E: usize = C;
const N: usize = C + EXCESS_SLOTS;
type VN = SVector<f64, N>;
type MN = SMatrix<f64, N, N>;
const P: usize = 0;
const V: usize = 3;
const TH: usize = 6;
const BA: usize = 9;
const BG: usize = 12;
const S: usize = 15;

/// An IMU sample, body frame, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Time, seconds.
    pub t_s: f64,
    /// Specific force, m/s^2 (about `+g` up when at rest).
    pub accel_m_s2: [f64; 3],
    /// Angular rate, rad/s.
    pub gyro_rad_s: [f64; 3],
}

/// The error-state filter.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuFilter {
    params: ImuParams,
    t_s: f64,
    p_m: Vector3<f64>,
    v_m_s: Vector3<f64>,
    q: UnitQuaternion<f64>,
    ba: Vector3<f64>,
    bg: Vector3<f64>,
    shadow_m: f64,
    cov: MN,
    excess: ExcessSlots,
    /// The excess paths' nominal values (rows `E..`; the others unused).
    excess_m: VN,
    /// The last IMU sample, held until the next one.
    last: Option<ImuSample>,
    /// Sum of the specific forces (body) of the levelling window, their
    /// count, and the time of the first.
    level_sum: Vector3<f64>,
    level_n: u32,
    first_imu_s: Option<f64>,
    levelled: bool,
}

/// Length of the levelling window at the start of the log, seconds: long
/// against the vibration of idling motors, short against the take-off.
const LEVEL_WINDOW_S: f64 = 0.5;

impl ImuFilter {
    /// An unplaced filter.
    pub fn new(params: ImuParams) -> Result<Self, InvalidParameter> {
        params.validate()?;
        let mut cov = MN::identity();
        let sb = |s: f64| s * s;
        for k in 0..3 {
            cov[(BA + k, BA + k)] = sb(params.initial_accel_bias_sigma_m_s2);
            cov[(BG + k, BG + k)] = sb(params.initial_gyro_bias_sigma_rad_s);
        }
        cov[(S, S)] = if params.shadow_prior_sigma_m > 0.0 {
            sb(params.shadow_prior_sigma_m)
        } else {
            1.0
        };
        let excess = ExcessSlots::new(params.excess, E);
        excess.init(&mut cov);
        Ok(Self {
            params,
            t_s: f64::NEG_INFINITY,
            p_m: Vector3::zeros(),
            v_m_s: Vector3::zeros(),
            q: UnitQuaternion::from_euler_angles(0.0, 0.0, params.initial_yaw_rad),
            ba: Vector3::zeros(),
            bg: Vector3::zeros(),
            shadow_m: params.shadow_m,
            cov,
            excess,
            excess_m: VN::zeros(),
            last: None,
            level_sum: Vector3::zeros(),
            level_n: 0,
            first_imu_s: None,
            levelled: false,
        })
    }

    /// Attitude, body to world, `[x, y, z, w]`.
    pub fn attitude_xyzw(&self) -> [f64; 4] {
        let c = self.q.coords;
        [c.x, c.y, c.z, c.w]
    }

    /// The body shadow estimate and its standard deviation, metres.
    pub fn shadow_m(&self) -> (f64, f64) {
        (self.shadow_m, self.cov[(S, S)].sqrt())
    }

    /// Accelerometer and gyro bias estimates (m/s^2, rad/s).
    pub fn biases(&self) -> ([f64; 3], [f64; 3]) {
        (self.ba.into(), self.bg.into())
    }

    /// Integrates up to `s.t_s` with the previous sample, then holds `s`.
    /// Non-finite samples are ignored.
    pub fn imu(&mut self, s: &ImuSample) {
        let finite = s.t_s.is_finite()
            && s.accel_m_s2
                .iter()
                .chain(&s.gyro_rad_s)
                .all(|v| v.is_finite());
        if !finite {
            return;
        }
        if self.last.is_some() {
            self.propagate_to(s.t_s);
        }
        // The IMU stream is the filter's clock: when it steps back by more
        // than a gap (the receiver's clock was set back), the filter
        // follows it. Otherwise it would stop integrating until the old
        // time came round again while the vehicle kept moving; the watch
        // sees the same jump in the range differences and re-places it.
        if self.t_s < s.t_s || self.t_s - s.t_s > self.params.max_imu_gap_s {
            self.t_s = s.t_s;
        }
        if !self.levelled {
            let first = *self.first_imu_s.get_or_insert(s.t_s);
            self.level_sum += Vector3::from(s.accel_m_s2);
            self.level_n += 1;
            if s.t_s - first >= LEVEL_WINDOW_S {
                self.level();
            }
        }
        self.last = Some(*s);
    }

    /// Integrates the held sample from the state's time to `t_s`.
    fn propagate_to(&mut self, t_s: f64) {
        let Some(imu) = self.last else { return };
        let dt = t_s - self.t_s;
        if dt.is_nan() || dt <= 0.0 {
            return;
        }
        if dt > self.params.max_imu_gap_s {
            // A gap: nothing to integrate across; the watch restarts.
            self.t_s = t_s;
            return;
        }
        let r = self.q.to_rotation_matrix().into_inner();
        let mut a_b = Vector3::from(imu.accel_m_s2) - self.ba;
        if self.params.thrust_axis_only {
            a_b.x = 0.0;
            a_b.y = 0.0;
        }
        let w = Vector3::from(imu.gyro_rad_s) - self.bg;
        let g = Vector3::new(0.0, 0.0, -self.params.gravity_m_s2);
        let a_w = r * a_b + g;
        if self.levelled {
            self.p_m += self.v_m_s * dt + a_w * (0.5 * dt * dt);
            self.v_m_s += a_w * dt;
        }
        let dq = UnitQuaternion::from_scaled_axis(w * dt);
        self.q *= dq;
        let mut f = MC::identity();
        let i3 = Matrix3::identity();
        f.fixed_view_mut::<3, 3>(P, V).copy_from(&(i3 * dt));
        f.fixed_view_mut::<3, 3>(V, TH)
            .copy_from(&(-r * skew(&a_b) * dt));
        let mut dba = -r * dt;
        if self.params.thrust_axis_only {
            // The horizontal channels are not used: nor are their biases.
            dba.column_mut(0).fill(0.0);
            dba.column_mut(1).fill(0.0);
        }
        f.fixed_view_mut::<3, 3>(V, BA).copy_from(&dba);
        f.fixed_view_mut::<3, 3>(TH, TH)
            .copy_from(&dq.to_rotation_matrix().into_inner().transpose());
        f.fixed_view_mut::<3, 3>(TH, BG).copy_from(&(-i3 * dt));
        let pr = &self.params;
        let mut q = MC::zeros();
        for k in 0..3 {
            q[(V + k, V + k)] = pr.accel_noise_m_s2_rt_hz.powi(2) * dt;
            q[(TH + k, TH + k)] = pr.gyro_noise_rad_s_rt_hz.powi(2) * dt;
            q[(BA + k, BA + k)] = pr.accel_bias_walk_m_s3_rt_hz.powi(2) * dt;
            q[(BG + k, BG + k)] = pr.gyro_bias_walk_rad_s2_rt_hz.powi(2) * dt;
        }
        let mut cov = predict_moved(&self.cov, &f, &q);
        let mut excess_m = self.excess_m;
        self.excess.decay(&mut excess_m, &mut cov, dt);
        if cov.iter().chain(excess_m.iter()).all(|v| v.is_finite()) {
            self.cov = cov;
            self.excess_m = excess_m;
        }
        self.t_s = t_s;
    }

    fn antenna_m(&self) -> Vector3<f64> {
        self.p_m + self.q * Vector3::from(self.params.antenna_body_m)
    }

    /// The predicted range difference (excess paths included) and its row
    /// of `H`.
    fn linearise(&self, m: &RangeDifferenceSample) -> Option<(f64, SMatrix<f64, 1, N>)> {
        let l = shadow::linearise(&self.antenna_m(), m, self.shadow_m)?;
        let (mut h, excess_m) = self.excess.observe(&self.excess_m, m);
        let r = self.q.to_rotation_matrix().into_inner();
        let lever = Vector3::from(self.params.antenna_body_m);
        h.fixed_view_mut::<1, 3>(0, P)
            .copy_from(&l.gradient.transpose());
        // d(R exp(dtheta) l) = -R [l]x dtheta.
        h.fixed_view_mut::<1, 3>(0, TH)
            .copy_from(&(-l.gradient.transpose() * r * skew(&lever)));
        // Held: no column in H.
        if self.params.shadow_prior_sigma_m > 0.0 {
            h[(0, S)] = l.d_shadow;
        }
        Some((l.predicted_m + excess_m, h))
    }

    /// The excess-path estimates of the anchors heard lately: `(anchor,
    /// metres, standard deviation)`.
    pub fn excess_paths_m(&self) -> Vec<([f64; 3], f64, f64)> {
        self.excess.estimates(&self.excess_m, &self.cov)
    }

    /// Levels the attitude from the averaged specific force, with the
    /// configured yaw.
    fn level(&mut self) {
        if self.level_n == 0 {
            return;
        }
        let f = self.level_sum / f64::from(self.level_n);
        if f.norm() < 1.0 {
            return;
        }
        let f = f.normalize();
        let roll = f.y.atan2(f.z);
        let pitch = (-f.x).atan2((f.y * f.y + f.z * f.z).sqrt());
        let yaw = self.params.initial_yaw_rad;
        self.q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
        let (tilt, yaw_s) = (
            self.params.initial_tilt_sigma_rad,
            self.params.initial_yaw_sigma_rad,
        );
        self.cov.fixed_view_mut::<3, N>(TH, 0).fill(0.0);
        self.cov.fixed_view_mut::<N, 3>(0, TH).fill(0.0);
        // Body-frame error: yaw uncertainty mostly on the body z axis when
        // level.
        self.cov[(TH, TH)] = tilt * tilt;
        self.cov[(TH + 1, TH + 1)] = tilt * tilt;
        self.cov[(TH + 2, TH + 2)] = yaw_s * yaw_s;
        self.levelled = true;
    }
}

/// `P <- F P F^T + Q` where `F` and `Q` act on the states the IMU moves;
/// the excess paths' own transition is their decay, applied after. Cheaper
/// than the whole matrix product at the IMU's rate.
fn predict_moved(cov: &MN, f: &MC, q: &MC) -> MN {
    let mut out = *cov;
    let moved = crate::estimator::kf::predict(&cov.fixed_view::<C, C>(0, 0).into_owned(), f, q);
    out.fixed_view_mut::<C, C>(0, 0).copy_from(&moved);
    let cross = f * cov.fixed_view::<C, EXCESS_SLOTS>(0, E);
    out.fixed_view_mut::<C, EXCESS_SLOTS>(0, E)
        .copy_from(&cross);
    out.fixed_view_mut::<EXCESS_SLOTS, C>(E, 0)
        .copy_from(&cross.transpose());
    out
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

impl GuardedFilter for ImuFilter {
    fn predict_to(&mut self, t_s: f64) {
        self.propagate_to(t_s);
    }

    fn position_m(&self) -> Vector3<f64> {
        self.antenna_m()
    }

    fn position_sigma_m(&self) -> f64 {
        crate::estimator::kf::largest_axis_sigma(&self.cov, P)
    }

    /// The body's position covariance: what the attitude's uncertainty
    /// adds through the antenna's lever arm (millimetres for a lever of
    /// centimetres) is left out.
    fn position_covariance_m2(&self) -> nalgebra::Matrix3<f64> {
        self.cov.fixed_view::<3, 3>(P, P).into_owned()
    }

    fn predicted_m(&self, m: &RangeDifferenceSample) -> Option<f64> {
        self.linearise(m).map(|(predicted_m, _)| predicted_m)
    }

    fn update(&mut self, m: &RangeDifferenceSample) -> Outcome {
        self.excess.assign(&mut self.excess_m, &mut self.cov, m);
        let Some((predicted_m, h)) = self.linearise(m) else {
            return Outcome::Rejected(Rejection::Numerical);
        };
        let r = self.q.to_rotation_matrix().into_inner();
        let (dx, cov, outcome) = match gated_update(
            &VN::zeros(),
            &self.cov,
            &h,
            m.d_m - predicted_m,
            m.sigma_m,
            self.params.gate_sigma,
        ) {
            Ok(ok) => ok,
            Err(r) => return Outcome::Rejected(r),
        };
        let mut dx = dx;
        if self.params.thrust_axis_only {
            // With the specific force along body z, rotating about the
            // vertical changes no prediction: yaw and the vertical gyro
            // bias are unobservable from range differences (but for the
            // centimetre of horizontal lever arm), and a correction to
            // them is an artefact of the linearisation. Drop it.
            for block in [TH, BG] {
                let mut w = r * dx.fixed_rows::<3>(block);
                w.z = 0.0;
                dx.fixed_rows_mut::<3>(block)
                    .copy_from(&(r.transpose() * w));
            }
        }
        self.p_m += dx.fixed_rows::<3>(P);
        self.v_m_s += dx.fixed_rows::<3>(V);
        self.q *= UnitQuaternion::from_scaled_axis(dx.fixed_rows::<3>(TH).into_owned());
        self.ba += dx.fixed_rows::<3>(BA);
        self.bg += dx.fixed_rows::<3>(BG);
        // A body can only delay a signal: the shadow is one-sided.
        self.shadow_m = (self.shadow_m + dx[S]).max(0.0);
        for i in E..N {
            self.excess_m[i] += dx[i];
        }
        self.excess.clamp(&mut self.excess_m);
        self.cov = cov;
        outcome
    }

    fn reset(&mut self, t_s: f64, position_m: Vector3<f64>, sigma_m: f64) {
        if !self.levelled {
            self.level();
        }
        if self.levelled {
            self.propagate_to(t_s);
        }
        if self.t_s < t_s {
            self.t_s = t_s;
        }
        self.p_m = position_m - self.q * Vector3::from(self.params.antenna_body_m);
        self.v_m_s = Vector3::zeros();
        // Position and velocity start afresh; attitude, biases and shadow
        // belong to the vehicle and are kept.
        self.cov.fixed_view_mut::<6, N>(0, 0).fill(0.0);
        self.cov.fixed_view_mut::<N, 6>(0, 0).fill(0.0);
        let sv = self.params.initial_velocity_sigma_m_s;
        for k in 0..3 {
            self.cov[(P + k, P + k)] = sigma_m * sigma_m;
            self.cov[(V + k, V + k)] = sv * sv;
        }
    }

    /// The IMU carries position, velocity and attitude through the time
    /// the watch holds the filter lost (once levelled).
    fn tracks_while_lost(&self) -> bool {
        self.levelled
    }

    fn constrain(&mut self, volume: &FlightVolume) -> bool {
        let a = self.antenna_m();
        let (q, moved) = volume.clamp(&a);
        if moved.iter().any(|&m| m) {
            self.p_m += q - a;
            for (k, _) in moved.iter().enumerate().filter(|m| *m.1) {
                self.v_m_s[k] = 0.0;
            }
            return true;
        }
        false
    }
}
