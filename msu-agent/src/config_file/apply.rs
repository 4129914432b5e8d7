//! Where each input block's values land in each estimator's parameters.
//!
//! The estimators were written from different papers and name the same
//! physical noise differently (a fix's noise floor is `position.r_floor_mm`
//! in the seed filters, a gyro's noise is a white noise and a rate in
//! `tdoa-ekf` but an angle random walk in `gyro-ckf`). The file names each
//! input's noise and gate once, in the units of a data sheet; this module
//! converts. Every setter returns the parameter paths it wrote (to catch the
//! same value also set in `[filter.params]`), or nothing when the estimator
//! has no use for the value (the caller warns).

use ickon_fusion::estimator::EstimatorConfig;

/// The parameter paths a value was written to; empty: the estimator does not use it.
pub(super) type Touched = Vec<&'static str>;

/// `[filter] history_s`: every estimator keeps a history for late inputs.
pub(super) fn history_s(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::Odometry(p) => p.history_s = v,
        EstimatorConfig::MsuRaw(p) => p.history_s = v,
        EstimatorConfig::IckonAkf(p) => p.history_s = v,
        EstimatorConfig::GyroCkf(p) => p.history_s = v,
        EstimatorConfig::Cda(p) => p.history_s = v,
        EstimatorConfig::CdaMsu(p) => p.history_s = v,
        EstimatorConfig::TdoaEkf(p) => p.history_s = v,
    }
    vec!["history_s"]
}

/// `[fix] sigma_floor_mm`: the smallest per-axis sigma a fix is granted.
pub(super) fn fix_sigma_floor_mm(c: &mut EstimatorConfig, v: f64) -> Touched {
    let position = match c {
        EstimatorConfig::IckonAkf(p) => &mut p.position,
        EstimatorConfig::GyroCkf(p) => &mut p.position,
        EstimatorConfig::CdaMsu(p) => &mut p.position,
        _ => return vec![],
    };
    position.r_floor_mm = v;
    vec!["position.r_floor_mm"]
}

/// `[range_differences] gate_sigma`.
pub(super) fn range_gate_sigma(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.gate_sigma = v;
            vec!["gate_sigma"]
        }
        _ => vec![],
    }
}

/// `[range_differences] late_soft_sigma`.
pub(super) fn range_late_soft_sigma(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.late_soft_sigma = v;
            vec!["late_soft_sigma"]
        }
        _ => vec![],
    }
}

/// `[odometry] distance_sigma_fraction`: sigma of the distance the robot's
/// centre travelled, a fraction of it. `tdoa-ekf` models each wheel's slip,
/// and the centre averages two wheels: per wheel it is `sqrt(2)` larger.
pub(super) fn odometry_distance(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::Odometry(p) => p.noise.distance_fraction = v,
        EstimatorConfig::Cda(p) => p.noise.distance_fraction = v,
        EstimatorConfig::CdaMsu(p) => p.cda.noise.distance_fraction = v,
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.wheel_slip_fraction = v * std::f64::consts::SQRT_2;
            return vec!["sensors.wheel_slip_fraction"];
        }
        _ => return vec![],
    }
    vec!["noise.distance_fraction", "cda.noise.distance_fraction"]
}

/// `[odometry] heading_sigma_deg_per_m`: heading error per metre driven.
pub(super) fn odometry_heading_per_m(c: &mut EstimatorConfig, deg_per_m: f64) -> Touched {
    let v = deg_per_m.to_radians();
    match c {
        EstimatorConfig::Odometry(p) => p.noise.heading_rad_per_m = v,
        EstimatorConfig::Cda(p) => p.noise.heading_rad_per_m = v,
        EstimatorConfig::CdaMsu(p) => p.cda.noise.heading_rad_per_m = v,
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.wheel_heading_rad_per_m = v;
            return vec!["sensors.wheel_heading_rad_per_m"];
        }
        _ => return vec![],
    }
    vec!["noise.heading_rad_per_m", "cda.noise.heading_rad_per_m"]
}

/// `[odometry] heading_sigma_per_turn`: heading error per radian turned.
pub(super) fn odometry_heading_per_turn(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::Odometry(p) => p.noise.heading_rad_per_rad = v,
        EstimatorConfig::Cda(p) => p.noise.heading_rad_per_rad = v,
        EstimatorConfig::CdaMsu(p) => p.cda.noise.heading_rad_per_rad = v,
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.wheel_heading_rad_per_rad = v;
            return vec!["sensors.wheel_heading_rad_per_rad"];
        }
        _ => return vec![],
    }
    vec!["noise.heading_rad_per_rad", "cda.noise.heading_rad_per_rad"]
}

/// `[gyro] use`.
pub(super) fn gyro_use(c: &mut EstimatorConfig, v: bool) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.use_gyro = v;
            vec!["use_gyro"]
        }
        _ => vec![],
    }
}

/// `[gyro] white_noise_deg_s` and `rate_hz` together: `gyro-ckf` takes
/// their angle random walk `white / sqrt(rate)`.
pub(super) fn gyro_white_noise(c: &mut EstimatorConfig, white_deg_s: f64, rate_hz: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.gyro_white_deg_s = white_deg_s;
            p.sensors.gyro_rate_hz = rate_hz;
            vec!["sensors.gyro_white_deg_s", "sensors.gyro_rate_hz"]
        }
        EstimatorConfig::GyroCkf(p) => {
            p.gyro_noise_deg_sqrt_s = white_deg_s / rate_hz.sqrt();
            vec!["gyro_noise_deg_sqrt_s"]
        }
        _ => vec![],
    }
}

/// `[gyro] bias_sigma_deg_s`: the power-up bias.
pub(super) fn gyro_bias_sigma(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.gyro_bias_sigma_deg_s = v;
            vec!["sensors.gyro_bias_sigma_deg_s"]
        }
        EstimatorConfig::GyroCkf(p) => {
            p.initial_bias_sigma_deg_s = v;
            vec!["initial_bias_sigma_deg_s"]
        }
        _ => vec![],
    }
}

/// `[gyro] bias_walk_deg_s_sqrt_s`.
pub(super) fn gyro_bias_walk(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.gyro_bias_walk_deg_s_sqrt_s = v;
            vec!["sensors.gyro_bias_walk_deg_s_sqrt_s"]
        }
        EstimatorConfig::GyroCkf(p) => {
            p.bias_walk_deg_s_sqrt_s = v;
            vec!["bias_walk_deg_s_sqrt_s"]
        }
        _ => vec![],
    }
}

/// `[gyro] scale_error`.
pub(super) fn gyro_scale_error(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => {
            p.sensors.gyro_scale_error = v;
            vec!["sensors.gyro_scale_error"]
        }
        _ => vec![],
    }
}

/// `[gyro] max_gap_s`: the gate on gyro gaps (a longer one is not integrated).
pub(super) fn gyro_max_gap(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => p.max_gyro_gap_s = v,
        EstimatorConfig::GyroCkf(p) => p.max_gyro_gap_s = v,
        EstimatorConfig::Cda(p) => p.max_gyro_gap_s = v,
        EstimatorConfig::CdaMsu(p) => {
            p.cda.max_gyro_gap_s = v;
            return vec!["cda.max_gyro_gap_s"];
        }
        _ => return vec![],
    }
    vec!["max_gyro_gap_s"]
}

/// `[receiver_heading] sigma_deg`.
pub(super) fn receiver_heading_sigma(c: &mut EstimatorConfig, v: f64) -> Touched {
    match c {
        EstimatorConfig::TdoaEkf(p) => p.heading_sigma_deg = v,
        EstimatorConfig::GyroCkf(p) => p.heading_sigma_deg = v,
        EstimatorConfig::MsuRaw(p) => p.heading_sigma_deg = v,
        EstimatorConfig::IckonAkf(p) => {
            p.heading.sigma_v_deg = v;
            return vec!["heading.sigma_v_deg"];
        }
        EstimatorConfig::CdaMsu(p) => {
            p.heading.sigma_v_deg = v;
            return vec!["heading.sigma_v_deg"];
        }
        _ => return vec![],
    }
    vec!["heading_sigma_deg"]
}
