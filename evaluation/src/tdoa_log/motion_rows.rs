//! The optional odometry and IMU files, streamed row by row on the
//! measurements' clock, checked as the other files are.

use std::path::Path;

use super::format::{OdometryRow, imu_columns as ic, odometry_columns as oc};
use super::read::{LineFile, LogError};
use crate::util::dataset::ImuRow;

/// Largest odometry increment accepted, metres: a row is one step of the
/// wheels (tens of milliseconds), not a journey; beyond, a unit error or
/// cumulative poses given for increments.
const MAX_INCREMENT_M: f64 = 100.0;

/// The odometry file, one increment at a time.
pub struct OdometryReader {
    file: LineFile,
    cols: [usize; 4],
    last_s: f64,
}

impl OdometryReader {
    /// Opens `path` and checks its header.
    pub fn open(path: &Path) -> Result<Self, LogError> {
        let file = LineFile::open(path)?;
        let cols = [
            file.required(oc::TIME)?,
            file.required(oc::DX)?,
            file.required(oc::DY)?,
            file.required(oc::DTHETA)?,
        ];
        Ok(Self {
            file,
            cols,
            last_s: f64::NEG_INFINITY,
        })
    }

    /// The next increment, `None` at the end.
    pub fn next_row(&mut self) -> Result<Option<OdometryRow>, LogError> {
        let Some(r) = self.file.next_fields()? else {
            return Ok(None);
        };
        let f = &self.file;
        let [t, dx, dy, dth] = self.cols;
        let t_s = f.number(&r, t)?;
        if t_s < self.last_s {
            return Err(f.bad(
                Some(t),
                format!("{t_s} s after {} s: times go backwards", self.last_s),
            ));
        }
        self.last_s = t_s;
        let (dx_m, dy_m) = (f.number(&r, dx)?, f.number(&r, dy)?);
        for (k, v) in [(dx, dx_m), (dy, dy_m)] {
            if v.abs() > MAX_INCREMENT_M {
                return Err(f.bad(
                    Some(k),
                    format!(
                        "{v} m in one increment is beyond {MAX_INCREMENT_M} m: rows are increments since the previous row, not poses"
                    ),
                ));
            }
        }
        let dtheta_rad = f.number(&r, dth)?;
        if dtheta_rad.abs() > std::f64::consts::TAU {
            return Err(f.bad(
                Some(dth),
                format!("{dtheta_rad} rad in one increment is over a full turn: a unit error (degrees?) or a heading given for a turn"),
            ));
        }
        Ok(Some(OdometryRow::from_increment(
            t_s, dx_m, dy_m, dtheta_rad,
        )))
    }
}

/// The IMU file, one sample at a time.
pub struct ImuReader {
    file: LineFile,
    time: usize,
    accel: [usize; 3],
    gyro: [usize; 3],
    last_s: f64,
}

impl ImuReader {
    /// Opens `path` and checks its header.
    pub fn open(path: &Path) -> Result<Self, LogError> {
        let file = LineFile::open(path)?;
        let time = file.required(ic::TIME)?;
        let mut accel = [0; 3];
        let mut gyro = [0; 3];
        for k in 0..3 {
            accel[k] = file.required(ic::ACCEL[k])?;
            gyro[k] = file.required(ic::GYRO[k])?;
        }
        Ok(Self {
            file,
            time,
            accel,
            gyro,
            last_s: f64::NEG_INFINITY,
        })
    }

    /// The next sample, `None` at the end.
    pub fn next_row(&mut self) -> Result<Option<ImuRow>, LogError> {
        let Some(r) = self.file.next_fields()? else {
            return Ok(None);
        };
        let f = &self.file;
        let t_s = f.number(&r, self.time)?;
        if t_s < self.last_s {
            return Err(f.bad(
                Some(self.time),
                format!("{t_s} s after {} s: times go backwards", self.last_s),
            ));
        }
        self.last_s = t_s;
        let mut row = ImuRow {
            t_s,
            accel_m_s2: [0.0; 3],
            gyro_rad_s: [0.0; 3],
        };
        for k in 0..3 {
            row.accel_m_s2[k] = f.number(&r, self.accel[k])?;
            row.gyro_rad_s[k] = f.number(&r, self.gyro[k])?;
        }
        Ok(Some(row))
    }
}
