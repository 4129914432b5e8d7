//! What one Plaza run gives: the filter's and dead reckoning's tracks
//! against the truth, and their statistics.

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
    /// Tracks, for the plots.
    #[serde(skip)]
    pub filter_track: Vec<Sample>,
    /// Dead-reckoning track, for the plots.
    #[serde(skip)]
    pub odometry_track: Vec<Sample>,
}
