//! Distances to beacons into the estimators: each one checked against the
//! site, fused on its own (tightly coupled), and, when three or more agree,
//! their trilateration as a fix for the estimators that take positions.

use ickon_fusion::estimator::{BeaconRangeSample, Input};
use ickon_fusion::ranging;
use ickon_fusion::tdoa;

use super::MsuCore;
use crate::beacons::{BeaconDistance, BeaconDistances, KitPosition, MAX_DISTANCES};
use crate::error::MsuError;

/// A distance may exceed the farthest the receiver can be from its beacon
/// on the floor by this much before it counts as absurd, metres: three of
/// a ranging kit's sigmas (centimetres) are far less; a reflection that
/// long is refused anyway by the filter's gate.
const BEYOND_THE_SITE_M: f64 = 1.0;

impl MsuCore {
    /// Fuses one reading of distances. Every distance the site explains
    /// goes to the estimators; the others are refused (an unknown beacon,
    /// a distance that is not a number, not positive, shorter than the
    /// beacon's height above the receiver or longer than the site allows)
    /// and named in the error, after the good ones were used.
    pub(crate) fn on_beacon_distances(&mut self, msg: &BeaconDistances) -> Result<(), MsuError> {
        if msg.distances.len() > MAX_DISTANCES {
            return Err(MsuError::BeaconDistances {
                refused: msg.distances.len(),
                of: msg.distances.len(),
                reason: format!("more than {MAX_DISTANCES} distances in one reading"),
            });
        }
        self.gate(msg.stamp)?;
        let t_s = self.clock.to_fusion(msg.stamp);
        let mut used = Vec::new();
        let mut first_refusal = None;
        let mut refused = 0;
        for d in &msg.distances {
            match self.beacon_range(t_s, d) {
                Ok(sample) => {
                    // A range the filter gates out (a reflection) leaves it
                    // as it was; the host counts it.
                    let _ = self.host.feed(&Input::BeaconRange(sample));
                    used.push(sample);
                }
                Err(reason) => {
                    refused += 1;
                    first_refusal.get_or_insert(format!("beacon {}: {reason}", d.tx_id));
                }
            }
        }
        if !used.is_empty() {
            // Ranges keep the pose as fresh as fixes do.
            self.last_fix = Some(self.last_fix.map_or(msg.stamp, |t| t.max(msg.stamp)));
        }
        self.fix_from_ranges(t_s, &used);
        match first_refusal {
            None => Ok(()),
            Some(reason) => Err(MsuError::BeaconDistances {
                refused,
                of: msg.distances.len(),
                reason,
            }),
        }
    }

    /// The range sample for `d`, or why the site cannot explain it.
    fn beacon_range(&self, t_s: f64, d: &BeaconDistance) -> Result<BeaconRangeSample, String> {
        let config = self.solver.config();
        let Some(tx) = config.transmitters.iter().find(|t| t.tx_id == d.tx_id) else {
            return Err("not a transmitter of this site".into());
        };
        if !(d.distance_m.is_finite() && d.distance_m > 0.0) {
            return Err(format!(
                "distance {} m is not a positive number",
                d.distance_m
            ));
        }
        if !(d.sigma_m.is_finite() && d.sigma_m > 0.0) {
            return Err(format!("sigma {} m is not a positive number", d.sigma_m));
        }
        let slack_m = 3.0 * d.sigma_m;
        let height_gap_m = (tx.z_m - config.height_m).abs();
        if d.distance_m + slack_m < height_gap_m {
            return Err(format!(
                "{:.3} m is shorter than the beacon's {height_gap_m:.3} m above the receiver",
                d.distance_m
            ));
        }
        if let Some([lo, hi]) = config.floor_bounds_m {
            let farthest_xy_m = [lo[0], hi[0]]
                .iter()
                .flat_map(|x| [lo[1], hi[1]].map(|y| (x - tx.x_m).hypot(y - tx.y_m)))
                .fold(0.0, f64::max);
            let farthest_m = farthest_xy_m.hypot(height_gap_m) + BEYOND_THE_SITE_M;
            if d.distance_m > farthest_m + slack_m {
                return Err(format!(
                    "{:.3} m is farther than the site allows ({farthest_m:.1} m)",
                    d.distance_m
                ));
            }
        }
        Ok(BeaconRangeSample {
            t_s,
            beacon_m: [tx.x_m, tx.y_m, tx.z_m],
            range_m: d.distance_m,
            sigma_m: d.sigma_m,
        })
    }

    /// Fuses a ranging kit's own position as a fix with its stated noise;
    /// refused when it is not a number or off the site's floor.
    pub(crate) fn on_kit_position(&mut self, p: &KitPosition) -> Result<(), MsuError> {
        let refuse = |reason: String| MsuError::KitPosition { reason };
        if !(p.x_m.is_finite() && p.y_m.is_finite()) {
            return Err(refuse(format!(
                "({}, {}) m is not a position",
                p.x_m, p.y_m
            )));
        }
        if !(p.sigma_m.is_finite() && p.sigma_m > 0.0) {
            return Err(refuse(format!(
                "sigma {} m is not a positive number",
                p.sigma_m
            )));
        }
        if let Some([lo, hi]) = self.solver.config().floor_bounds_m {
            let slack_m = 3.0 * p.sigma_m;
            let off = |v: f64, k: usize| v < lo[k] - slack_m || v > hi[k] + slack_m;
            if off(p.x_m, 0) || off(p.y_m, 1) {
                return Err(refuse(format!(
                    "({:.2}, {:.2}) m is off the site's floor",
                    p.x_m, p.y_m
                )));
            }
        }
        self.gate(p.stamp)?;
        let t_s = self.clock.to_fusion(p.stamp);
        let covariance = nalgebra::Matrix2::identity() * p.sigma_m.powi(2);
        self.host.feed(&Input::Fix(tdoa::Fix::from_position(
            t_s, p.x_m, p.y_m, covariance,
        )))?;
        self.last_fix = Some(self.last_fix.map_or(p.stamp, |t| t.max(p.stamp)));
        if !self.localised && self.agrees_with([p.x_m, p.y_m], p.sigma_m * 2f64.sqrt(), t_s) {
            self.localised = true;
            tracing::info!(
                "pose confirmed by the kit's position at ({:.2}, {:.2}) m",
                p.x_m,
                p.y_m
            );
        }
        Ok(())
    }

    /// Trilaterates `ranges` (three or more beacons) into a fix for the
    /// estimators that take positions, and confirms the pose by it; a
    /// solution whose residuals the ranges' sigmas do not explain (a
    /// reflection among them) is not used.
    fn fix_from_ranges(&mut self, t_s: f64, ranges: &[BeaconRangeSample]) {
        let height_m = self.solver.config().height_m;
        let Some(fix) = ranging::trilaterate(ranges, height_m) else {
            return;
        };
        let worst_sigma_m = ranges.iter().map(|r| r.sigma_m).fold(0.0, f64::max);
        if fix.rms_residual_m > 3.0 * worst_sigma_m {
            return;
        }
        let fix_sigma_m = fix.covariance_xy_m2.trace().max(0.0).sqrt();
        let solved = tdoa::Fix::from_position(t_s, fix.x_m, fix.y_m, fix.covariance_xy_m2);
        if let Err(e) = self.host.feed(&Input::Fix(solved)) {
            tracing::debug!("fix from ranges not fused: {e}");
        }
        if !self.localised && self.agrees_with([fix.x_m, fix.y_m], fix_sigma_m, t_s) {
            self.localised = true;
            tracing::info!(
                "pose confirmed by ranges at ({:.2}, {:.2}) m",
                fix.x_m,
                fix.y_m
            );
        }
    }
}
