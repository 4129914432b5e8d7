//! The estimators `ickon replay util` compares, fed one measurement at a
//! time, each answering its estimates as `(t_s, position_m)`.
//!
//! - `tdoa-ekf`: the constant-velocity filter with the body shadow
//!   ([`CvFilter`]) under the watch of [`Guarded`] (placed from a
//!   consistent window before publishing, kept in the flight volume, late
//!   anchors set aside, lost filters re-placed), one parameter set for
//!   every UTIL flight ([`util_cv_params`], [`util_guard_params`]), causal;
//! - `imu-eskf`: the same watch over the IMU error-state filter
//!   ([`ImuFilter`], [`util_imu_params`]), when the file has the IMU;
//! - `cv-ekf`: the baseline, a plain constant-velocity EKF with a 3-sigma
//!   gate ([`TdoaEkf3d`] with no shadow), started at the anchors' centroid
//!   and publishing from the first measurement;
//! - `window-gn`: the pairwise Gauss-Newton solver of `fusion::tdoa`
//!   ([`refine_pairs`]) on consecutive windows of [`WINDOW_S`], with the
//!   physical check first and one pass of residual rejection; its estimate
//!   is stamped at the mean time of the measurements it used (so it lags
//!   the newest measurement by about half a window).

use std::collections::HashMap;

use ickon_fusion::estimator::RangeDifferenceSample;
use ickon_fusion::estimator::flight::{CvFilter, CvParams, ExcessParams, ImuFilter, ImuParams};
use ickon_fusion::estimator::guard::{
    FlightVolume, GuardCounts, GuardParams, Guarded, GuardedFilter,
};
use ickon_fusion::estimator::tdoa_ekf::{Outcome, Rejection, TdoaEkf3d, TdoaEkf3dParams};
use ickon_fusion::tdoa::{PairMeasurement, RefineConfig, refine_pairs};
use nalgebra::{Matrix3, Vector3};

/// Standard deviation given to every UTIL range difference, metres: the
/// RMS of the measurements against the truth on the TDoA2 flights is about
/// 0.09 m (data README), rounded up.
pub const MEASUREMENT_SIGMA_M: f64 = 0.1;

/// Length of the windows of `window-gn`, seconds: about 45 TDoA2 or 28
/// TDoA3 measurements, several per anchor pair, during which a flying tag
/// moves a few centimetres.
pub const WINDOW_S: f64 = 0.1;

/// The baseline `cv-ekf`: a plain constant-velocity EKF with a 3-sigma
/// innovation gate and no body model (the data set's own reference
/// filter), `accel_psd_m2_s3 = 1` (a quadrotor flying indoor patterns
/// changes velocity by about 1 m/s within a second), started at the
/// anchors' centroid within 2 m, at rest within 1 m/s.
pub fn baseline_params() -> TdoaEkf3dParams {
    TdoaEkf3dParams {
        accel_psd_m2_s3: 1.0,
        initial_sigma_m: 2.0,
        initial_velocity_sigma_m_s: 1.0,
        gate_sigma: 3.0,
        propagation_speed_m_s: 299_792_458.0,
        shadow_bias_m: 0.0,
        ..TdoaEkf3dParams::default()
    }
}

/// The body shadow of the UTIL drone, derived from its geometry before
/// any flight: a signal from an anchor straight below crosses the airframe
/// under the antenna, whose extent is the antenna's height above the body
/// centre (0.0908 m, the lever arm in the data README). Not sized on any
/// flight's truth.
pub const UTIL_SHADOW_M: f64 = 0.0908;

/// What a user may override for a parameter study; `None` keeps the
/// choice documented at [`util_cv_params`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Overrides {
    /// Acceleration density of `tdoa-ekf`, m^2/s^3.
    pub accel_psd_m2_s3: Option<f64>,
    /// The body shadow, metres.
    pub shadow_m: Option<f64>,
    /// Prior standard deviation of an online shadow estimate, metres.
    pub shadow_prior_sigma_m: Option<f64>,
    /// Standard deviation of each anchor's excess path, metres.
    pub excess_sigma_m: Option<f64>,
}

/// The anchors' excess paths in the UTIL arena, sized from its geometry
/// before any flight was scored: a signal reflected off the floor or off
/// the wooden shelf beside the flight area, or crossing it, travels about
/// a decimetre further than the straight line at the heights flown (a
/// standard deviation of 0.1 m); it lasts about as long as the vehicle
/// takes to cross the reflecting patch at its speed of about 1 m/s (a
/// correlation time of 1 s).
pub fn util_excess_params(o: Overrides) -> ExcessParams {
    ExcessParams {
        sigma_m: o.excess_sigma_m.unwrap_or(0.1),
        correlation_s: 1.0,
    }
}

/// The UTIL vehicle's vertical acceleration density as a share of its
/// horizontal one, from its flight plans before any flight was scored: the
/// most vertical of them (data README) is a sine of +-0.5 m along circles
/// of 1.5 m radius, a vertical acceleration at most a third of the
/// horizontal one; a density goes as the square of the acceleration, so a
/// tenth.
pub const UTIL_VERTICAL_PSD_RATIO: f64 = 0.1;

/// `tdoa-ekf`'s filter on UTIL flights: the library defaults
/// ([`CvParams::default`]: 1 m^2/s^3 as for the baseline, 3 sigma) with
/// the vehicle's vertical share [`UTIL_VERTICAL_PSD_RATIO`], the
/// drone's body shadow [`UTIL_SHADOW_M`], held (not estimated: online, it
/// is nearly the signature of a height error and wandered, see the
/// README's leave-one-out), and the arena's excess paths
/// ([`util_excess_params`]).
pub fn util_cv_params(o: Overrides) -> CvParams {
    let d = CvParams::default();
    CvParams {
        accel_psd_m2_s3: o.accel_psd_m2_s3.unwrap_or(d.accel_psd_m2_s3),
        vertical_psd_ratio: UTIL_VERTICAL_PSD_RATIO,
        shadow_m: o.shadow_m.unwrap_or(UTIL_SHADOW_M),
        shadow_prior_sigma_m: o.shadow_prior_sigma_m.unwrap_or(0.0),
        excess: util_excess_params(o),
        ..d
    }
}

/// `imu-eskf`'s filter: the library defaults ([`ImuParams::default`], all
/// chosen from the IMU's class, none fitted to this data), the UTIL
/// antenna lever arm, the start yaw, the same body shadow and excess paths
/// as `tdoa-ekf`, and the multirotor's thrust-axis model (`thrust_axis_only`: the UTIL
/// vehicle is a quadrotor; in flight its accelerometer's horizontal
/// channels read a tenth to a quarter of a g while it hovers level).
pub fn util_imu_params(antenna_body_m: [f64; 3], initial_yaw_rad: f64, o: Overrides) -> ImuParams {
    let d = ImuParams::default();
    ImuParams {
        antenna_body_m,
        initial_yaw_rad,
        shadow_m: o.shadow_m.unwrap_or(UTIL_SHADOW_M),
        shadow_prior_sigma_m: o.shadow_prior_sigma_m.unwrap_or(0.0),
        thrust_axis_only: true,
        excess: util_excess_params(o),
        ..d
    }
}

/// The watch's parameters: the library defaults
/// ([`GuardParams::default`]), each explained where it is defined.
pub fn util_guard_params() -> GuardParams {
    GuardParams::default()
}

/// Rejections of one estimator, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Rejections {
    /// `|d|` longer than the anchors' distance.
    pub physical: u64,
    /// Outside the innovation gate (EKF) or the residual gate (window).
    pub gate: u64,
    /// Numerically refused, or in a window that gave no fix.
    pub other: u64,
}

impl Rejections {
    /// All of them.
    pub fn total(&self) -> u64 {
        self.physical + self.gate + self.other
    }
}

/// A filter under the watch on a UTIL flight.
pub struct GuardedRunner<F> {
    guard: Guarded<F>,
    /// Rejections so far (measurements of anchors set aside count as
    /// `other`).
    pub rejections: Rejections,
    /// Time of the first published estimate, seconds.
    pub first_published_s: Option<f64>,
}

impl<F: GuardedFilter> GuardedRunner<F> {
    /// Watches `filter` in `volume`.
    pub fn new(filter: F, volume: FlightVolume, params: GuardParams) -> Self {
        Self {
            guard: Guarded::new(filter, volume, params, None),
            rejections: Rejections::default(),
            first_published_s: None,
        }
    }

    /// What the watch did.
    pub fn counts(&self) -> GuardCounts {
        self.guard.counts()
    }

    /// The filter (for the IMU and the final state).
    pub fn filter(&self) -> &F {
        self.guard.filter()
    }

    /// The covariance of the position the filter publishes, m^2.
    pub fn covariance_m2(&self) -> Matrix3<f64> {
        self.guard.filter().position_covariance_m2()
    }

    /// The filter, to feed it the IMU.
    pub fn filter_mut(&mut self) -> &mut F {
        self.guard.filter_mut()
    }

    /// Fuses one measurement; the published estimate at its time, if any.
    pub fn step(&mut self, m: &RangeDifferenceSample) -> Option<(f64, [f64; 3])> {
        let step = self.guard.step(m);
        match step.outcome {
            Some(Outcome::Accepted { .. }) => {}
            Some(Outcome::Rejected(Rejection::Physical { .. })) => self.rejections.physical += 1,
            Some(Outcome::Rejected(Rejection::Gate { .. })) => self.rejections.gate += 1,
            Some(Outcome::Rejected(_)) => self.rejections.other += 1,
            None if self.guard.is_placed() => self.rejections.other += 1,
            None => {}
        }
        let p = step.published_m?;
        self.first_published_s.get_or_insert(m.t_s);
        Some((m.t_s, p))
    }
}

/// `tdoa-ekf` on a UTIL flight.
pub type CvRunner = GuardedRunner<CvFilter>;
/// `imu-eskf` on a UTIL flight.
pub type ImuRunner = GuardedRunner<ImuFilter>;

/// The baseline `cv-ekf` on a UTIL flight.
pub struct EkfRunner {
    params: TdoaEkf3dParams,
    start_m: [f64; 3],
    filter: Option<TdoaEkf3d>,
    /// Rejections so far.
    pub rejections: Rejections,
}

impl EkfRunner {
    /// Starts at `start_m` with `params` at the first measurement.
    pub fn new(params: TdoaEkf3dParams, start_m: [f64; 3]) -> Self {
        Self {
            params,
            start_m,
            filter: None,
            rejections: Rejections::default(),
        }
    }

    /// The covariance of the position, m^2 (`None` before the first
    /// measurement).
    pub fn covariance_m2(&self) -> Option<Matrix3<f64>> {
        self.filter
            .as_ref()
            .map(|f| f.covariance().fixed_view::<3, 3>(0, 0).into_owned())
    }

    /// Times the filter widened its variance after finding itself lost.
    pub fn recoveries(&self) -> u64 {
        self.filter.as_ref().map_or(0, TdoaEkf3d::recoveries)
    }

    /// Fuses one measurement; the estimate at its time.
    pub fn step(&mut self, m: &RangeDifferenceSample) -> Option<(f64, [f64; 3])> {
        let filter = match &mut self.filter {
            Some(f) => f,
            None => self
                .filter
                .insert(TdoaEkf3d::new(self.params, self.start_m, m.t_s).ok()?),
        };
        filter.predict_to(m.t_s);
        match filter.update_range_difference(m) {
            Outcome::Accepted { .. } => {}
            Outcome::Rejected(Rejection::Physical { .. }) => self.rejections.physical += 1,
            Outcome::Rejected(Rejection::Gate { .. }) => self.rejections.gate += 1,
            Outcome::Rejected(_) => self.rejections.other += 1,
        }
        Some((filter.t_s(), filter.position_m()))
    }
}

/// `window-gn` on a UTIL flight.
pub struct WindowRunner {
    config: RefineConfig,
    window: Vec<(f64, PairMeasurement)>,
    window_start_s: Option<f64>,
    last_m: Vector3<f64>,
    sigma_m: f64,
    /// Rejections so far.
    pub rejections: Rejections,
}

impl WindowRunner {
    /// Starts its first solve from `start_m`, later ones from the previous
    /// solution.
    pub fn new(start_m: [f64; 3]) -> Self {
        Self::with_sigma(start_m, MEASUREMENT_SIGMA_M)
    }

    /// The same, for measurements of standard deviation `sigma_m`.
    pub fn with_sigma(start_m: [f64; 3], sigma_m: f64) -> Self {
        Self {
            config: RefineConfig {
                sigma_m,
                ..RefineConfig::default()
            },
            window: Vec::new(),
            window_start_s: None,
            last_m: Vector3::from(start_m),
            sigma_m,
            rejections: Rejections::default(),
        }
    }

    /// Time of the first measurement of the open window: its estimate
    /// will not be older.
    pub fn window_start_s(&self) -> Option<f64> {
        self.window_start_s
    }

    /// Adds one measurement; when it closes a window, the window's estimate.
    pub fn step(&mut self, m: &RangeDifferenceSample) -> Option<(f64, [f64; 3])> {
        let start = *self.window_start_s.get_or_insert(m.t_s);
        let mut out = None;
        if m.t_s >= start + WINDOW_S {
            out = self.solve();
            self.window.clear();
            self.window_start_s = Some(m.t_s);
        }
        if m.d_m.abs() > m.baseline_m() {
            self.rejections.physical += 1;
        } else {
            let pair = PairMeasurement {
                a_m: Vector3::from(m.a_m),
                b_m: Vector3::from(m.b_m),
                d_m: m.d_m,
            };
            self.window.push((m.t_s, pair));
        }
        out
    }

    /// Solves the open window (call once at the end of the file).
    pub fn finish(&mut self) -> Option<(f64, [f64; 3])> {
        let out = self.solve();
        self.window.clear();
        out
    }

    fn solve(&mut self) -> Option<(f64, [f64; 3])> {
        let pairs: Vec<PairMeasurement> = self.window.iter().map(|(_, p)| *p).collect();
        let Ok(first) = refine_pairs(&pairs, self.last_m, &self.config) else {
            self.rejections.other += pairs.len() as u64;
            return None;
        };
        // One pass of residual rejection at 3 sigma, then the final solve.
        let gate_m = 3.0 * self.sigma_m;
        let keep: Vec<usize> = (0..pairs.len())
            .filter(|&i| first.residuals_m[i].abs() <= gate_m)
            .collect();
        self.rejections.gate += (pairs.len() - keep.len()) as u64;
        let kept: Vec<PairMeasurement> = keep.iter().map(|&i| pairs[i]).collect();
        let solution = if kept.len() == pairs.len() {
            first
        } else {
            match refine_pairs(&kept, first.position_m, &self.config) {
                Ok(s) => s,
                Err(_) => {
                    self.rejections.other += kept.len() as u64;
                    return None;
                }
            }
        };
        self.last_m = solution.position_m;
        let t_s = keep.iter().map(|&i| self.window[i].0).sum::<f64>() / keep.len() as f64;
        let p = solution.position_m;
        Some((t_s, [p.x, p.y, p.z]))
    }
}

/// The anchors' centroid, the start of the baseline (no truth used).
pub fn centroid(anchors: &HashMap<u32, [f64; 3]>) -> [f64; 3] {
    let n = anchors.len().max(1) as f64;
    std::array::from_fn(|k| anchors.values().map(|a| a[k]).sum::<f64>() / n)
}
