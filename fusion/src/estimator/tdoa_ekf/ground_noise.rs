//! The ground filter's sensor noise, as data sheets state it.
//!
//! Every default is the data-sheet value the `paper` noise profile of the
//! simulator is built from (sim/src/profile.rs: a Pioneer 3-DX and a
//! low-cost MEMS gyro), not a value fitted to any route: the same numbers
//! are used on every site. A robot with other sensors sets its own sheet.

/// Noise of the relative sensors (gyro, wheels) and prior uncertainty of
/// the calibration states.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundNoise {
    /// White noise of one gyro sample, deg/s (sheet: 0.1).
    pub gyro_white_deg_s: f64,
    /// Gyro sampling rate, Hz (sheet: 100): with the white noise it gives
    /// the angle random walk `white / sqrt(rate)`.
    pub gyro_rate_hz: f64,
    /// Standard deviation of the gyro's power-up bias, deg/s (sheet: 0.5).
    pub gyro_bias_sigma_deg_s: f64,
    /// Gyro bias random walk, deg/s per sqrt(s) (sheet: 0.01).
    pub gyro_bias_walk_deg_s_sqrt_s: f64,
    /// Gyro scale factor error, a fraction of the turn (sheet: 0.005): the
    /// prior standard deviation of the filter's turn scale state (one
    /// constant error, not noise per step).
    pub gyro_scale_error: f64,
    /// Slip of each wheel, a fraction of its travel (sheet: 0.01); the
    /// centre's distance averages two wheels, so its sigma is this over
    /// `sqrt(2)`.
    pub wheel_slip_fraction: f64,
    /// Extra wheel slip per rad/s of turn rate (sheet: 0.02).
    pub wheel_slip_per_rad_s: f64,
    /// Heading change error of the wheels per metre driven, rad/m, when no
    /// gyro runs: `sqrt(2) * slip / wheel base` (0.01 and 0.33 m: 0.043).
    pub wheel_heading_rad_per_m: f64,
    /// Heading change error of the wheels per radian turned (the
    /// wheel-base error, sheet: 0.015); also the prior standard deviation
    /// of the turn scale state when the wheels give the heading.
    pub wheel_heading_rad_per_rad: f64,
    /// Random walk of the wheels' heading drift (the turn bias when no gyro
    /// runs), deg/s per sqrt(s).
    pub wheel_bias_walk_deg_s_sqrt_s: f64,
    /// Prior standard deviation of the distance scale (the tyre radius
    /// tolerance; sheet: 0.0025).
    pub distance_scale_sigma: f64,
    /// Prior standard deviation of the range bias of absolute ranges,
    /// metres (radio ranging only).
    pub range_bias_sigma_m: f64,
    /// Random walk of the range bias, metres per sqrt(s).
    pub range_bias_walk_m_sqrt_s: f64,
    /// Prior standard deviation of the range scale error of absolute
    /// ranges (a fraction of the distance).
    pub range_scale_sigma: f64,
    /// Standard deviation of the air temperature the MSU assumes (the
    /// site's, or its thermometer's), degrees Celsius (sheet: 1).
    pub temperature_sigma_c: f64,
    /// Standard deviation of each transmitter's surveyed position along any
    /// direction, metres (sheet: 0.01, the accuracy `paper`'s site survey
    /// states). Constant over a run, so fusing more cycles does not average
    /// it away: it is added to the published covariance as the position
    /// error it gives through the geometry heard (`systematic.rs`), and no
    /// arrival's sigma is taken as less than it (finer stamps do not place
    /// a transmitter better than its survey). Zero leaves it out.
    pub survey_sigma_m: f64,
    /// Least standard deviation of a cell's residual sync error against
    /// the central unit, microseconds (0: only what the cells report).
    /// Every arrival of a cell is late or early by the same amount, so it
    /// is a state per cell heard lately (`clock_slots.rs`), learnt from the
    /// range differences between cells, not noise; its prior is the sigma
    /// the cell reports in its status, at least this.
    pub cell_sync_sigma_us: f64,
    /// Random walk of a cell's sync error, as a share of its sigma per
    /// sqrt(s) (0.28). A cell's offset is the mean of the best exchanges of
    /// 12 stretches of a 25 s window (`cell-controller/src/sync.rs`): every
    /// 2.1 s one of them is replaced, which moves the mean by
    /// `sigma sqrt(2/12)`, a variance of `0.08 sigma^2` per second. So the
    /// error is not constant (as a fixed walk of a few microseconds per
    /// sqrt(s) made it, and the filter then trusted a bias the cell had
    /// moved on from) but forgotten over the cell's window.
    pub cell_sync_walk_per_sqrt_s: f64,
    /// Distance over which the air between a robot and its transmitters
    /// changes, metres (3: a heater's or an open door's warm or cold spot,
    /// an air handler's draft, are a few metres across). The site-wide
    /// speed of sound is right on average, not where the robot is: the air
    /// a robot hears through can be a few degrees off it for as long as the
    /// robot stays in one place, which scales every range it measures
    /// there alike, cycle after cycle. So the local speed's relative error
    /// is a state of the filter (`local_air_sigma_c`'s share of the speed
    /// as its spread), learnt from the differences between near and
    /// far transmitters, and forgotten as the robot drives away from where
    /// it was learnt. 0 leaves the state out, and the speed's error is then
    /// counted as noise on each arrival.
    pub air_correlation_length_m: f64,
    /// Time over which the air at one place changes, seconds (60: a door
    /// opened, a heater cycling, the hall's daily swing ahead of the
    /// site-wide speed the fleet learns over minutes).
    pub air_correlation_time_s: f64,
    /// Standard deviation of the air temperature where a robot is against
    /// the site-wide air the speed of sound is learnt for, degrees Celsius
    /// (2: a hall's warm and cold spots and its layers, a few degrees
    /// apart). The spread of the local speed state.
    pub local_air_sigma_c: f64,
    /// Standard deviation of the wind where a robot is, m/s (0: the state
    /// is left out; 0.5 in a hall whose air handlers blow 0.5 to 2 m/s
    /// where robots drive). A draft carries sound faster along it and
    /// slower against it, so the transmitters up- and downwind of a robot
    /// read short and long by a share of their distance: an error no
    /// offset or scale takes up, which a fix turns into a position error.
    /// With a spread, the local wind is a state of the filter, forgotten
    /// like the local speed of sound (over `air_correlation_length_m` and
    /// `air_correlation_time_s`). Seen from transmitters at similar
    /// distances, a wind looks like a shift of the robot, so the state
    /// lets it hide part of a heading error for a while (a 1 deg/s gyro
    /// bias step tracked 5-25 % worse at 0.5 m/s) and costs a little in
    /// still air; it is off unless the site's air calls for it.
    pub local_wind_sigma_m_s: f64,
    /// Standard deviation of the drafts where a robot is that no state of
    /// the filter carries, m/s (0.5: the low end of an air handler's 0.5
    /// to 2 m/s, as for `local_wind_sigma_m_s`). Seen from transmitters at
    /// similar distances a draft looks like a shift of the robot along it
    /// (`w r / c` for paths of length `r`), so no residual shows it, and it
    /// stays while the robot is in the draft: it is added to the published
    /// covariance as the position error it gives through the geometry heard
    /// (`systematic.rs`), not to the arrivals' noise, so the estimate is
    /// unchanged. Not used while the local wind is a state (its
    /// covariance is in the state's); 0 leaves it out.
    pub draft_sigma_m_s: f64,
}

/// The speed of sound the sync error's microseconds are turned into metres
/// and the wind's spread into a share of the speed with (20 degC): only
/// variances depend on it.
pub(super) const NOMINAL_SPEED_OF_SOUND_M_S: f64 = 343.0;

impl Default for GroundNoise {
    fn default() -> Self {
        Self {
            gyro_white_deg_s: 0.1,
            gyro_rate_hz: 100.0,
            gyro_bias_sigma_deg_s: 0.5,
            gyro_bias_walk_deg_s_sqrt_s: 0.01,
            gyro_scale_error: 0.005,
            wheel_slip_fraction: 0.01,
            wheel_slip_per_rad_s: 0.02,
            wheel_heading_rad_per_m: 0.043,
            wheel_heading_rad_per_rad: 0.015,
            wheel_bias_walk_deg_s_sqrt_s: 0.01,
            distance_scale_sigma: 0.0025,
            range_bias_sigma_m: 3.0,
            range_bias_walk_m_sqrt_s: 0.001,
            range_scale_sigma: 0.1,
            temperature_sigma_c: 1.0,
            survey_sigma_m: 0.01,
            cell_sync_sigma_us: 0.0,
            cell_sync_walk_per_sqrt_s: 0.28,
            air_correlation_length_m: 3.0,
            air_correlation_time_s: 60.0,
            local_air_sigma_c: 2.0,
            local_wind_sigma_m_s: 0.0,
            draft_sigma_m_s: 0.5,
        }
    }
}

impl GroundNoise {
    /// Variance of a measured distance `d` driven at turn rate `omega`.
    pub(super) fn var_distance(&self, d_m: f64, omega_rad_s: f64) -> f64 {
        let s = (self.wheel_slip_fraction + self.wheel_slip_per_rad_s * omega_rad_s.abs())
            / std::f64::consts::SQRT_2;
        (s * d_m).powi(2)
    }

    /// Variance of a gyro heading change integrated over `dt_s`: the angle
    /// random walk only (the scale error is a state of the filter).
    pub(super) fn var_gyro_turn(&self, dt_s: f64) -> f64 {
        let white = self.gyro_white_deg_s.to_radians();
        let arw2 = white * white / self.gyro_rate_hz.max(1e-9);
        arw2 * dt_s.abs()
    }

    /// Variance of a wheel heading change `dtheta` over distance `d`.
    pub(super) fn var_wheel_turn(&self, dtheta_rad: f64, d_m: f64) -> f64 {
        (self.wheel_heading_rad_per_m * d_m.abs()).powi(2)
            + (self.wheel_heading_rad_per_rad * dtheta_rad).powi(2)
    }

    /// Standard deviation of a cell's clock bias, metres of path.
    pub(super) fn clock_bias_sigma_m(&self) -> f64 {
        self.cell_sync_sigma_us * 1e-6 * NOMINAL_SPEED_OF_SOUND_M_S
    }

    /// Variance a cell's clock bias of sigma `sigma_m` gains over `dt_s`, m^2.
    pub(super) fn var_clock_walk(&self, sigma_m: f64, dt_s: f64) -> f64 {
        (self.cell_sync_walk_per_sqrt_s * sigma_m).powi(2) * dt_s.abs()
    }

    /// Relative standard deviation of the speed of sound the MSU assumes:
    /// the speed goes with the square root of the absolute temperature, so
    /// `0.5 sigma_T / T` at 20 degC (0.17 % for the sheet's 1 degC).
    pub(super) fn speed_of_sound_rel_sigma(&self) -> f64 {
        0.5 * self.temperature_sigma_c / 293.15
    }

    /// Standard deviation of the local wind over the speed of sound, 0
    /// when the wind is not a state.
    pub(super) fn local_wind_rel_sigma(&self) -> f64 {
        if self.air_correlation_length_m > 0.0 && self.air_correlation_time_s > 0.0 {
            self.local_wind_sigma_m_s / NOMINAL_SPEED_OF_SOUND_M_S
        } else {
            0.0
        }
    }

    /// Standard deviation of the drafts no state carries over the speed of
    /// sound: the published covariance's share of the wind, 0 while the
    /// local wind is a state.
    pub(super) fn unmodelled_wind_rel_sigma(&self) -> f64 {
        if self.learns_local_wind() {
            0.0
        } else {
            self.draft_sigma_m_s / NOMINAL_SPEED_OF_SOUND_M_S
        }
    }

    /// The same sensors ranging by radio (UWB, or any log whose
    /// propagation speed is not that of sound in air): a radio wave's speed
    /// does not depend on the air, so the assumed temperature's error, the
    /// local speed of sound and wind states and the drafts' share of the
    /// published covariance are all left out.
    pub fn without_air(self) -> Self {
        Self {
            temperature_sigma_c: 0.0,
            local_air_sigma_c: 0.0,
            local_wind_sigma_m_s: 0.0,
            draft_sigma_m_s: 0.0,
            ..self
        }
    }

    /// Whether the local wind is a state of the filter.
    pub(super) fn learns_local_wind(&self) -> bool {
        self.local_wind_rel_sigma() > 0.0
    }

    /// Whether the local speed of sound is a state of the filter.
    pub(super) fn learns_local_air(&self) -> bool {
        self.air_correlation_length_m > 0.0
            && self.air_correlation_time_s > 0.0
            && self.local_air_rel_sigma() > 0.0
    }

    /// Relative standard deviation of the local speed of sound against the
    /// site-wide one (the temperature's, as for the site-wide speed).
    pub(super) fn local_air_rel_sigma(&self) -> f64 {
        0.5 * self.local_air_sigma_c / 293.15
    }

    /// How much of the local air (its speed of sound, its wind) is still
    /// known after the robot drove `distance_m` over `dt_s`: `exp(-(|d| / L + dt / T))`, a
    /// first-order Gauss-Markov process in distance and in time.
    pub(super) fn local_air_memory(&self, distance_m: f64, dt_s: f64) -> f64 {
        if !(self.learns_local_air() || self.learns_local_wind()) {
            return 1.0;
        }
        let decay = distance_m.abs() / self.air_correlation_length_m
            + dt_s.abs() / self.air_correlation_time_s;
        (-decay).exp()
    }

    /// Checks the domain; `Err((field, reason))`. Each value also has an
    /// upper bound far beyond any real sensor's sheet, so that a typo such
    /// as `1e300` is refused by name instead of overflowing a variance and
    /// silently dropping a term later.
    pub(crate) fn check(&self) -> Result<(), (&'static str, &'static str)> {
        let fields = [
            (
                "sensors.gyro_white_deg_s",
                self.gyro_white_deg_s,
                100.0,
                "must be finite, non-negative and at most 100 deg/s",
            ),
            (
                "sensors.gyro_bias_sigma_deg_s",
                self.gyro_bias_sigma_deg_s,
                100.0,
                "must be finite, non-negative and at most 100 deg/s",
            ),
            (
                "sensors.gyro_bias_walk_deg_s_sqrt_s",
                self.gyro_bias_walk_deg_s_sqrt_s,
                10.0,
                "must be finite, non-negative and at most 10 deg/s per sqrt(s)",
            ),
            (
                "sensors.gyro_scale_error",
                self.gyro_scale_error,
                1.0,
                "must be finite, non-negative and at most 1 (100 %)",
            ),
            (
                "sensors.wheel_slip_fraction",
                self.wheel_slip_fraction,
                1.0,
                "must be finite, non-negative and at most 1 (100 %)",
            ),
            (
                "sensors.wheel_slip_per_rad_s",
                self.wheel_slip_per_rad_s,
                1.0,
                "must be finite, non-negative and at most 1 per rad/s",
            ),
            (
                "sensors.wheel_heading_rad_per_m",
                self.wheel_heading_rad_per_m,
                10.0,
                "must be finite, non-negative and at most 10 rad/m",
            ),
            (
                "sensors.wheel_heading_rad_per_rad",
                self.wheel_heading_rad_per_rad,
                1.0,
                "must be finite, non-negative and at most 1 rad/rad",
            ),
            (
                "sensors.wheel_bias_walk_deg_s_sqrt_s",
                self.wheel_bias_walk_deg_s_sqrt_s,
                10.0,
                "must be finite, non-negative and at most 10 deg/s per sqrt(s)",
            ),
            (
                "sensors.distance_scale_sigma",
                self.distance_scale_sigma,
                1.0,
                "must be finite, non-negative and at most 1 (100 %)",
            ),
        ];
        for (field, v, max, reason) in fields.into_iter().chain(self.absolute_bounds()) {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err((field, reason));
            }
        }
        if !(self.gyro_rate_hz.is_finite() && self.gyro_rate_hz > 0.0 && self.gyro_rate_hz <= 1e5) {
            return Err((
                "sensors.gyro_rate_hz",
                "must be finite, positive and at most 100 kHz",
            ));
        }
        Ok(())
    }

    /// The bounds of the absolute measurements' sheet values (ranges,
    /// the air, the survey, the cells' clocks): field, value, largest
    /// allowed, and what is wrong beyond it.
    fn absolute_bounds(&self) -> [(&'static str, f64, f64, &'static str); 12] {
        [
            (
                "sensors.range_bias_sigma_m",
                self.range_bias_sigma_m,
                1000.0,
                "must be finite, non-negative and at most 1000 m",
            ),
            (
                "sensors.range_bias_walk_m_sqrt_s",
                self.range_bias_walk_m_sqrt_s,
                10.0,
                "must be finite, non-negative and at most 10 m per sqrt(s)",
            ),
            (
                "sensors.range_scale_sigma",
                self.range_scale_sigma,
                1.0,
                "must be finite, non-negative and at most 1 (100 %)",
            ),
            (
                "sensors.temperature_sigma_c",
                self.temperature_sigma_c,
                50.0,
                "must be finite, non-negative and at most 50 degC",
            ),
            (
                "sensors.survey_sigma_m",
                self.survey_sigma_m,
                1.0,
                "must be finite, non-negative and at most 1 m",
            ),
            (
                "sensors.cell_sync_sigma_us",
                self.cell_sync_sigma_us,
                100_000.0,
                "must be finite, non-negative and at most 100000 us",
            ),
            (
                "sensors.cell_sync_walk_per_sqrt_s",
                self.cell_sync_walk_per_sqrt_s,
                100.0,
                "must be finite, non-negative and at most 100 per sqrt(s)",
            ),
            (
                "sensors.air_correlation_length_m",
                self.air_correlation_length_m,
                10_000.0,
                "must be finite, non-negative and at most 10000 m",
            ),
            (
                "sensors.local_air_sigma_c",
                self.local_air_sigma_c,
                50.0,
                "must be finite, non-negative and at most 50 degC",
            ),
            (
                "sensors.local_wind_sigma_m_s",
                self.local_wind_sigma_m_s,
                100.0,
                "must be finite, non-negative and at most 100 m/s",
            ),
            (
                "sensors.draft_sigma_m_s",
                self.draft_sigma_m_s,
                100.0,
                "must be finite, non-negative and at most 100 m/s",
            ),
            (
                "sensors.air_correlation_time_s",
                self.air_correlation_time_s,
                1e6,
                "must be finite, non-negative and at most 1e6 s",
            ),
        ]
    }
}
