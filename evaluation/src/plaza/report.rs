//! What one Plaza run gives: the filter's and dead reckoning's tracks
//! against the truth, and their statistics.

use ickon_sim::score::{Nees, inside_95_ellipse, nees_2d};

/// Error statistics of one track, metres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Stats {
    /// 2D root mean square error.
    pub rmse_m: f64,
    /// Mean 2D error.
    pub mean_m: f64,
    /// 95th percentile of the 2D error.
    pub p95_m: f64,
    /// Largest 2D error.
    pub max_m: f64,
    /// Largest 2D error after the first minute.
    pub max_after_60s_m: f64,
    /// Scored estimates.
    pub samples: usize,
}

/// One estimate against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Seconds since the run's start.
    pub t_s: f64,
    /// Estimate, metres.
    pub estimate_m: [f64; 2],
    /// Truth at the same time, metres.
    pub truth_m: [f64; 2],
}

/// The result of one run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunReport {
    /// Run name (its directory).
    pub run: String,
    /// Duration, seconds.
    pub duration_s: f64,
    /// The filter.
    pub filter: Stats,
    /// Dead reckoning from the same start.
    pub odometry: Stats,
    /// Ranges fused and rejected.
    pub ranges_used: u64,
    /// Ranges rejected (gate, late).
    pub ranges_rejected: u64,
    /// The range bias estimated at the end, metres.
    pub range_bias_m: f64,
    /// The range scale error estimated at the end.
    pub range_scale: f64,
    /// The distance scale error estimated at the end.
    pub distance_scale: f64,
    /// The turn-rate bias estimated at the end, deg/s.
    pub turn_bias_deg_s: f64,
    /// Re-initialisations of the filter.
    pub reinitialisations: usize,
    /// Times the filter reopened its heading and turn bias.
    pub adaptations: u32,
    /// Share of the filter's scored poses whose truth lies inside the 95 %
    /// ellipse of the covariance it published, percent (95 when honest);
    /// `None` unless every pose came with a usable covariance.
    pub inside_95_pct: Option<f64>,
    /// Bar-Shalom's test of that covariance: the average 2D NEES with its
    /// 95 % bounds; `None` as above.
    pub nees: Option<Nees>,
    /// Tracks, for the plots.
    #[serde(skip)]
    pub filter_track: Vec<Sample>,
    /// Dead-reckoning track, for the plots.
    #[serde(skip)]
    pub odometry_track: Vec<Sample>,
}

/// The consistency test of a track's published covariance, accumulated
/// pose by pose.
#[derive(Debug, Clone, Default)]
pub struct Consistency {
    nees: Vec<f64>,
    inside: usize,
    without_covariance: usize,
}

impl Consistency {
    /// One pose's error (metres) under its covariance `xx, xy, yy` (m^2).
    pub fn push(&mut self, error_m: [f64; 2], covariance_m2: [f64; 3]) {
        match nees_2d(error_m, covariance_m2) {
            Some(v) => {
                self.inside += usize::from(inside_95_ellipse(error_m, covariance_m2) == Some(true));
                self.nees.push(v);
            }
            None => self.without_covariance += 1,
        }
    }

    /// Share inside the 95 % ellipse, percent; `None` unless every pose had
    /// a usable covariance.
    pub fn inside_95_pct(&self) -> Option<f64> {
        (self.without_covariance == 0 && !self.nees.is_empty())
            .then(|| 100.0 * self.inside as f64 / self.nees.len() as f64)
    }

    /// The average NEES and its bounds; `None` as for the share.
    pub fn nees(&self) -> Option<Nees> {
        if self.without_covariance > 0 {
            return None;
        }
        Nees::of(&self.nees)
    }
}
