//! The estimators that take the log's odometry or IMU beside its
//! measurements: in 2D the MSU's ground filter (`tdoa-ekf` fed every
//! wheel increment, as `ickon replay plaza` drives it) and dead reckoning
//! (`odometry`); in 3D `imu-eskf`, the IMU filter of
//! `ickon replay util --imu`. Each reads its own stream of the file, so
//! that nothing is held beyond the next row.

use std::path::Path;

use nalgebra::Matrix3;

use ickon_fusion::estimator::flight::ImuSample;
use ickon_fusion::estimator::history::InOrderFilter;
use ickon_fusion::estimator::tdoa_ekf::TdoaEkf;
use ickon_fusion::estimator::{
    BeaconRangeSample, InitialPose, Input, PoseEstimate, RangeDifferenceSample,
};

use super::format::OdometryRow;
use super::motion_rows::{ImuReader, OdometryReader};
use super::read::LogError;
use crate::util::dataset::ImuRow;
use crate::util::estimators::ImuRunner;
use crate::util::score::Track;

/// The odometry file handed out up to a time.
struct OdometryStream {
    reader: OdometryReader,
    next: Option<OdometryRow>,
    ended: bool,
    /// Time of the last increment handed out (the start's before the first).
    last_s: Option<f64>,
}

impl OdometryStream {
    fn open(path: &Path, start_s: Option<f64>) -> Result<Self, LogError> {
        Ok(Self {
            reader: OdometryReader::open(path)?,
            next: None,
            ended: false,
            last_s: start_s,
        })
    }

    /// The next increment stamped before `t_s`, with the time it spans.
    fn next_before(&mut self, t_s: f64) -> Result<Option<(OdometryRow, f64)>, LogError> {
        if self.next.is_none() && !self.ended {
            self.next = self.reader.next_row()?;
            self.ended = self.next.is_none();
        }
        match self.next {
            Some(o) if o.t_s < t_s => {
                self.next = None;
                let dt = self.last_s.map_or(0.0, |l| (o.t_s - l).max(0.0));
                self.last_s = Some(o.t_s);
                Ok(Some((o, dt)))
            }
            _ => Ok(None),
        }
    }
}

/// `tdoa-ekf` on a wheeled robot: every increment a prediction, each
/// range an update with the ranges' bias and scale estimated, each range
/// difference an arrival of its cycle; the pose scored after every
/// increment.
pub struct GroundRunner {
    filter: TdoaEkf,
    odometry: OdometryStream,
    /// The height the filter puts the receiver at (ranges' beacons too).
    height_m: f64,
    /// Measurements accepted.
    pub used: u64,
    /// Measurements rejected.
    pub rejected: u64,
}

impl GroundRunner {
    /// The filter with `params`, the increments of `path` from `start_s`.
    pub fn new(
        path: &Path,
        params: &ickon_fusion::estimator::tdoa_ekf::TdoaEkfParams,
        start_s: Option<f64>,
    ) -> Result<Self, LogError> {
        Ok(Self {
            filter: TdoaEkf::new(params),
            odometry: OdometryStream::open(path, start_s)?,
            height_m: params.receiver_height_m,
            used: 0,
            rejected: 0,
        })
    }

    /// Drives every increment stamped before `t_s`, queuing the pose after
    /// each on `track`.
    pub fn drive_until(&mut self, t_s: f64, track: &mut Track) -> Result<(), LogError> {
        while let Some((o, dt)) = self.odometry.next_before(t_s)? {
            self.filter
                .increment(o.t_s, o.distance_m, o.dtheta_rad, dt, false);
            if let Some(PoseEstimate {
                x_m,
                y_m,
                covariance,
                ..
            }) = self.filter.pose()
            {
                // The pose's (x, y, heading) covariance: its position block,
                // the height held at the floor's (a planar track's test
                // leaves it out).
                let mut position = Matrix3::identity();
                position
                    .fixed_view_mut::<2, 2>(0, 0)
                    .copy_from(&covariance.fixed_view::<2, 2>(0, 0));
                track.push_with(o.t_s, [x_m, y_m, 0.0], Some(position));
            }
        }
        Ok(())
    }

    /// Fuses a range to the anchor at `anchor_m`.
    pub fn range(&mut self, t_s: f64, anchor_m: [f64; 3], range_m: f64, sigma_m: f64) {
        self.step(&Input::BeaconRange(BeaconRangeSample {
            t_s,
            beacon_m: [anchor_m[0], anchor_m[1], self.height_m],
            range_m,
            sigma_m,
        }));
    }

    /// Fuses one range difference.
    pub fn difference(&mut self, s: &RangeDifferenceSample) {
        self.step(&Input::RangeDifference(*s));
    }

    fn step(&mut self, input: &Input) {
        self.filter.step(input);
        match self.filter.last_outcome() {
            Some(o) if o.is_accepted() => self.used += 1,
            _ => self.rejected += 1,
        }
    }

    /// Times the filter re-initialised itself, lost.
    pub fn reinitialisations(&self) -> u64 {
        self.filter.reinitialisations().len() as u64
    }
}

/// Dead reckoning: the increments integrated from the start pose.
pub struct DeadReckoning {
    odometry: OdometryStream,
    pose: (f64, f64, f64),
}

impl DeadReckoning {
    /// From `start` at `start_s`, the increments of `path`.
    pub fn new(path: &Path, start: InitialPose, start_s: f64) -> Result<Self, LogError> {
        Ok(Self {
            odometry: OdometryStream::open(path, Some(start_s))?,
            pose: (start.x_m, start.y_m, start.theta_rad),
        })
    }

    /// Drives every increment stamped before `t_s`, queuing each pose.
    pub fn drive_until(&mut self, t_s: f64, track: &mut Track) -> Result<(), LogError> {
        while let Some((o, _)) = self.odometry.next_before(t_s)? {
            let (x, y, th) = self.pose;
            let mid = th + 0.5 * o.dtheta_rad;
            self.pose = (
                x + o.distance_m * mid.cos(),
                y + o.distance_m * mid.sin(),
                th + o.dtheta_rad,
            );
            track.push(o.t_s, [self.pose.0, self.pose.1, 0.0]);
        }
        Ok(())
    }
}

/// `imu-eskf` fed the IMU file's samples up to each range difference.
pub struct ImuSlot {
    /// The filter under the watch.
    pub runner: ImuRunner,
    reader: ImuReader,
    next: Option<ImuRow>,
    ended: bool,
}

impl ImuSlot {
    /// The filter, the samples of `path`.
    pub fn new(runner: ImuRunner, path: &Path) -> Result<Self, LogError> {
        Ok(Self {
            runner,
            reader: ImuReader::open(path)?,
            next: None,
            ended: false,
        })
    }

    /// Integrates the samples up to the measurement's time, then fuses it;
    /// the published estimate, if any.
    pub fn step(&mut self, m: &RangeDifferenceSample) -> Result<Option<(f64, [f64; 3])>, LogError> {
        loop {
            if self.next.is_none() && !self.ended {
                self.next = self.reader.next_row()?;
                self.ended = self.next.is_none();
            }
            match self.next {
                Some(s) if s.t_s <= m.t_s => {
                    self.runner.filter_mut().imu(&ImuSample {
                        t_s: s.t_s,
                        accel_m_s2: s.accel_m_s2,
                        gyro_rad_s: s.gyro_rad_s,
                    });
                    self.next = None;
                }
                _ => break,
            }
        }
        Ok(self.runner.step(m))
    }
}
