//! Validation of estimator parameters at the edge, so that a bad config is
//! reported once by name instead of making every input fail later.

use super::InitialPose;
use super::cda::CdaParams;
use super::dead_reckoning::DeadReckoningNoise;
use super::gyro_ckf::GyroCkfParams;
use super::heading_kf::HeadingKfParams;
use super::obstacle_angle::ObstacleAngleParams;
use super::position_akf::PositionAkfParams;
use super::registry::EstimatorConfig;
use super::tdoa_ekf::TdoaEkfParams;

/// A parameter outside its domain.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("estimator `{estimator}`: parameter `{field}` {reason}")]
pub struct InvalidParameter {
    /// The estimator name.
    pub estimator: &'static str,
    /// The parameter.
    pub field: &'static str,
    /// What it must satisfy.
    pub reason: &'static str,
}

type Check = Result<(), (&'static str, &'static str)>;

fn positive(field: &'static str, v: f64) -> Check {
    if v > 0.0 && !v.is_nan() {
        Ok(())
    } else {
        Err((field, "must be positive"))
    }
}

fn finite_positive(field: &'static str, v: f64) -> Check {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err((field, "must be finite and positive"))
    }
}

fn non_negative(field: &'static str, v: f64) -> Check {
    if v >= 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err((field, "must be finite and non-negative"))
    }
}

fn history(v: f64) -> Check {
    non_negative("history_s", v)
}

fn heading(p: &HeadingKfParams) -> Check {
    positive("heading.sigma_w_deg", p.sigma_w_deg)?;
    positive("heading.sigma_v_deg", p.sigma_v_deg)?;
    positive("heading.initial_sigma_deg", p.initial_sigma_deg)
}

fn position(p: &PositionAkfParams) -> Check {
    positive("position.q_mm2", p.q_mm2)?;
    non_negative("position.c_pos", p.c_pos)?;
    positive("position.r_floor_mm", p.r_floor_mm)?;
    positive("position.reinit_gap_s", p.reinit_gap_s)
}

fn initial(p: &InitialPose) -> Check {
    for (field, v) in [
        ("initial_pose.x_m", p.x_m),
        ("initial_pose.y_m", p.y_m),
        ("initial_pose.theta_rad", p.theta_rad),
    ] {
        if !v.is_finite() {
            return Err((field, "must be finite"));
        }
    }
    positive("initial_pose.sigma_xy_m", p.sigma_xy_m)?;
    positive("initial_pose.sigma_theta_rad", p.sigma_theta_rad)
}

fn noise(p: &DeadReckoningNoise) -> Check {
    non_negative("noise.distance_fraction", p.distance_fraction)?;
    non_negative("noise.heading_rad_per_m", p.heading_rad_per_m)?;
    non_negative("noise.heading_rad_per_rad", p.heading_rad_per_rad)
}

fn obstacle(p: &ObstacleAngleParams) -> Check {
    positive("obstacle.d_safe_m", p.d_safe_m)?;
    non_negative("obstacle.k_ultrasonic_m", p.k_ultrasonic_m)?;
    non_negative("obstacle.k_ir_m", p.k_ir_m)?;
    non_negative("obstacle.n_ir", p.n_ir)
}

fn gyro_ckf(p: &GyroCkfParams) -> Check {
    non_negative("gyro_noise_deg_sqrt_s", p.gyro_noise_deg_sqrt_s)?;
    non_negative("bias_walk_deg_s_sqrt_s", p.bias_walk_deg_s_sqrt_s)?;
    positive("initial_bias_sigma_deg_s", p.initial_bias_sigma_deg_s)?;
    positive("heading_sigma_deg", p.heading_sigma_deg)?;
    positive("initial_heading_sigma_deg", p.initial_heading_sigma_deg)?;
    non_negative("max_gyro_gap_s", p.max_gyro_gap_s)?;
    position(&p.position)?;
    p.initial_pose.as_ref().map_or(Ok(()), initial)?;
    history(p.history_s)
}

fn cda(p: &CdaParams) -> Check {
    if p.calibration_samples == 0 {
        return Err(("calibration_samples", "must be at least 1"));
    }
    non_negative("mu_stop_deg", p.mu_stop_deg)?;
    non_negative("mu_start_deg", p.mu_start_deg)?;
    if p.mu_stop_deg >= p.mu_start_deg {
        return Err((
            "mu_stop_deg",
            "must be below mu_start_deg (the CDA paper: mu2 << mu1)",
        ));
    }
    if !(0.0..=1.0).contains(&p.complementary_alpha) {
        return Err(("complementary_alpha", "must be within [0, 1]"));
    }
    obstacle(&p.obstacle)?;
    non_negative("max_gyro_gap_s", p.max_gyro_gap_s)?;
    noise(&p.noise)?;
    initial(&p.initial_pose)?;
    history(p.history_s)
}

fn tdoa_ekf(p: &TdoaEkfParams) -> Check {
    p.initial_pose.as_ref().map_or(Ok(()), initial)?;
    if !p.receiver_height_m.is_finite() {
        return Err(("receiver_height_m", "must be finite"));
    }
    p.sensors.check()?;
    non_negative("max_gyro_gap_s", p.max_gyro_gap_s)?;
    positive("gate_sigma", p.gate_sigma)?;
    positive("late_soft_sigma", p.late_soft_sigma)?;
    non_negative("heading_sigma_deg", p.heading_sigma_deg)?;
    p.recovery.check()?;
    positive("model_nis", p.model_nis)?;
    if p.reinit_arrivals < 4 {
        return Err((
            "reinit_arrivals",
            "must be at least 4 (a checked 2D fix needs one more than 3)",
        ));
    }
    non_negative("reinit_heading_sigma_deg", p.reinit_heading_sigma_deg)?;
    if let Some(f) = &p.floor {
        let ok = (0..2)
            .all(|k| f.min_m[k].is_finite() && f.max_m[k].is_finite() && f.min_m[k] < f.max_m[k]);
        if !ok {
            return Err(("floor", "corners must be finite with min below max"));
        }
    }
    if p.start_transmitters < 2 {
        return Err((
            "start_transmitters",
            "must be at least 2 (one range difference names two)",
        ));
    }
    finite_positive("start_sigma_xy_m", p.start_sigma_xy_m)?;
    finite_positive("heading_chord_m", p.heading_chord_m)?;
    finite_positive("settled_sigma_m", p.settled_sigma_m)?;
    finite_positive("track_heading_sigma_deg", p.track_heading_sigma_deg)?;
    if p.late.window == 0 {
        return Err(("late.window", "must be at least 1"));
    }
    if !(p.late.blamed_share > 0.0 && p.late.blamed_share < 1.0) {
        return Err(("late.blamed_share", "must be within (0, 1)"));
    }
    non_negative("late.hold_s", p.late.hold_s)?;
    history(p.history_s)
}

impl EstimatorConfig {
    /// Checks every parameter is in its domain.
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        let check = match self {
            Self::Odometry(p) => initial(&p.initial_pose)
                .and_then(|()| noise(&p.noise))
                .and_then(|()| history(p.history_s)),
            Self::MsuRaw(p) => positive("heading_sigma_deg", p.heading_sigma_deg)
                .and_then(|()| history(p.history_s)),
            Self::IckonAkf(p) => heading(&p.heading)
                .and_then(|()| position(&p.position))
                .and_then(|()| p.initial_pose.as_ref().map_or(Ok(()), initial))
                .and_then(|()| history(p.history_s)),
            Self::GyroCkf(p) => gyro_ckf(p),
            Self::Cda(p) => cda(p),
            Self::CdaMsu(p) => cda(&p.cda)
                .and_then(|()| heading(&p.heading))
                .and_then(|()| position(&p.position))
                .and_then(|()| p.initial_pose.as_ref().map_or(Ok(()), initial))
                .and_then(|()| history(p.history_s)),
            Self::TdoaEkf(p) => tdoa_ekf(p),
        };
        check.map_err(|(field, reason)| InvalidParameter {
            estimator: self.name(),
            field,
            reason,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::names;

    #[test]
    fn seed_defaults_are_valid() {
        for name in names() {
            EstimatorConfig::default_for(name)
                .unwrap()
                .validate()
                .unwrap();
        }
    }

    #[test]
    fn inverted_cda_thresholds_are_named_in_the_error() {
        let config = EstimatorConfig::Cda(CdaParams {
            mu_start_deg: 0.01,
            ..CdaParams::default()
        });
        let err = config.validate().unwrap_err();
        assert_eq!((err.estimator, err.field), ("cda", "mu_stop_deg"));
    }

    #[test]
    fn nan_noise_is_refused() {
        let mut p = crate::estimator::ickon_akf::IckonAkfParams::default();
        p.position.c_pos = f64::NAN;
        let err = EstimatorConfig::IckonAkf(p).validate().unwrap_err();
        assert_eq!(err.field, "position.c_pos");
    }

    #[test]
    fn an_absurd_but_finite_survey_sigma_is_refused_by_name() {
        let with_survey = |sigma_m: f64| {
            let mut p = TdoaEkfParams::default();
            p.sensors.survey_sigma_m = sigma_m;
            EstimatorConfig::TdoaEkf(p).validate()
        };
        // 1e300 is within a plain range check, but its CRLB overflows and
        // the survey term would be silently left out of the published
        // covariance.
        for bad in [1e300, 1.01, -0.01, f64::INFINITY, f64::NAN] {
            let err = with_survey(bad).unwrap_err();
            assert_eq!(err.field, "sensors.survey_sigma_m", "{bad}");
            assert!(err.to_string().contains("at most 1 m"), "{err}");
        }
        for fine in [0.0, 0.01, 1.0] {
            with_survey(fine).unwrap();
        }
    }

    #[test]
    fn every_sensor_sheet_value_has_an_upper_bound() {
        let mut p = TdoaEkfParams::default();
        p.sensors.gyro_rate_hz = 1e12;
        let err = EstimatorConfig::TdoaEkf(p).validate().unwrap_err();
        assert_eq!(err.field, "sensors.gyro_rate_hz");
        let mut p = TdoaEkfParams::default();
        p.sensors.temperature_sigma_c = 1e200;
        let err = EstimatorConfig::TdoaEkf(p).validate().unwrap_err();
        assert_eq!(err.field, "sensors.temperature_sigma_c");
        let mut p = TdoaEkfParams::default();
        p.sensors.local_air_sigma_c = f64::NAN;
        let err = EstimatorConfig::TdoaEkf(p).validate().unwrap_err();
        assert_eq!(err.field, "sensors.local_air_sigma_c");
        let mut p = TdoaEkfParams::default();
        p.sensors.air_correlation_length_m = -1.0;
        let err = EstimatorConfig::TdoaEkf(p).validate().unwrap_err();
        assert_eq!(err.field, "sensors.air_correlation_length_m");
        for bad in [f64::NAN, -0.5, 1e9] {
            let mut p = TdoaEkfParams::default();
            p.sensors.local_wind_sigma_m_s = bad;
            let err = EstimatorConfig::TdoaEkf(p).validate().unwrap_err();
            assert_eq!(err.field, "sensors.local_wind_sigma_m_s");
            let mut p = TdoaEkfParams::default();
            p.sensors.draft_sigma_m_s = bad;
            let err = EstimatorConfig::TdoaEkf(p).validate().unwrap_err();
            assert_eq!(err.field, "sensors.draft_sigma_m_s");
        }
    }
}
