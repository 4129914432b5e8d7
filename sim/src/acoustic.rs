//! The ultrasonic channel: flight of one burst to one MSU, line of sight,
//! reflections, drops, id decoding errors, and the first receiver to hear it.

use ickon_proto::site::{Site, Transmitter};
use rand_chacha::ChaCha8Rng;

use crate::air::AirField;
use crate::profile::UltrasoundNoise;
use crate::rng;

/// One burst as the MSU hears it, before its clock stamps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heard {
    /// Id the MSU decoded (wrong when decoding failed).
    pub tx_id: u32,
    /// Receiver that heard it first.
    pub receiver_id: u8,
    /// True time of arrival (detection jitter included), seconds.
    pub t_true_s: f64,
    /// Whether the sound came by a reflection.
    pub reflected: bool,
    /// Length of the path the detected sound took, metres (longer than the
    /// direct path for a reflection).
    pub path_m: f64,
}

/// Flight time from `tx` to the MSU through the air `air`, with the MSU
/// moving: solves `tau = travel(tx, p(t_emit + tau))` by fixed-point
/// iteration (it contracts by `v / c`, about 1e-3 per step).
pub fn flight_time_s(
    tx: [f64; 3],
    t_emit_s: f64,
    air: &AirField,
    msu_at: &impl Fn(f64) -> [f64; 3],
) -> f64 {
    let mut tau = air.travel_s(tx, msu_at(t_emit_s), t_emit_s);
    for _ in 0..4 {
        tau = air.travel_s(tx, msu_at(t_emit_s + tau), t_emit_s);
    }
    tau
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The receiver whose pointing angle is nearest to the bearing of the source
/// in the robot frame (`bearing_rad` counter-clockwise from the heading).
pub fn nearest_receiver(receiver_angles_rad: &[f64], bearing_rad: f64) -> u8 {
    let mut best = (f64::INFINITY, 0u8);
    for (i, a) in receiver_angles_rad.iter().enumerate() {
        let d = ickon_fusion::angle::wrap_pi(bearing_rad - a).abs();
        if d < best.0 {
            best = (d, u8::try_from(i).unwrap_or(u8::MAX));
        }
    }
    best.1
}

/// The straight path of one burst to the MSU: how long it flies and where
/// the MSU is when it arrives. Deterministic: no draw is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Path {
    /// Flight time of the direct sound, seconds.
    pub tau_s: f64,
    /// MSU position at arrival, metres.
    pub msu_m: [f64; 3],
    /// Robot heading at arrival, radians.
    pub heading_rad: f64,
    /// Length of the direct path, metres.
    pub direct_m: f64,
    /// Whether no wall or column blocks the direct path.
    pub in_sight: bool,
}

/// The direct path of a burst of `tx` emitted at true time `t_emit_s`.
pub fn propagate(
    site: &Site,
    air: &AirField,
    tx: &Transmitter,
    t_emit_s: f64,
    pose_at: &impl Fn(f64) -> ([f64; 3], f64),
) -> Path {
    let msu_at = |t: f64| pose_at(t).0;
    let tau = flight_time_s(tx.position_m, t_emit_s, air, &msu_at);
    let (p, heading) = pose_at(t_emit_s + tau);
    Path {
        tau_s: tau,
        msu_m: p,
        heading_rad: heading,
        direct_m: distance(tx.position_m, p),
        in_sight: site.line_of_sight(tx.position_m, p),
    }
}

/// What the MSU hears of one burst of `tx` emitted at true time `t_emit_s`;
/// `pose_at(t)` gives the MSU's `(x, y, z)` and the robot heading at true time `t`.
pub fn hear(
    site: &Site,
    noise: &UltrasoundNoise,
    air: &AirField,
    tx: &Transmitter,
    t_emit_s: f64,
    pose_at: &impl Fn(f64) -> ([f64; 3], f64),
    rng: &mut ChaCha8Rng,
) -> Option<Heard> {
    let path = propagate(site, air, tx, t_emit_s, pose_at);
    detect(site, noise, tx, t_emit_s, &path, rng)
}

/// Whether and how the MSU's detector picks up a burst that took `path`
/// (drops, reflections, jitter, receiver choice, id errors), before any
/// other burst is taken into account ([`crate::collision`] does that).
pub fn detect(
    site: &Site,
    noise: &UltrasoundNoise,
    tx: &Transmitter,
    t_emit_s: f64,
    path: &Path,
    rng: &mut ChaCha8Rng,
) -> Option<Heard> {
    let (tau, p, heading) = (path.tau_s, path.msu_m, path.heading_rad);
    let direct_m = path.direct_m;
    if direct_m > noise.max_range_m {
        return None;
    }
    let reflected = if path.in_sight {
        if rng::chance(rng, noise.drop_probability) {
            return None;
        }
        rng::chance(rng, noise.los_reflection_probability)
    } else if rng::chance(rng, noise.blocked_reflection_probability) {
        true
    } else {
        return None;
    };
    let extra_m = if reflected {
        rng::uniform(
            rng,
            noise.reflection_extra_m[0],
            noise.reflection_extra_m[1],
        )
    } else {
        0.0
    };
    let jitter_s = rng::normal(rng, noise.timing_jitter_us) * 1e-6;
    // A reflection's extra path flies at the direct path's mean speed.
    let path_speed_m_s = if tau > 0.0 { direct_m / tau } else { 343.0 };
    let t_true_s = t_emit_s + tau + extra_m / path_speed_m_s + jitter_s;
    // A reflection comes from wherever the reflecting surface is.
    let bearing = if reflected {
        rng::uniform(rng, -std::f64::consts::PI, std::f64::consts::PI)
    } else {
        (tx.position_m[1] - p[1]).atan2(tx.position_m[0] - p[0]) - heading
            + rng::normal(rng, noise.bearing_sigma_deg).to_radians()
    };
    let receiver_id = nearest_receiver(&site.msu.receiver_angles_rad, bearing);
    let tx_id = if rng::chance(rng, noise.id_error_probability) {
        let k = (rng::uniform(rng, 0.0, site.transmitters.len() as f64) as usize)
            .min(site.transmitters.len().saturating_sub(1));
        site.transmitters.get(k).map_or(tx.id, |t| t.id)
    } else {
        tx.id
    };
    Some(Heard {
        tx_id,
        receiver_id,
        t_true_s,
        reflected,
        path_m: direct_m + extra_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::air::Air;
    use crate::profile::NoiseProfile;
    use rand::SeedableRng;

    #[test]
    fn wall_blocks_a_transmitter_of_the_other_room_and_ideal_channel_stays_silent() {
        let site = Site::default_site();
        let noise = NoiseProfile::ideal().ultrasound;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let c = site.speed_of_sound_m_s;
        let air = AirField::new(&site, &Air::default(), 0.0);
        // In the corridor at x = 14, y = 2.2: transmitter 41 (room, y = 4.7) is behind the wall.
        let tx41 = site.transmitter(41).unwrap();
        let tx22 = site.transmitter(22).unwrap();
        let at = |_t: f64| ([14.0, 2.2, site.msu.height_m], 0.0);
        assert!(hear(&site, &noise, &air, tx41, 0.0, &at, &mut rng).is_none());
        let h = hear(&site, &noise, &air, tx22, 0.0, &at, &mut rng).unwrap();
        let d = distance(tx22.position_m, [14.0, 2.2, site.msu.height_m]);
        assert!((h.t_true_s - d / c).abs() < 1e-12);
        assert!(!h.reflected);
    }

    #[test]
    fn blocked_transmitter_is_heard_late_by_reflection_when_the_profile_says_so() {
        let site = Site::default_site();
        let mut noise = NoiseProfile::ideal().ultrasound;
        noise.blocked_reflection_probability = 1.0;
        noise.reflection_extra_m = [0.5, 0.5];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let c = site.speed_of_sound_m_s;
        let air = AirField::new(&site, &Air::default(), 0.0);
        let tx41 = site.transmitter(41).unwrap();
        let p = [14.0, 2.2, site.msu.height_m];
        let h = hear(&site, &noise, &air, tx41, 0.0, &|_t| (p, 0.0), &mut rng).unwrap();
        assert!(h.reflected);
        assert!((h.t_true_s - (distance(tx41.position_m, p) + 0.5) / c).abs() < 1e-12);
    }

    #[test]
    fn first_receiver_faces_the_transmitter() {
        let angles: Vec<f64> = (0..6).map(|i| f64::from(i) * 60f64.to_radians()).collect();
        assert_eq!(nearest_receiver(&angles, 0.1), 0);
        assert_eq!(nearest_receiver(&angles, 65f64.to_radians()), 1);
        assert_eq!(nearest_receiver(&angles, -50f64.to_radians()), 5);
        assert_eq!(nearest_receiver(&angles, 179f64.to_radians()), 3);
    }

    #[test]
    fn moving_msu_flight_time_solves_the_light_cone() {
        let site = Site::default_site();
        let air = AirField::new(&site, &Air::default(), 0.0);
        let tx = [0.0, 0.0, 3.0];
        let at = |t: f64| [1.0 + 0.5 * t, 0.0, 0.0];
        let tau = flight_time_s(tx, 0.0, &air, &at);
        let c = site.speed_of_sound_m_s;
        assert!((c * tau - distance(tx, at(tau))).abs() < 1e-9);
    }

    #[test]
    fn arrival_jitter_matches_the_profile_sigma() {
        let site = Site::default_site();
        let mut noise = NoiseProfile::ideal().ultrasound;
        noise.timing_jitter_us = 50.0;
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let c = site.speed_of_sound_m_s;
        let air = AirField::new(&site, &Air::default(), 0.0);
        let tx = site.transmitter(22).unwrap();
        let p = [14.0, 1.2, site.msu.height_m];
        let exact = distance(tx.position_m, p) / c;
        let errs: Vec<f64> = (0..5000)
            .map(|_| {
                hear(&site, &noise, &air, tx, 0.0, &|_t| (p, 0.0), &mut rng)
                    .unwrap()
                    .t_true_s
                    - exact
            })
            .collect();
        let n = errs.len() as f64;
        let mean = errs.iter().sum::<f64>() / n;
        let sd = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!(mean.abs() < 4.0 * 50e-6 / n.sqrt());
        assert!((sd / 50e-6 - 1.0).abs() < 0.05, "sd {sd}");
    }

    #[test]
    fn drop_rate_matches_the_profile_probability() {
        let site = Site::default_site();
        let mut noise = NoiseProfile::ideal().ultrasound;
        noise.drop_probability = 0.2;
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        let air = AirField::new(&site, &Air::default(), 0.0);
        let tx = site.transmitter(22).unwrap();
        let p = [14.0, 1.2, site.msu.height_m];
        let lost = (0..10_000)
            .filter(|_| hear(&site, &noise, &air, tx, 0.0, &|_t| (p, 0.0), &mut rng).is_none())
            .count();
        // 0.2 +- 4 sigma of a binomial share over 10 000 draws.
        assert!((lost as f64 / 10_000.0 - 0.2).abs() < 0.016, "{lost} lost");
    }
}
