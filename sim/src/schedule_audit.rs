//! Whether a schedule lets every burst through everywhere: at every point
//! of a grid over the cells (MSU height), the sound of every emission of
//! one cycle and of the cycles before and after it, and the
//! [`collision::fate`] of each audible one. Today's schedules must show no
//! collision; a shorter one is only worth what this says it loses.

use ickon_proto::msg::control::Schedule;
use ickon_proto::site::Site;
use serde::Serialize;

use crate::collision::{self, BurstTiming, Fate, Sound};
use crate::profile::CollisionModel;

/// What [`audit_schedule`] found.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct AuditReport {
    /// Grid points looked at.
    pub points: usize,
    /// (point, emission) pairs where the emission is audible.
    pub audible: u64,
    /// Of those, collided with another burst on their channel.
    pub collided: u64,
    /// Of those, masked by an earlier burst's tail.
    pub masked: u64,
    /// One spoiled pair, for the message: `(tx spoiled, tx spoiling, x_m, y_m)`.
    pub example: Option<(u32, u32, f64, f64)>,
}

impl AuditReport {
    /// Share of audible bursts spoiled (0 when none is audible).
    pub fn spoiled_share(&self) -> f64 {
        if self.audible == 0 {
            0.0
        } else {
            (self.collided + self.masked) as f64 / self.audible as f64
        }
    }
}

/// Audits `schedule` on `site` with the room of `model`; a burst is audible
/// within `max_range_m` in line of sight; grid points every `grid_m`.
pub fn audit_schedule(
    site: &Site,
    schedule: &Schedule,
    model: &CollisionModel,
    max_range_m: f64,
    grid_m: f64,
) -> AuditReport {
    let timing = BurstTiming::of(site);
    let period_s = schedule.cycle_period.as_secs_f64();
    let h = site.msu.height_m;
    let mut report = AuditReport::default();
    for p in grid(site, grid_m) {
        report.points += 1;
        let at = [p[0], p[1], h];
        let mut sounds: Vec<Sound> = Vec::new();
        // Index in `sounds` of each emission of the middle cycle.
        let mut middle: Vec<usize> = Vec::new();
        for cycle in [-1.0, 0.0, 1.0] {
            for e in &schedule.emissions {
                let Some(tx) = site.transmitter(e.tx_id) else {
                    continue;
                };
                let d = distance(tx.position_m, at);
                if d > max_range_m || !site.line_of_sight(tx.position_m, at) {
                    continue;
                }
                sounds.push(Sound {
                    tx_id: tx.id,
                    channel: tx.channel,
                    onset_s: cycle * period_s
                        + e.offset.as_secs_f64()
                        + d / site.speed_of_sound_m_s,
                    level_db: collision::level_db(model, d),
                });
                if cycle == 0.0 {
                    middle.push(sounds.len() - 1);
                }
            }
        }
        for &i in &middle {
            report.audible += 1;
            let s = sounds[i];
            let spoiler = match collision::fate(
                model,
                &timing,
                s.channel,
                s.onset_s,
                s.level_db,
                Some(i),
                &sounds,
            ) {
                Fate::Clear => None,
                Fate::Collided { with } => {
                    report.collided += 1;
                    Some(with)
                }
                Fate::Masked { by } => {
                    report.masked += 1;
                    Some(by)
                }
            };
            if let (Some(j), None) = (spoiler, report.example) {
                report.example = Some((s.tx_id, sounds[j].tx_id, p[0], p[1]));
            }
        }
    }
    report
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Points every `grid_m` inside some cell.
fn grid(site: &Site, grid_m: f64) -> Vec<[f64; 2]> {
    let (lo, hi) = site.bounds();
    let step = grid_m.max(0.05);
    let nx = ((hi[0] - lo[0]) / step).floor() as usize;
    let ny = ((hi[1] - lo[1]) / step).floor() as usize;
    let mut out = Vec::new();
    for i in 0..=nx {
        for j in 0..=ny {
            let p = [
                lo[0] + (i as f64 + 0.5) * step,
                lo[1] + (j as f64 + 0.5) * step,
            ];
            if site.cell_at(p).is_some() {
                out.push(p);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::NoiseProfile;
    use ickon_central::schedule::{compute_schedule, compute_uniform_schedule};

    fn audit(name: &str, profile: &NoiseProfile) -> AuditReport {
        let (site, _) = Site::builtin(name).unwrap();
        let all: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        let s = compute_schedule(&site, &all, 1, 0).unwrap();
        let u = &profile.ultrasound;
        audit_schedule(&site, &s, &u.collisions, u.max_range_m, 0.5)
    }

    #[test]
    fn the_uniform_schedule_lets_bursts_collide_where_two_cells_of_a_colour_are_heard() {
        // Measured: lab 15 of 2585 audible bursts (0.6 %), warehouse 268 of
        // 14970 (1.8 %): its colouring asks only whether one cell hears the
        // other, not whether a third place hears both.
        for name in ["lab", "warehouse"] {
            let (site, _) = Site::builtin(name).unwrap();
            let all: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
            let s = compute_uniform_schedule(&site, &all, 1, 0).unwrap();
            let u = NoiseProfile::paper().ultrasound;
            let r = audit_schedule(&site, &s, &u.collisions, u.max_range_m, 0.5);
            assert!(r.collided > 0 && r.spoiled_share() < 0.03, "{name}: {r:?}");
        }
    }

    #[test]
    fn the_lab_schedule_has_no_collision_anywhere() {
        let r = audit("lab", &NoiseProfile::paper());
        assert!(r.points > 300 && r.audible > 1000, "{r:?}");
        assert_eq!((r.collided, r.masked), (0, 0), "{r:?}");
    }

    #[test]
    fn the_warehouse_schedule_has_no_collision_anywhere() {
        let r = audit("warehouse", &NoiseProfile::paper());
        assert!(r.points > 1500 && r.audible > 10_000, "{r:?}");
        assert_eq!((r.collided, r.masked), (0, 0), "{r:?}");
    }

    #[test]
    fn bursts_squeezed_together_are_reported_spoiled() {
        let (site, _) = Site::builtin("lab").unwrap();
        let all: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        let mut s = compute_schedule(&site, &all, 1, 0).unwrap();
        // Every emission 1 ms after the previous one: collisions everywhere.
        for (k, e) in s.emissions.iter_mut().enumerate() {
            e.offset = ickon_proto::time::Duration::from_millis(k as i64);
        }
        let m = NoiseProfile::paper().ultrasound;
        let r = audit_schedule(&site, &s, &m.collisions, m.max_range_m, 0.5);
        assert!(r.spoiled_share() > 0.5, "{r:?}");
        assert!(r.example.is_some());
    }
}
