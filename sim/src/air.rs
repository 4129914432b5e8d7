//! The air of the hall: what the speed of sound and the drafts do to a
//! burst's flight. The MSU assumes one speed of sound, the site file's;
//! a real hall has none. Its temperature follows the day (cold in the
//! morning, warm in the afternoon), is warmer under the ceiling than at the
//! floor, warmer by a heater and colder by a door, and steps when a door
//! opens; its air handlers blow drafts that carry sound faster along them
//! and slower against them.
//!
//! A burst's travel time is the integral of `1 / (c(T(p)) + u(p) . d)`
//! along the straight ray from the transmitter to the receiver (`T` the
//! temperature, `u` the wind, `d` the ray's direction). The ray is kept
//! straight: refraction in a gradient of a degree per metre bends a
//! ten-metre ray by millimetres, and by Fermat's principle a path's time
//! changes only to second order with its shape. The integral is taken with
//! five-point Gauss-Legendre quadrature: the integrand is smooth at the
//! scale of a spot or a draft (metres), and five points match a
//! 400-point midpoint rule to within 0.2 us (0.07 mm of range, a
//! three-hundredth of the detectors' timing noise) on every path of the
//! built-in sites (`sim::air` tests).
//!
//! Spots and drafts are placed in fractions of the site's floor (its
//! bounding box), so that one profile fits every site.

use ickon_proto::site::{Site, speed_of_sound_at};
use serde::{Deserialize, Serialize};

/// Height at which the site file's nominal temperature is taken, metres:
/// where a wall thermostat reads the hall.
pub const NOMINAL_HEIGHT_M: f64 = 1.5;

/// A warm or cold spot: a heater, a sunlit skylight, a cold door.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spot {
    /// Centre as fractions of the floor's bounding box, `[x, y]` in 0..1.
    pub at: [f64; 2],
    /// Radius (the Gaussian's sigma) on the floor, metres.
    pub radius_m: f64,
    /// Temperature at the centre above the hall's, degrees Celsius.
    pub delta_c: f64,
}

/// A draft from an air handler: a horizontal wind, strongest at its centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Draft {
    /// Centre as fractions of the floor's bounding box, `[x, y]` in 0..1.
    pub at: [f64; 2],
    /// Radius (the Gaussian's sigma) on the floor, metres.
    pub radius_m: f64,
    /// Wind at the centre, `[east, north]`, m/s.
    pub velocity_m_s: [f64; 2],
}

/// A sudden change of the whole hall's temperature: a gate opened to the
/// yard, a heater switched on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    /// When, seconds from the start of the run.
    pub at_s: f64,
    /// The change, degrees Celsius.
    pub delta_c: f64,
    /// Time constant with which the hall returns to its course, seconds
    /// (0: it stays changed).
    pub recover_s: f64,
}

/// The air of a hall over a run. The default is still air at one
/// temperature everywhere.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Air {
    /// Peak-to-peak swing of the hall's temperature over a day, compressed
    /// into [`Self::swing_period_s`], degrees Celsius: the hall starts at
    /// its coldest, half a swing under the mean.
    pub swing_c: f64,
    /// Period of the swing, seconds (the run's "day"; 0: no swing).
    pub swing_period_s: f64,
    /// How much warmer the air is per metre of height, degrees Celsius per
    /// metre (warm air collects under the ceiling).
    pub gradient_c_per_m: f64,
    /// Warm and cold spots.
    pub spots: Vec<Spot>,
    /// Drafts.
    pub drafts: Vec<Draft>,
    /// Steps of the whole hall's temperature.
    pub steps: Vec<Step>,
}

impl Air {
    /// The air of a real hall: a 10 degree swing over a 20-minute "day"
    /// (a ten-minute run goes from the coldest morning to the warmest
    /// afternoon), 1 degree per metre of height, a heater (+3) and a cold
    /// gate (-3), two drafts of 1 m/s, and a gate opened at 240 s that
    /// cools the hall by 3 degrees, recovered over two minutes. The values
    /// are those of heated warehouses and factory halls: daily swings of 5
    /// to 15 degrees, stratification of 0.5 to 2 degrees per metre, air
    /// handlers' drafts of 0.5 to 2 m/s.
    pub fn building() -> Self {
        Self {
            swing_c: 10.0,
            swing_period_s: 1200.0,
            gradient_c_per_m: 1.0,
            spots: vec![
                Spot {
                    at: [0.25, 0.7],
                    radius_m: 2.5,
                    delta_c: 3.0,
                },
                Spot {
                    at: [0.8, 0.3],
                    radius_m: 2.5,
                    delta_c: -3.0,
                },
            ],
            drafts: vec![
                Draft {
                    at: [0.5, 0.5],
                    radius_m: 3.0,
                    velocity_m_s: [1.0, 0.0],
                },
                Draft {
                    at: [0.15, 0.25],
                    radius_m: 3.0,
                    velocity_m_s: [0.0, -1.0],
                },
            ],
            steps: vec![Step {
                at_s: 240.0,
                delta_c: -3.0,
                recover_s: 120.0,
            }],
        }
    }

    /// Whether the air is still and even (the travel time is the distance
    /// over one speed).
    pub fn is_calm(&self) -> bool {
        self.swing_c == 0.0
            && self.gradient_c_per_m == 0.0
            && self.spots.is_empty()
            && self.drafts.is_empty()
            && self.steps.is_empty()
    }

    /// The first value out of its range, as (field, reason).
    pub fn check(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, reason: String| Err((format!("ultrasound.air.{field}"), reason));
        let within = |v: f64, bound: f64| v.is_finite() && v.abs() <= bound;
        if !within(self.swing_c, 60.0) || self.swing_c < 0.0 {
            return bad("swing_c", format!("is {}: within 0 to 60", self.swing_c));
        }
        if !within(self.swing_period_s, 1e7) || self.swing_period_s < 0.0 {
            return bad(
                "swing_period_s",
                format!("is {}: within 0 to 1e7", self.swing_period_s),
            );
        }
        if !within(self.gradient_c_per_m, 20.0) {
            return bad(
                "gradient_c_per_m",
                format!("is {}: within -20 to 20", self.gradient_c_per_m),
            );
        }
        let fraction = |p: [f64; 2]| p.iter().all(|v| (0.0..=1.0).contains(v));
        for (i, s) in self.spots.iter().enumerate() {
            let good =
                fraction(s.at) && s.radius_m > 0.0 && s.radius_m <= 1e3 && within(s.delta_c, 40.0);
            if !good {
                return bad(
                    &format!("spots[{i}]"),
                    "needs `at` within 0 to 1, a radius above 0 up to 1000 m, a delta within -40 to 40".into(),
                );
            }
        }
        for (i, d) in self.drafts.iter().enumerate() {
            let good = fraction(d.at)
                && d.radius_m > 0.0
                && d.radius_m <= 1e3
                && d.velocity_m_s.iter().all(|v| within(*v, 20.0));
            if !good {
                return bad(
                    &format!("drafts[{i}]"),
                    "needs `at` within 0 to 1, a radius above 0 up to 1000 m, a wind within -20 to 20 m/s".into(),
                );
            }
        }
        for (i, s) in self.steps.iter().enumerate() {
            let good = within(s.at_s, 1e7)
                && s.at_s >= 0.0
                && within(s.delta_c, 40.0)
                && within(s.recover_s, 1e7)
                && s.recover_s >= 0.0;
            if !good {
                return bad(
                    &format!("steps[{i}]"),
                    "needs a time within 0 to 1e7 s, a delta within -40 to 40, a recovery within 0 to 1e7 s".into(),
                );
            }
        }
        Ok(())
    }
}

/// The air of one site: [`Air`] placed on its floor, about the site's
/// nominal temperature.
#[derive(Debug, Clone, PartialEq)]
pub struct AirField {
    /// The temperature the MSU assumes, degrees Celsius.
    nominal_c: f64,
    /// The site's speed of sound at `nominal_c`, m/s: the true speed is
    /// scaled from it, so a site that names a speed rather than a
    /// temperature keeps it.
    nominal_speed_m_s: f64,
    /// The hall's mean temperature off the nominal, degrees Celsius.
    offset_c: f64,
    air: Air,
    /// Spots and drafts in metres: `(x, y, sigma)`.
    spots_m: Vec<([f64; 2], f64, f64)>,
    drafts_m: Vec<([f64; 2], f64, [f64; 2])>,
}

/// Gauss-Legendre nodes on [0, 1] and their weights (five points).
const NODES: [(f64, f64); 5] = [
    (0.046_910_077_030_668, 0.118_463_442_528_095),
    (0.230_765_344_947_158, 0.239_314_335_249_683),
    (0.5, 0.284_444_444_444_444),
    (0.769_234_655_052_842, 0.239_314_335_249_683),
    (0.953_089_922_969_332, 0.118_463_442_528_095),
];

impl AirField {
    /// `air` over `site`, its mean `offset_c` degrees off the site's
    /// nominal temperature (the profile's `temperature_error_c`).
    pub fn new(site: &Site, air: &Air, offset_c: f64) -> Self {
        let (lo, hi) = site.bounds();
        let place = |at: [f64; 2]| {
            [
                lo[0] + at[0] * (hi[0] - lo[0]),
                lo[1] + at[1] * (hi[1] - lo[1]),
            ]
        };
        Self {
            nominal_c: site.temperature_c.unwrap_or(20.0),
            nominal_speed_m_s: site.speed_of_sound_m_s,
            offset_c,
            air: air.clone(),
            spots_m: air
                .spots
                .iter()
                .map(|s| (place(s.at), s.radius_m, s.delta_c))
                .collect(),
            drafts_m: air
                .drafts
                .iter()
                .map(|d| (place(d.at), d.radius_m, d.velocity_m_s))
                .collect(),
        }
    }

    /// The hall's temperature at height [`NOMINAL_HEIGHT_M`] away from
    /// every spot at `t_s`, degrees Celsius.
    pub fn hall_c(&self, t_s: f64) -> f64 {
        let a = &self.air;
        let swing = if a.swing_period_s > 0.0 {
            -0.5 * a.swing_c * (std::f64::consts::TAU * t_s / a.swing_period_s).cos()
        } else {
            0.0
        };
        let steps: f64 = a
            .steps
            .iter()
            .filter(|s| t_s >= s.at_s)
            .map(|s| {
                if s.recover_s > 0.0 {
                    s.delta_c * (-(t_s - s.at_s) / s.recover_s).exp()
                } else {
                    s.delta_c
                }
            })
            .sum();
        self.nominal_c + self.offset_c + swing + steps
    }

    /// The temperature at `p` (metres) at `t_s`, degrees Celsius.
    pub fn temperature_c(&self, p: [f64; 3], t_s: f64) -> f64 {
        let spots: f64 = self
            .spots_m
            .iter()
            .map(|&(c, sigma, delta)| delta * gaussian(p, c, sigma))
            .sum();
        self.hall_c(t_s) + self.air.gradient_c_per_m * (p[2] - NOMINAL_HEIGHT_M) + spots
    }

    /// The speed of sound in still air at `p` at `t_s`, m/s.
    pub fn speed_m_s(&self, p: [f64; 3], t_s: f64) -> f64 {
        // Scaled from the site's own speed, so that a site naming a speed
        // instead of a temperature keeps its speed at the nominal air.
        let t = self.temperature_c(p, t_s).max(-200.0);
        self.nominal_speed_m_s * speed_of_sound_at(t) / speed_of_sound_at(self.nominal_c)
    }

    /// The wind at `p`, `[east, north]`, m/s.
    pub fn wind_m_s(&self, p: [f64; 3]) -> [f64; 2] {
        let mut w = [0.0; 2];
        for &(c, sigma, v) in &self.drafts_m {
            let g = gaussian(p, c, sigma);
            w[0] += v[0] * g;
            w[1] += v[1] * g;
        }
        w
    }

    /// Travel time of sound from `from` to `to` (metres) leaving at `t_s`,
    /// seconds (see the module docs).
    pub fn travel_s(&self, from: [f64; 3], to: [f64; 3], t_s: f64) -> f64 {
        let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if length < 1e-9 {
            return 0.0;
        }
        if self.air.is_calm() {
            return length / self.speed_m_s(from, t_s);
        }
        let dir = d.map(|v| v / length);
        let slowness: f64 = NODES
            .iter()
            .map(|&(s, w)| {
                let p = [from[0] + s * d[0], from[1] + s * d[1], from[2] + s * d[2]];
                let wind = self.wind_m_s(p);
                let along = wind[0] * dir[0] + wind[1] * dir[1];
                // Never slower than a tenth of the still air: a gale is
                // not a hall's draft, and the ray must stay finite.
                w / (self.speed_m_s(p, t_s) + along).max(0.1 * self.speed_m_s(p, t_s))
            })
            .sum();
        length * slowness
    }

    /// The effective speed of sound from `from` to `to` at `t_s` (the
    /// distance over the travel time), m/s: what a system that knew the
    /// air perfectly would use for that path.
    pub fn path_speed_m_s(&self, from: [f64; 3], to: [f64; 3], t_s: f64) -> f64 {
        let tau = self.travel_s(from, to, t_s);
        let length = distance(from, to);
        if tau > 0.0 {
            length / tau
        } else {
            self.speed_m_s(from, t_s)
        }
    }
}

/// A unit-height Gaussian of `p`'s horizontal distance from `centre`.
fn gaussian(p: [f64; 3], centre: [f64; 2], sigma: f64) -> f64 {
    let r2 = (p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2);
    (-0.5 * r2 / (sigma * sigma)).exp()
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The travel time by a fine midpoint rule.
    fn midpoint_s(field: &AirField, from: [f64; 3], to: [f64; 3], t_s: f64) -> f64 {
        let n = 400;
        let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
        let length = distance(from, to);
        let dir = d.map(|v| v / length);
        (0..n)
            .map(|i| {
                let s = (f64::from(i) + 0.5) / f64::from(n);
                let p = [from[0] + s * d[0], from[1] + s * d[1], from[2] + s * d[2]];
                let w = field.wind_m_s(p);
                length / f64::from(n) / (field.speed_m_s(p, t_s) + w[0] * dir[0] + w[1] * dir[1])
            })
            .sum()
    }

    #[test]
    fn five_points_integrate_every_path_of_the_built_in_sites_within_a_fifth_of_a_microsecond() {
        for site in [Site::default_site(), Site::builtin("warehouse").unwrap().0] {
            let field = AirField::new(&site, &Air::building(), 0.0);
            let (lo, hi) = site.bounds();
            let mut worst: f64 = 0.0;
            for tx in &site.transmitters {
                for i in 0..=10 {
                    for j in 0..=10 {
                        let p = [
                            lo[0] + (hi[0] - lo[0]) * f64::from(i) / 10.0,
                            lo[1] + (hi[1] - lo[1]) * f64::from(j) / 10.0,
                            site.msu.height_m,
                        ];
                        if distance(p, tx.position_m) > 12.0 {
                            continue;
                        }
                        let e = field.travel_s(tx.position_m, p, 300.0)
                            - midpoint_s(&field, tx.position_m, p, 300.0);
                        worst = worst.max(e.abs());
                    }
                }
            }
            assert!(worst < 2e-7, "{}: {worst} s", site.name);
        }
    }

    #[test]
    fn calm_air_at_the_nominal_temperature_is_the_site_speed() {
        let site = Site::default_site();
        let field = AirField::new(&site, &Air::default(), 0.0);
        let (a, b) = ([1.0, 1.0, 3.0], [4.0, 5.0, 0.3]);
        let tau = field.travel_s(a, b, 100.0);
        assert!((tau * site.speed_of_sound_m_s - distance(a, b)).abs() < 1e-12);
    }

    #[test]
    fn a_draft_speeds_sound_along_it_and_slows_it_against_it() {
        let site = Site::default_site();
        let air = Air {
            drafts: vec![Draft {
                at: [0.5, 0.5],
                radius_m: 100.0,
                velocity_m_s: [2.0, 0.0],
            }],
            ..Air::default()
        };
        let field = AirField::new(&site, &air, 0.0);
        let (a, b) = ([2.0, 2.0, 1.0], [6.0, 2.0, 1.0]);
        let down = field.path_speed_m_s(a, b, 0.0);
        let up = field.path_speed_m_s(b, a, 0.0);
        let c = site.speed_of_sound_m_s;
        assert!((down - c - 2.0).abs() < 0.01, "{down}");
        assert!((up - c + 2.0).abs() < 0.01, "{up}");
    }

    #[test]
    fn a_linear_gradient_gives_every_ray_the_temperature_of_its_mid_height() {
        let site = Site::default_site();
        let air = Air {
            gradient_c_per_m: 1.0,
            ..Air::default()
        };
        let field = AirField::new(&site, &air, 0.0);
        for (a, b) in [
            ([0.0, 0.0, 3.0], [1.0, 0.0, 0.3]),
            ([0.0, 0.0, 3.0], [8.0, 3.0, 0.3]),
        ] {
            let mid = [0.0, 0.0, 0.5 * (a[2] + b[2])];
            let speed = field.path_speed_m_s(a, b, 0.0);
            // The slowness is averaged, not the speed: equal to 1e-5 relative.
            assert!((speed / field.speed_m_s(mid, 0.0) - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn the_hall_swings_from_cold_to_warm_and_a_step_recovers() {
        let site = Site::default_site();
        let field = AirField::new(&site, &Air::building(), 0.0);
        let nominal = site.temperature_c.unwrap_or(20.0);
        assert!((field.hall_c(0.0) - (nominal - 5.0)).abs() < 1e-9);
        assert!((field.hall_c(600.0) - (nominal + 5.0 - 3.0 * (-3.0f64).exp())).abs() < 1e-9);
        let before = field.hall_c(239.999);
        let after = field.hall_c(240.0);
        assert!((after - before + 3.0).abs() < 0.01);
    }

    #[test]
    fn out_of_range_air_is_refused_naming_the_field() {
        let mut air = Air::building();
        assert_eq!(air.check(), Ok(()));
        air.spots[1].at = [1.5, 0.0];
        assert_eq!(air.check().unwrap_err().0, "ultrasound.air.spots[1]");
        let air = Air {
            swing_c: f64::NAN,
            ..Air::default()
        };
        assert_eq!(air.check().unwrap_err().0, "ultrasound.air.swing_c");
        let air = Air {
            steps: vec![Step {
                at_s: -1.0,
                delta_c: 1.0,
                recover_s: 0.0,
            }],
            ..Air::default()
        };
        assert_eq!(air.check().unwrap_err().0, "ultrasound.air.steps[0]");
    }
}
