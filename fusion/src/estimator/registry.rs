//! Estimators by name, with their parameters as serde structs whose
//! `Default` holds the papers' values.
//!
//! A configuration is tagged by the estimator name, e.g. in TOML:
//! ```toml
//! name = "ickon-akf"
//! [position]
//! c_pos = 0.025
//! ```
//! Missing fields take their defaults; unknown fields are errors.

use super::cda::{Cda, CdaParams};
use super::cda_msu::{CdaMsu, CdaMsuParams};
use super::gyro_ckf::{GyroCkf, GyroCkfParams};
use super::history::LateInputHistory;
use super::ickon_akf::{IckonAkf, IckonAkfParams};
use super::msu_raw::{MsuRaw, MsuRawParams};
use super::odometry::{Odometry, OdometryParams};
use super::tdoa_ekf::{TdoaEkf, TdoaEkfParams};
use super::{Estimator, InvalidParameter};
use crate::estimator::InitialPose;

pub use super::gyro_ckf::two_sensor_heading;

/// The estimator names, in the order the evaluator lists them.
const NAMES: [&str; 7] = [
    "odometry",
    "msu-raw",
    "ickon-akf",
    "gyro-ckf",
    "cda",
    "cda-msu",
    "tdoa-ekf",
];

/// Every estimator name [`build_by_name`] accepts.
pub fn names() -> &'static [&'static str] {
    &NAMES
}

/// The name is not one of [`names`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown estimator `{name}` (known: odometry, msu-raw, ickon-akf, gyro-ckf, cda, cda-msu, tdoa-ekf)"
)]
pub struct UnknownEstimator {
    /// The name asked for.
    pub name: String,
}

/// An estimator with its parameters, tagged by name.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "name")]
pub enum EstimatorConfig {
    /// `odometry`.
    #[serde(rename = "odometry")]
    Odometry(OdometryParams),
    /// `msu-raw`.
    #[serde(rename = "msu-raw")]
    MsuRaw(MsuRawParams),
    /// `ickon-akf`.
    #[serde(rename = "ickon-akf")]
    IckonAkf(IckonAkfParams),
    /// `gyro-ckf`.
    #[serde(rename = "gyro-ckf")]
    GyroCkf(GyroCkfParams),
    /// `cda`.
    #[serde(rename = "cda")]
    Cda(CdaParams),
    /// `cda-msu`.
    #[serde(rename = "cda-msu")]
    CdaMsu(CdaMsuParams),
    /// `tdoa-ekf` (ground robot).
    #[serde(rename = "tdoa-ekf")]
    TdoaEkf(TdoaEkfParams),
}

impl EstimatorConfig {
    /// The default configuration of the estimator called `name`.
    pub fn default_for(name: &str) -> Result<Self, UnknownEstimator> {
        Ok(match name {
            "odometry" => Self::Odometry(OdometryParams::default()),
            "msu-raw" => Self::MsuRaw(MsuRawParams::default()),
            "ickon-akf" => Self::IckonAkf(IckonAkfParams::default()),
            "gyro-ckf" => Self::GyroCkf(GyroCkfParams::default()),
            "cda" => Self::Cda(CdaParams::default()),
            "cda-msu" => Self::CdaMsu(CdaMsuParams::default()),
            "tdoa-ekf" => Self::TdoaEkf(TdoaEkfParams::default()),
            _ => {
                return Err(UnknownEstimator {
                    name: name.to_owned(),
                });
            }
        })
    }

    /// Sets where the robot starts (`[x_m, y_m, theta_rad]`), keeping the
    /// configured start uncertainty; `msu-raw` has no start pose and ignores it.
    pub fn set_initial_pose(&mut self, start: [f64; 3]) {
        let with = |p: Option<InitialPose>| InitialPose {
            x_m: start[0],
            y_m: start[1],
            theta_rad: start[2],
            ..p.unwrap_or_default()
        };
        match self {
            Self::Odometry(p) => p.initial_pose = with(Some(p.initial_pose)),
            Self::MsuRaw(_) => {}
            Self::IckonAkf(p) => p.initial_pose = Some(with(p.initial_pose)),
            Self::GyroCkf(p) => p.initial_pose = Some(with(p.initial_pose)),
            Self::Cda(p) => p.initial_pose = with(Some(p.initial_pose)),
            Self::CdaMsu(p) => p.initial_pose = Some(with(p.initial_pose)),
            Self::TdoaEkf(p) => p.initial_pose = Some(with(p.initial_pose)),
        }
    }

    /// The estimator's name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Odometry(_) => "odometry",
            Self::MsuRaw(_) => "msu-raw",
            Self::IckonAkf(_) => "ickon-akf",
            Self::GyroCkf(_) => "gyro-ckf",
            Self::Cda(_) => "cda",
            Self::CdaMsu(_) => "cda-msu",
            Self::TdoaEkf(_) => "tdoa-ekf",
        }
    }
}

/// Builds the estimator described by `config`, once its parameters are
/// checked ([`EstimatorConfig::validate`]).
pub fn build(config: &EstimatorConfig) -> Result<Box<dyn Estimator>, InvalidParameter> {
    config.validate()?;
    Ok(build_valid(config))
}

fn build_valid(config: &EstimatorConfig) -> Box<dyn Estimator> {
    match config {
        EstimatorConfig::Odometry(p) => {
            Box::new(LateInputHistory::new(Odometry::new(p), p.history_s))
        }
        EstimatorConfig::MsuRaw(p) => Box::new(LateInputHistory::new(MsuRaw::new(p), p.history_s)),
        EstimatorConfig::IckonAkf(p) => {
            Box::new(LateInputHistory::new(IckonAkf::new(p), p.history_s))
        }
        EstimatorConfig::GyroCkf(p) => {
            Box::new(LateInputHistory::new(GyroCkf::new(p), p.history_s))
        }
        EstimatorConfig::Cda(p) => Box::new(LateInputHistory::new(Cda::new(p), p.history_s)),
        EstimatorConfig::CdaMsu(p) => Box::new(LateInputHistory::new(CdaMsu::new(p), p.history_s)),
        EstimatorConfig::TdoaEkf(p) => {
            Box::new(LateInputHistory::new(TdoaEkf::new(p), p.history_s))
        }
    }
}

/// Builds the estimator called `name` with its default parameters.
pub fn build_by_name(name: &str) -> Result<Box<dyn Estimator>, UnknownEstimator> {
    // The seed defaults are valid (tested in `config_check`).
    Ok(build_valid(&EstimatorConfig::default_for(name)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_builds_an_estimator_of_that_name() {
        for name in names() {
            let e = build_by_name(name).unwrap();
            assert_eq!(e.name(), *name);
            assert_eq!(EstimatorConfig::default_for(name).unwrap().name(), *name);
        }
    }

    #[test]
    fn config_is_tagged_by_name_and_missing_fields_take_the_seed_defaults() {
        use serde::Deserialize;
        use serde::de::IntoDeserializer;
        use serde::de::value::Error;
        use std::collections::BTreeMap;

        for name in names() {
            let map: BTreeMap<&str, &str> = [("name", *name)].into();
            let config = EstimatorConfig::deserialize(map.into_deserializer())
                .map_err(|e: Error| e.to_string())
                .unwrap();
            assert_eq!(config, EstimatorConfig::default_for(name).unwrap());
        }
        let map: BTreeMap<&str, &str> = [("name", "ickon-akf"), ("c_poz", "1")].into();
        let typo = EstimatorConfig::deserialize(map.into_deserializer());
        assert!(typo.map_err(|e: Error| e.to_string()).is_err());
    }

    #[test]
    fn unknown_name_is_a_typed_error() {
        let err = build_by_name("kalman").err().unwrap();
        assert_eq!(err.name, "kalman");
    }
}
