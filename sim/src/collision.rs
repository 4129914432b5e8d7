//! Collisions and reverberation at one MSU: which of the bursts its detector
//! picked up survive the other bursts' sound on the same carrier channel.
//!
//! Without this a schedule that fires bursts closer together would look
//! free in simulation. The model ([`CollisionModel`] in the noise profile,
//! the burst length and decoder window from the site):
//!
//! - every burst that reaches the MSU in line of sight within the profile's
//!   range is a [`Sound`], heard or not by the detector (a dropped detection
//!   still puts energy in the air); reflected sound is left out as an
//!   interferer (it is weaker and spread in time);
//! - two sounds on one channel whose onsets are closer than the burst length
//!   plus the decoder window **collide**: the detection is lost, or, with
//!   the profile's probability, comes out at the earlier onset with the
//!   stronger burst's id;
//! - a detected burst that starts inside an earlier sound's **reverberation
//!   tail** (starting `reverb_tail_db` under that sound when it ends, dying
//!   at `reverb_decay_db_per_ms`) less than `detection_snr_db` above it is
//!   **masked** and lost.
//!
//! Draws come from the caller's own stream, so a run without collisions
//! draws exactly what it drew before this model existed.

use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::acoustic::Heard;
use crate::profile::CollisionModel;
use crate::rng;

/// The sound of one burst at one MSU, whether or not its detector picked it up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sound {
    /// The transmitter that fired.
    pub tx_id: u32,
    /// Its carrier channel.
    pub channel: u8,
    /// True time the direct sound reaches the MSU, seconds.
    pub onset_s: f64,
    /// Level at the MSU, dB relative to the burst at 1 m.
    pub level_db: f64,
}

/// The site's burst timing, seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BurstTiming {
    /// Length of one burst.
    pub burst_s: f64,
    /// How long after a burst the decoder still takes sound as part of it.
    pub window_s: f64,
}

impl BurstTiming {
    /// The timing of `site`'s bursts.
    pub fn of(site: &ickon_proto::site::Site) -> Self {
        Self {
            burst_s: site.burst_length_s,
            window_s: site.decoder_window_s,
        }
    }

    /// Onsets closer than this collide.
    pub fn collision_s(&self) -> f64 {
        self.burst_s + self.window_s
    }
}

/// What happened to one detected burst.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fate {
    /// Nothing else on its channel spoiled it.
    Clear,
    /// It overlapped sound `with` (an index into the sounds).
    Collided {
        /// The other sound.
        with: usize,
    },
    /// It started in the reverberation tail of sound `by`.
    Masked {
        /// The earlier, louder sound.
        by: usize,
    },
}

/// What the collisions did over a run, counted per detected burst whose
/// direct path reached the MSU. Detections of blocked transmitters (only
/// a reflection came through: a rack or wall between, so the schedule may
/// fire them together with the transmitters in sight) are counted apart.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct CollisionCounts {
    /// Bursts the detector picked up before collisions were considered.
    pub detected: u64,
    /// Detections of blocked transmitters, heard only by a reflection.
    pub blocked_detected: u64,
    /// Of those, how many collisions and masking took.
    pub blocked_lost: u64,
    /// Of those, how many overlapped another burst on their channel.
    pub collided: u64,
    /// Of the collided ones, how many still gave a detection (earlier onset, stronger id).
    pub misdecoded: u64,
    /// Detected bursts lost in an earlier burst's reverberation tail.
    pub masked: u64,
}

impl CollisionCounts {
    /// Detections lost to collisions and masking.
    pub fn lost(&self) -> u64 {
        self.collided - self.misdecoded + self.masked
    }

    /// [`lost`](Self::lost) as a share of the detected bursts (0 when none).
    pub fn lost_share(&self) -> f64 {
        if self.detected == 0 {
            0.0
        } else {
            self.lost() as f64 / self.detected as f64
        }
    }

    /// Both counts added.
    pub fn add(&mut self, other: &CollisionCounts) {
        self.detected += other.detected;
        self.blocked_detected += other.blocked_detected;
        self.blocked_lost += other.blocked_lost;
        self.collided += other.collided;
        self.misdecoded += other.misdecoded;
        self.masked += other.masked;
    }
}

/// Level of a burst after `path_m` metres, dB relative to 1 m (paths under
/// 10 cm are taken as 10 cm).
pub fn level_db(model: &CollisionModel, path_m: f64) -> f64 {
    let d = path_m.max(0.1);
    -20.0 * d.log10() - model.absorption_db_per_m * d
}

/// The fate of a burst on `channel` detected at `onset_s` with `level_db`,
/// among `sounds`; `own` is its own entry there (not an interferer).
pub fn fate(
    model: &CollisionModel,
    timing: &BurstTiming,
    channel: u8,
    onset_s: f64,
    level: f64,
    own: Option<usize>,
    sounds: &[Sound],
) -> Fate {
    let mut masked = None;
    for (j, s) in sounds.iter().enumerate() {
        if Some(j) == own || s.channel != channel {
            continue;
        }
        let dt_s = onset_s - s.onset_s;
        if dt_s.abs() < timing.collision_s() {
            return Fate::Collided { with: j };
        }
        if dt_s > 0.0 && masked.is_none() {
            let since_end_ms = (dt_s - timing.burst_s) * 1e3;
            let tail =
                s.level_db + model.reverb_tail_db - model.reverb_decay_db_per_ms * since_end_ms;
            if tail > level - model.detection_snr_db {
                masked = Some(j);
            }
        }
    }
    masked.map_or(Fate::Clear, |by| Fate::Masked { by })
}

/// One detection before collisions: what was heard, its channel, and its
/// own sound among the sounds (none when only a reflection reached the MSU).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// What the detector picked up.
    pub heard: Heard,
    /// Carrier channel of the burst.
    pub channel: u8,
    /// Index of the burst's own direct sound.
    pub own: Option<usize>,
}

/// The detections that survive the other `sounds`, counted into `counts`;
/// one detection per id is kept (the earliest), as the MSU takes an id
/// once per cycle. `rng` decides the mis-decodings.
pub fn resolve(
    model: &CollisionModel,
    timing: &BurstTiming,
    detections: &[Detection],
    sounds: &[Sound],
    rng: &mut ChaCha8Rng,
    counts: &mut CollisionCounts,
) -> Vec<Heard> {
    let mut out: Vec<Heard> = Vec::with_capacity(detections.len());
    for d in detections {
        let h = d.heard;
        if d.own.is_none() {
            counts.blocked_detected += 1;
            let level = level_db(model, h.path_m) - model.reflection_loss_db;
            match fate(model, timing, d.channel, h.t_true_s, level, None, sounds) {
                Fate::Clear => out.push(h),
                _ => counts.blocked_lost += 1,
            }
            continue;
        }
        counts.detected += 1;
        let loss = if h.reflected {
            model.reflection_loss_db
        } else {
            0.0
        };
        let level = level_db(model, h.path_m) - loss;
        match fate(model, timing, d.channel, h.t_true_s, level, d.own, sounds) {
            Fate::Clear => out.push(h),
            Fate::Masked { .. } => counts.masked += 1,
            Fate::Collided { with } => {
                counts.collided += 1;
                if rng::chance(rng, model.misdecode_probability) {
                    counts.misdecoded += 1;
                    let other = &sounds[with];
                    out.push(Heard {
                        tx_id: if other.level_db > level {
                            other.tx_id
                        } else {
                            h.tx_id
                        },
                        t_true_s: h.t_true_s.min(other.onset_s),
                        ..h
                    });
                }
            }
        }
    }
    out.sort_by(|a, b| a.t_true_s.total_cmp(&b.t_true_s));
    let mut seen = std::collections::HashSet::new();
    out.retain(|h| seen.insert(h.tx_id));
    out
}

#[cfg(test)]
mod tests;
