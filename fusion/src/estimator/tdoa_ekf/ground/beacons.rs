//! Absolute ranges to beacons, with their bias and scale estimated: radio
//! beacons at the antenna's height, or beacons anywhere in the room (a
//! Marvelmind kit's stationary beacons, on walls or the ceiling, measured
//! from the receiver at its height above the floor).

use std::f64::consts::PI;

use super::{TdoaEkf, prior};
use crate::estimator::BeaconRangeSample;
use crate::estimator::tdoa_ekf::ground_state::{
    self as gs, RANGE_BIAS, RANGE_SCALE, Row, State, X, Y,
};
use crate::estimator::tdoa_ekf::observation::{Outcome, Rejection};

impl TdoaEkf {
    /// Without a start pose: starts where the ranges heard together put
    /// the receiver, heading unknown (found from the track, as after a
    /// start from arrivals).
    pub(in crate::estimator::tdoa_ekf) fn start_from_ranges(&mut self, r: &BeaconRangeSample) {
        let Some(fix) = self.range_start.add(r, self.params.receiver_height_m) else {
            return;
        };
        let mut x = State::zeros();
        x[X] = fix.x_m;
        x[Y] = fix.y_m;
        self.state = Some((x, prior(&self.params, fix.sigma_m, PI)));
        self.heading_from_track = Some(None);
    }

    /// Fuses one absolute range `range_m` (standard deviation `sigma_m`)
    /// to a beacon at `beacon_m` (`x, y`, same height as the antenna),
    /// measured at `t_s`, read as `(1 + scale) d + bias` with both estimated. Late (long)
    /// ranges are down-weighted and rejected like late arrivals.
    pub fn range(&mut self, t_s: f64, beacon_m: [f64; 2], range_m: f64, sigma_m: f64) -> Outcome {
        let beacon_m = [beacon_m[0], beacon_m[1], self.params.receiver_height_m];
        let out = self.range_update(t_s, beacon_m, range_m, sigma_m);
        self.t_s = self.t_s.max(t_s);
        self.last_outcome = Some(out);
        out
    }

    /// Fuses a range to a beacon at `beacon_m` (`x, y, z`) from the
    /// receiver at its height; the caller records the outcome.
    pub(in crate::estimator::tdoa_ekf) fn range_update(
        &mut self,
        t_s: f64,
        beacon_m: [f64; 3],
        range_m: f64,
        sigma_m: f64,
    ) -> Outcome {
        if ![t_s, beacon_m[0], beacon_m[1], beacon_m[2], range_m]
            .iter()
            .all(|v| v.is_finite())
        {
            return Outcome::Rejected(Rejection::NonFinite { field: "range" });
        }
        if !(sigma_m.is_finite() && sigma_m > 0.0) {
            return Outcome::Rejected(Rejection::BadSigma { sigma_m });
        }
        let Some((x, p)) = self.state else {
            return Outcome::Rejected(Rejection::NotInitialised);
        };
        let at = self.position_at(&x, t_s);
        let (dx, dy, dz) = (at.x - beacon_m[0], at.y - beacon_m[1], at.z - beacon_m[2]);
        let d = dx.hypot(dy).hypot(dz);
        if d < 1e-6 {
            return Outcome::Rejected(Rejection::Numerical);
        }
        let k = 1.0 + x[RANGE_SCALE];
        let mut h = Row::zeros();
        h[X] = k * dx / d;
        h[Y] = k * dy / d;
        h[RANGE_BIAS] = 1.0;
        h[RANGE_SCALE] = d;
        let nu = range_m - k * d - x[RANGE_BIAS];
        let r = sigma_m * sigma_m;
        let s = gs::innovation_variance(&p, &h, r);
        let normalised = nu / s.sqrt();
        if normalised.abs() > self.params.gate_sigma {
            // Only a range far shorter than predicted (impossible for a
            // late, non-direct path) is evidence of a lost filter.
            self.note(normalised < 0.0);
            return Outcome::Rejected(Rejection::Gate {
                normalised: normalised.abs(),
            });
        }
        let soft = self.params.late_soft_sigma;
        let r = if normalised > soft {
            r + s * ((normalised / soft).powi(2) - 1.0)
        } else {
            r
        };
        match gs::update(&x, &p, &h, nu, r) {
            Some(next) => {
                self.state = Some(next);
                self.note(false);
                self.adapt(normalised);
                self.project_on_floor();
                Outcome::Accepted {
                    innovation_m: nu,
                    normalised: normalised.abs(),
                }
            }
            None => Outcome::Rejected(Rejection::Numerical),
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    use crate::estimator::history::InOrderFilter;
    use crate::estimator::tdoa_ekf::{GroundNoise, TdoaEkf, TdoaEkfParams};
    use crate::estimator::{BeaconRangeSample, InitialPose, Input};

    /// A robot driving a 4 m circle under four ceiling beacons at 3 m, its
    /// receiver 0.3 m above the floor, ranging one beacon every 0.125 s
    /// with 2 cm of noise; the filter starts 0.3 m off.
    fn drive(
        params: &TdoaEkfParams,
        mut ranges: impl FnMut(f64, [f64; 3], Vector3<f64>) -> Option<f64>,
    ) -> (f64, f64) {
        let beacons = [
            [0.0, 0.0, 3.0],
            [6.0, 0.0, 3.0],
            [6.0, 6.0, 3.0],
            [0.0, 6.0, 3.0],
        ];
        let truth = |t: f64| {
            let a = 0.2 * t;
            (
                3.0 + 2.0 * a.cos(),
                3.0 + 2.0 * a.sin(),
                a + std::f64::consts::FRAC_PI_2,
            )
        };
        let (x0, y0, th0) = truth(0.0);
        let mut f = TdoaEkf::new(&TdoaEkfParams {
            initial_pose: Some(InitialPose {
                x_m: x0 + 0.3,
                y_m: y0,
                theta_rad: th0,
                sigma_xy_m: 0.5,
                sigma_theta_rad: 0.1,
            }),
            use_gyro: false,
            ..*params
        });
        let (mut sum, mut n, mut worst) = (0.0, 0, 0.0f64);
        for k in 1..=4000 {
            let t = 0.025 * f64::from(k);
            // 0.4 m/s along the circle.
            f.increment(t, 0.01, 0.005, 0.01, false);
            if k % 5 == 0 {
                let (x, y, _) = truth(t);
                let b = beacons[(k / 5) as usize % 4];
                let at = Vector3::new(x, y, params.receiver_height_m);
                if let Some(range_m) = ranges(t, b, at) {
                    f.step(&Input::BeaconRange(BeaconRangeSample {
                        t_s: t,
                        beacon_m: b,
                        range_m,
                        sigma_m: 0.02,
                    }));
                }
            }
            if t > 20.0 {
                let (x, y, _) = truth(t);
                let p = f.pose().expect("started");
                let e = (p.x_m - x).hypot(p.y_m - y);
                sum += e;
                n += 1;
                worst = worst.max(e);
            }
        }
        (sum / f64::from(n), worst)
    }

    #[test]
    fn ranges_to_ceiling_beacons_are_fused_in_three_dimensions() {
        let params = TdoaEkfParams {
            receiver_height_m: 0.3,
            ..TdoaEkfParams::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.02).expect("valid sigma");
        let (mean, worst) = drive(&params, |_, b, at| {
            let d = (at - Vector3::from(b)).norm();
            Some(d + noise.sample(&mut rng))
        });
        assert!(mean < 0.03 && worst < 0.1, "mean {mean} m, worst {worst} m");
    }

    #[test]
    fn without_a_start_pose_the_filter_starts_from_the_beacons_it_ranges() {
        // An ultrasonic kit's ranges: a bias of centimetres, a scale error
        // of the speed of sound's change over a few kelvin (0.18 %/K). With
        // a radio's priors (metres, 10 %) a robot standing still mistakes
        // part of the ranges' bias and scale for its position (7 cm here).
        let sensors = GroundNoise {
            range_bias_sigma_m: 0.05,
            range_scale_sigma: 0.005,
            ..GroundNoise::default()
        };
        let params = TdoaEkfParams {
            receiver_height_m: 0.3,
            initial_pose: None,
            sensors,
            ..TdoaEkfParams::default()
        };
        let beacons = [
            [0.0, 0.0, 3.0],
            [6.0, 0.0, 3.0],
            [6.0, 6.0, 3.0],
            [0.0, 6.0, 3.0],
        ];
        let mut f = TdoaEkf::new(&params);
        let at = Vector3::new(1.5, 4.0, 0.3);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let noise = Normal::new(0.0, 0.02).expect("valid sigma");
        for k in 0..80 {
            let b = beacons[k % 4];
            let t = 0.125 * k as f64;
            f.step(&Input::BeaconRange(BeaconRangeSample {
                t_s: t,
                beacon_m: b,
                range_m: (at - Vector3::from(b)).norm() + noise.sample(&mut rng),
                sigma_m: 0.02,
            }));
            if k < 2 {
                assert!(f.pose().is_none(), "started from {} beacon(s)", k + 1);
            }
        }
        let p = f.pose().expect("started from three beacons");
        let e = (p.x_m - at.x).hypot(p.y_m - at.y);
        assert!(e < 0.05, "{e} m off after 10 s of ranges: {p:?}");
    }

    #[test]
    fn a_range_shorter_than_the_beacons_height_is_refused() {
        // 2.7 m of height between receiver and beacon: no position gives
        // a range of 1 m; the filter must not be pulled by it.
        let params = TdoaEkfParams {
            receiver_height_m: 0.3,
            ..TdoaEkfParams::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let noise = Normal::new(0.0, 0.02).expect("valid sigma");
        let mut k = 0;
        let (mean, worst) = drive(&params, |_, b, at| {
            k += 1;
            if k % 7 == 0 {
                return Some(1.0);
            }
            Some((at - Vector3::from(b)).norm() + noise.sample(&mut rng))
        });
        assert!(
            mean < 0.04 && worst < 0.15,
            "mean {mean} m, worst {worst} m"
        );
    }
}
