//! The air temperature sensors on the cells' transmitter boards: each
//! reads the world's air ([`AirField`]) where its board hangs (the middle
//! of its cell's transmitters, under the ceiling), with a bias of its own
//! drawn once from the seed, noise on every reading, and the board's
//! resolution (0.01 degree, the device protocol's). Faults make a sensor
//! stuck at its last reading, report no valid reading (not a number), or
//! jump by 25 degrees every other reading, from a time on.
//!
//! The profile's `[air_sensors]` describes them (absent: no board has a
//! sensor, as on sites whose boards lack one).

use ickon_proto::site::Site;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::air::AirField;
use crate::rng::{normal, stream};

/// How far a jumping sensor jumps, degrees Celsius.
const JUMP_C: f64 = 25.0;

/// What goes wrong with a board's sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SensorFaultKind {
    /// It repeats its last reading for good.
    Stuck,
    /// It has no valid reading (the board reports "none", read as not a number).
    NotANumber,
    /// Every other reading is 25 degrees off.
    Jumping,
}

/// A fault of one cell's sensor from a time on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorFault {
    /// The cell whose board's sensor fails.
    pub cell: String,
    /// From when, seconds from the start of the run.
    pub at_s: f64,
    /// How.
    pub kind: SensorFaultKind,
}

/// The boards' sensors of a profile (`[air_sensors]`). The default is no
/// sensor at all.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AirSensors {
    /// Readings per second of each board (0: no board has a sensor).
    pub rate_hz: f64,
    /// One-sigma bias of each sensor, drawn once per board, degrees Celsius.
    pub bias_sigma_c: f64,
    /// One-sigma noise of each reading, degrees Celsius.
    pub noise_sigma_c: f64,
    /// Sensors that fail.
    pub faults: Vec<SensorFault>,
}

impl AirSensors {
    /// The sensors of typical boards: a reading a second, a bias of half a
    /// degree and a tenth of a degree of noise (the data sheets of digital
    /// sensors of +-0.5 C accuracy).
    pub fn typical() -> Self {
        Self {
            rate_hz: 1.0,
            bias_sigma_c: 0.5,
            noise_sigma_c: 0.1,
            faults: Vec::new(),
        }
    }

    /// Whether no board has a sensor.
    pub fn is_absent(&self) -> bool {
        self.rate_hz == 0.0 && self.faults.is_empty()
    }

    /// The first value out of its range, as (field, reason).
    pub fn check(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, reason: String| Err((format!("air_sensors.{field}"), reason));
        let within = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
        if !within(self.rate_hz, 0.0, 100.0) {
            return bad("rate_hz", format!("is {}: within 0 to 100", self.rate_hz));
        }
        if !within(self.bias_sigma_c, 0.0, 20.0) {
            return bad(
                "bias_sigma_c",
                format!("is {}: within 0 to 20", self.bias_sigma_c),
            );
        }
        if !within(self.noise_sigma_c, 0.0, 20.0) {
            return bad(
                "noise_sigma_c",
                format!("is {}: within 0 to 20", self.noise_sigma_c),
            );
        }
        for (i, f) in self.faults.iter().enumerate() {
            if !within(f.at_s, 0.0, 1e7) || f.cell.is_empty() {
                return bad(
                    &format!("faults[{i}]"),
                    "needs a cell and a time within 0 to 1e7 s".into(),
                );
            }
        }
        Ok(())
    }
}

/// One board's sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct AirSensor {
    /// Where it hangs, metres.
    at_m: [f64; 3],
    bias_c: f64,
    noise_sigma_c: f64,
    fault: Option<(f64, SensorFaultKind)>,
    rng: ChaCha8Rng,
    /// The last reading given, degrees Celsius.
    last_c: f64,
    readings: u64,
}

impl AirSensor {
    /// The sensor of `cell`'s board at `at_m`, as `spec` describes, its
    /// bias and noise drawn from `seed`.
    pub fn new(cell: &str, at_m: [f64; 3], spec: &AirSensors, seed: u64) -> Self {
        let mut rng = stream(seed, &format!("air-sensor/{cell}"));
        let bias_c = normal(&mut rng, spec.bias_sigma_c);
        let fault = spec
            .faults
            .iter()
            .find(|f| f.cell == cell)
            .map(|f| (f.at_s, f.kind));
        Self {
            at_m,
            bias_c,
            noise_sigma_c: spec.noise_sigma_c,
            fault,
            rng,
            last_c: f64::NAN,
            readings: 0,
        }
    }

    /// Where the sensor hangs, metres.
    pub fn at_m(&self) -> [f64; 3] {
        self.at_m
    }

    /// Its bias, degrees Celsius.
    pub fn bias_c(&self) -> f64 {
        self.bias_c
    }

    /// A reading of `air` at `t_s` (seconds from the start of the run),
    /// degrees Celsius at the board's resolution (0.01); not a number when
    /// the sensor has no valid reading.
    pub fn read(&mut self, air: &AirField, t_s: f64) -> f64 {
        self.readings += 1;
        let noise = normal(&mut self.rng, self.noise_sigma_c);
        let true_c = air.temperature_c(self.at_m, t_s);
        let fresh = ((true_c + self.bias_c + noise) * 100.0).round() / 100.0;
        let reading = match self.fault {
            Some((from_s, kind)) if t_s >= from_s => match kind {
                SensorFaultKind::Stuck if self.last_c.is_finite() => self.last_c,
                SensorFaultKind::Stuck => fresh,
                SensorFaultKind::NotANumber => f64::NAN,
                SensorFaultKind::Jumping if self.readings.is_multiple_of(2) => fresh + JUMP_C,
                SensorFaultKind::Jumping => fresh,
            },
            _ => fresh,
        };
        self.last_c = reading;
        reading
    }
}

/// Where `cell`'s board hangs on `site`: the middle of its transmitters
/// (`None`: the cell has none).
pub fn board_position(site: &Site, cell: &str) -> Option<[f64; 3]> {
    let mut sum = [0.0; 3];
    let mut n = 0.0;
    for t in site.transmitters.iter().filter(|t| t.cell == cell) {
        for (s, p) in sum.iter_mut().zip(t.position_m) {
            *s += p;
        }
        n += 1.0;
    }
    (n > 0.0).then(|| sum.map(|s| s / n))
}

/// Every cell board's sensor of a run, read at the profile's rate.
#[derive(Debug, Clone)]
pub struct CellAirSensors {
    sensors: Vec<(String, AirSensor)>,
    period_s: f64,
    next_s: f64,
}

impl CellAirSensors {
    /// The sensors of `site`'s cells (the site as the world has it: the
    /// transmitters where they really hang) as `spec` describes them;
    /// `None` when no board has one.
    pub fn new(site: &Site, spec: &AirSensors, seed: u64) -> Option<Self> {
        if spec.rate_hz.is_nan() || spec.rate_hz <= 0.0 {
            return None;
        }
        let sensors = site
            .cells
            .iter()
            .filter_map(|c| {
                let at = board_position(site, &c.id)?;
                Some((c.id.clone(), AirSensor::new(&c.id, at, spec, seed)))
            })
            .collect();
        Some(Self {
            sensors,
            period_s: 1.0 / spec.rate_hz,
            next_s: 0.0,
        })
    }

    /// The readings due by `t_s`, each board's at each period: (cell,
    /// seconds measured, degrees Celsius).
    pub fn due(&mut self, air: &AirField, t_s: f64) -> Vec<(String, f64, f64)> {
        let mut out = Vec::new();
        while self.next_s <= t_s {
            let at = self.next_s;
            for (cell, sensor) in &mut self.sensors {
                out.push((cell.clone(), at, sensor.read(air, at)));
            }
            self.next_s += self.period_s;
        }
        out
    }
}

#[cfg(test)]
mod tests;
