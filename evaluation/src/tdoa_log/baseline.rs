//! The per-epoch least-squares baseline `ls` of `ickon replay tdoa`,
//! computed from a run held in memory (a recording's robot, see
//! `ickon replay mcap`) instead of from the files [`super::export`] writes
//! of it: the same arrivals (those the export keeps), the same solver
//! set up as for the written anchors, scored by the same code. A
//! recording and its conversion (`ickon convert mcap --to tdoa`) then
//! differ only by what reading and writing the files does to the numbers
//! (rounding to the nanosecond and the micrometre).

use std::collections::HashMap;

use ickon_proto::site::Site;
use ickon_sim::recording::Recording;

use super::epoch::Units;
use super::export::{epochs, mobile_height_m};
use super::format::{Anchor, Anchors, Arrival, Kind, Role};
use super::replay::{solver_for, volume_of};
use crate::util::dataset::TruthRow;
use crate::util::score::{Summary, Track, Truth};

/// What the baseline made of a run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Baseline {
    /// Epochs (cycles with an arrival kept).
    pub epochs: u64,
    /// Epochs the solver fixed.
    pub fixes: u64,
    /// Fixes scored against the truth, as `ickon replay tdoa` scores them.
    pub scored: u64,
    /// Their RMS error, metres.
    pub rmse_m: Option<f64>,
    /// Their mean error, metres.
    pub mean_m: Option<f64>,
    /// Their median error, metres.
    pub median_m: Option<f64>,
}

/// The baseline of `rec` (the anchors of `site`, the arrivals' timing
/// sigma `sigma_s`), scored against its truth; `None` when the site's
/// transmitters enclose no volume.
pub fn least_squares(site: &Site, sigma_s: f64, rec: &Recording) -> Option<Baseline> {
    let anchors = anchors_of(site);
    let volume = volume_of(&anchors).ok()?;
    let mut solver = solver_for(&anchors, volume);
    let units = Units {
        speed_m_s: Some(site.speed_of_sound_m_s),
        default_sigma_m: sigma_s * site.speed_of_sound_m_s,
    };
    let mut track = Track::new(false);
    let mut n_epochs = 0;
    for (cycle, arrivals) in epochs(rec) {
        let rows: Vec<Arrival> = arrivals
            .iter()
            .filter_map(|a| {
                Some(Arrival {
                    line: 0,
                    epoch: cycle,
                    t_s: a.t_s,
                    anchor: *anchors.by_id.get(&a.tx_id.to_string())?,
                    reference: None,
                    kind: Kind::ToaS,
                    value: a.t_s - a.offset_s,
                    sigma: Some(sigma_s),
                })
            })
            .collect();
        if rows.is_empty() {
            continue;
        }
        n_epochs += 1;
        if let Some((t, p, cov)) = solver.solve(&rows, &anchors, &units) {
            track.push_with(t, p, Some(cov));
        }
    }
    let mut truth = Truth::new([0.0; 3]);
    for s in &rec.truth {
        let row = TruthRow {
            t_s: s.t_s,
            position_m: [s.x_m, s.y_m, 0.0],
            attitude_xyzw: None,
        };
        truth.push(row, &mut [&mut track]);
    }
    truth.finish(&mut [&mut track]);
    let Summary {
        scored,
        rmse_3d_m,
        mean_3d_m,
        median_3d_m,
        ..
    } = track.summary();
    Some(Baseline {
        epochs: n_epochs,
        fixes: solver.solved,
        scored,
        rmse_m: rmse_3d_m,
        mean_m: mean_3d_m,
        median_m: median_3d_m,
    })
}

/// The site's transmitters as `ickon replay tdoa` reads the anchors file
/// the export writes: 2D, in the plane of the mobile's height.
fn anchors_of(site: &Site) -> Anchors {
    let list: Vec<Anchor> = site
        .transmitters
        .iter()
        .map(|t| Anchor {
            id: t.id.to_string(),
            position_m: t.position_m,
        })
        .collect();
    Anchors {
        by_id: list
            .iter()
            .enumerate()
            .map(|(k, a)| (a.id.clone(), k))
            .collect::<HashMap<_, _>>(),
        list,
        dim: 2,
        role: Role::Transmitter,
        plane_z_m: mobile_height_m(site),
    }
}
