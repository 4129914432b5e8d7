//! A noise profile from a TOML file: `--profile FILE` wherever a built-in
//! name is taken, so a user can model their own site (a better survey,
//! a warmer hall, a noisier gyro) or switch one error off to see what it
//! costs. The file holds every field of [`NoiseProfile`]; a missing or
//! unknown field and a value out of its range are refused with the field's
//! name. `deploy/profiles/paper.toml` is `paper` written out.

use std::path::Path;

use crate::profile::{NoiseProfile, UnknownProfile};

/// Largest profile file read, bytes: a profile is a few kilobytes; a path
/// to anything larger (a log, `/dev/zero`) is refused before it fills memory.
pub const MAX_PROFILE_FILE_BYTES: u64 = 1 << 20;

/// Why a profile could not be had.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// Neither a built-in name nor a file.
    #[error(transparent)]
    Unknown(#[from] UnknownProfile),
    /// The file could not be read (missing, too large for a profile, not UTF-8).
    #[error("{path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Not TOML, a field missing or unknown, or a value of the wrong type
    /// (the text names the line, the column and the field).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// What the parser said.
        message: String,
    },
    /// A value out of its range.
    #[error("{path}: `{field}` {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// The field, as a dotted path.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl NoiseProfile {
    /// A built-in profile by name, or else the profile in the TOML file at
    /// `name_or_path` (checked, see [`NoiseProfile::check`]).
    pub fn load(name_or_path: &str) -> Result<Self, ProfileError> {
        if let Ok(p) = Self::by_name(name_or_path) {
            return Ok(p);
        }
        let path = Path::new(name_or_path);
        let looks_like_a_file = name_or_path.contains('/') || name_or_path.ends_with(".toml");
        if !path.exists() && !looks_like_a_file {
            return Err(UnknownProfile(name_or_path.to_owned()).into());
        }
        let text = ickon_proto::text_file::read_bounded(path, MAX_PROFILE_FILE_BYTES).map_err(
            |reason| ProfileError::Read {
                path: name_or_path.to_owned(),
                reason,
            },
        )?;
        let profile: Self = toml::from_str(&text).map_err(|e| ProfileError::Parse {
            path: name_or_path.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        profile
            .check()
            .map_err(|(field, reason)| ProfileError::Invalid {
                path: name_or_path.to_owned(),
                field,
                reason,
            })?;
        Ok(profile)
    }

    /// The first value out of its range, as (field, reason): probabilities
    /// in `[0, 1]`, noises, rates and distances finite and not negative,
    /// rates and the range positive, the reflection interval ordered.
    pub fn check(&self) -> Result<(), (String, String)> {
        let u = &self.ultrasound;
        let c = &u.collisions;
        let e = &self.encoders;
        let g = &self.gyro;
        let o = &self.obstacles;
        let k = &self.clocks;
        let probabilities = [
            ("ultrasound.drop_probability", u.drop_probability),
            (
                "ultrasound.blocked_reflection_probability",
                u.blocked_reflection_probability,
            ),
            (
                "ultrasound.los_reflection_probability",
                u.los_reflection_probability,
            ),
            ("ultrasound.id_error_probability", u.id_error_probability),
            (
                "ultrasound.collisions.misdecode_probability",
                c.misdecode_probability,
            ),
            ("obstacles.dropout_probability", o.dropout_probability),
        ];
        for (field, v) in probabilities {
            if !(0.0..=1.0).contains(&v) {
                return Err((
                    field.into(),
                    format!("is {v}: a probability is within 0 to 1"),
                ));
            }
        }
        let not_negative = [
            ("ultrasound.timing_jitter_us", u.timing_jitter_us),
            ("ultrasound.quantisation_us", u.quantisation_us),
            ("ultrasound.bearing_sigma_deg", u.bearing_sigma_deg),
            ("ultrasound.reflection_extra_m", u.reflection_extra_m[0]),
            ("ultrasound.survey_sigma_m", u.survey_sigma_m),
            (
                "ultrasound.collisions.absorption_db_per_m",
                c.absorption_db_per_m,
            ),
            (
                "ultrasound.collisions.reflection_loss_db",
                c.reflection_loss_db,
            ),
            (
                "ultrasound.collisions.reverb_decay_db_per_ms",
                c.reverb_decay_db_per_ms,
            ),
            ("ultrasound.collisions.detection_snr_db", c.detection_snr_db),
            ("encoders.slip_sigma", e.slip_sigma),
            ("encoders.slip_per_rad_s", e.slip_per_rad_s),
            ("gyro.bias_sigma_deg_s", g.bias_sigma_deg_s),
            ("gyro.bias_walk_deg_s_sqrt_s", g.bias_walk_deg_s_sqrt_s),
            ("gyro.white_sigma_deg_s", g.white_sigma_deg_s),
            ("obstacles.ultrasonic_sigma_m", o.ultrasonic_sigma_m),
            ("obstacles.ir_sigma_m", o.ir_sigma_m),
            ("clocks.cell_offset_sigma_ms", k.cell_offset_sigma_ms),
            ("clocks.cell_drift_sigma_ppm", k.cell_drift_sigma_ppm),
            ("clocks.net_delay_us", k.net_delay_us),
            ("clocks.net_jitter_us", k.net_jitter_us),
            ("clocks.net_asymmetry_sigma_us", k.net_asymmetry_sigma_us),
            ("clocks.msu_offset_sigma_ms", k.msu_offset_sigma_ms),
            ("clocks.msu_drift_sigma_ppm", k.msu_drift_sigma_ppm),
        ];
        for (field, v) in not_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err((
                    field.into(),
                    format!("is {v}: it must be finite and not negative"),
                ));
            }
        }
        let finite = [
            (
                "ultrasound.temperature_error_c",
                u.temperature_error_c,
                50.0,
            ),
            (
                "ultrasound.collisions.reverb_tail_db",
                c.reverb_tail_db,
                200.0,
            ),
            ("encoders.left_radius_error", e.left_radius_error, 0.5),
            ("encoders.right_radius_error", e.right_radius_error, 0.5),
            ("encoders.wheel_base_error", e.wheel_base_error, 0.5),
            ("gyro.scale_error", g.scale_error, 0.5),
        ];
        for (field, v, bound) in finite {
            if !(v.is_finite() && v.abs() <= bound) {
                return Err((
                    field.into(),
                    format!("is {v}: it must be within -{bound} to {bound}"),
                ));
            }
        }
        let positive = [
            ("ultrasound.max_range_m", u.max_range_m),
            ("gyro.rate_hz", g.rate_hz),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err((
                    field.into(),
                    format!("is {v}: it must be finite and positive"),
                ));
            }
        }
        u.air.check()?;
        self.air_sensors.check()?;
        let [lo, hi] = u.reflection_extra_m;
        if !(hi.is_finite() && hi >= lo) {
            return Err((
                "ultrasound.reflection_extra_m".into(),
                format!("is [{lo}, {hi}]: the second bound must be finite and not below the first"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The profile file shipped as an example, relative to this crate.
    const PAPER_FILE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/profiles/paper.toml");

    #[test]
    fn the_shipped_file_is_paper_and_every_built_in_profile_round_trips() {
        let loaded = NoiseProfile::load(PAPER_FILE).unwrap();
        assert_eq!(loaded, NoiseProfile::paper());
        let dir = tempfile::tempdir().unwrap();
        for name in NoiseProfile::names() {
            let p = NoiseProfile::by_name(name).unwrap();
            assert_eq!(p.check(), Ok(()), "{name}");
            let path = dir.path().join(format!("{name}.toml"));
            std::fs::write(&path, toml::to_string(&p).unwrap()).unwrap();
            assert_eq!(NoiseProfile::load(path.to_str().unwrap()).unwrap(), p);
        }
    }

    #[test]
    fn the_shipped_building_file_is_building() {
        let file = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../deploy/profiles/building.toml"
        );
        assert_eq!(NoiseProfile::load(file).unwrap(), NoiseProfile::building());
    }

    #[test]
    fn the_shipped_building_sensors_file_is_building_with_typical_sensors() {
        let file = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../deploy/profiles/building-sensors.toml"
        );
        let mut want = NoiseProfile::building();
        want.name = "building-sensors".into();
        want.air_sensors = crate::air_sensor::AirSensors::typical();
        assert_eq!(NoiseProfile::load(file).unwrap(), want);
        // A profile without the table has no sensors (older files load).
        assert!(NoiseProfile::building().air_sensors.is_absent());
    }

    #[test]
    fn a_bad_file_is_refused_naming_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let paper = std::fs::read_to_string(PAPER_FILE).unwrap();
        let cases = [
            (
                "drop_probability = 0.05",
                "drop_probability = 1.5",
                "ultrasound.drop_probability",
            ),
            (
                "timing_jitter_us = 70.0",
                "timing_jitter_us = nan",
                "ultrasound.timing_jitter_us",
            ),
            (
                "timing_jitter_us = 70.0",
                "timing_jitter_us = -1.0",
                "ultrasound.timing_jitter_us",
            ),
            ("rate_hz = 100.0", "rate_hz = 0.0", "gyro.rate_hz"),
            (
                "scale_error = 0.005",
                "scale_error = inf",
                "gyro.scale_error",
            ),
            (
                "timing_jitter_us = 70.0",
                "timing_jitter_us = 70.0\njitter_typo = 1.0",
                "jitter_typo",
            ),
            ("timing_jitter_us = 70.0\n", "", "timing_jitter_us"),
            ("rate_hz = 100.0", "rate_hz = \"fast\"", "rate_hz"),
        ];
        for (from, to, named) in cases {
            assert!(paper.contains(from), "{from}");
            let path = dir.path().join("bad.toml");
            std::fs::write(&path, paper.replacen(from, to, 1)).unwrap();
            let err = NoiseProfile::load(path.to_str().unwrap())
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(named) && err.contains("bad.toml"),
                "{to}: {err}"
            );
        }
        let err = NoiseProfile::load("no-such-profile")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("unknown noise profile `no-such-profile`"),
            "{err}"
        );
        let err = NoiseProfile::load(dir.path().to_str().unwrap()).unwrap_err();
        assert!(matches!(err, ProfileError::Read { .. }), "{err}");
        let err = NoiseProfile::load("/dev/zero").unwrap_err().to_string();
        assert!(err.contains("larger than"), "{err}");
        std::fs::write(dir.path().join("binary.toml"), [0xff, 0xfe, 0x00]).unwrap();
        let err = NoiseProfile::load(dir.path().join("binary.toml").to_str().unwrap()).unwrap_err();
        assert!(
            matches!(err, ProfileError::Read { .. } | ProfileError::Parse { .. }),
            "{err}"
        );
    }
}
