//! Per-anchor excess paths: a signal that reaches the receiver by a
//! reflection, or through something in the way, travels further than the
//! straight line, and it keeps doing so while the receiver, the anchor and
//! the obstacle stay roughly where they are: the error of a range
//! difference comes in runs, not as white noise. Each anchor heard gets a
//! state `e >= 0` (its excess path, metres), a first-order Gauss-Markov
//! process (standard deviation `sigma_m`, correlation time
//! `correlation_s`), so that a run of late arrivals from one anchor widens
//! what the filter believes about that anchor instead of pulling its
//! position while it stays sure of itself.
//!
//! A range difference `B - A` sees `e_B - e_A`. The states are one-sided
//! (a path can only be lengthened): clamped at zero after each update.
//! A fixed number of slots ([`EXCESS_SLOTS`]) holds the anchors heard
//! most recently; a new anchor takes the slot heard longest ago, which
//! restarts at its prior.

use nalgebra::{SMatrix, SVector};

use crate::estimator::{InvalidParameter, RangeDifferenceSample};

/// How many anchors have an excess-path state at once: a TDoA2 cycle of
/// the UWB systems and an ICKON cell both have 8 transmitters.
pub const EXCESS_SLOTS: usize = 8;

/// The excess-path model.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExcessParams {
    /// Steady-state standard deviation of an anchor's excess path, metres
    /// (0: no excess-path states).
    pub sigma_m: f64,
    /// Correlation time of an anchor's excess path, seconds.
    pub correlation_s: f64,
}

impl Default for ExcessParams {
    /// Off: the size of an excess path belongs to the arena, not to the
    /// filter (the UTIL replay sets it from its arena).
    fn default() -> Self {
        Self {
            sigma_m: 0.0,
            correlation_s: 1.0,
        }
    }
}

impl ExcessParams {
    /// Checks both fields are in their domain.
    pub fn validate(&self, estimator: &'static str) -> Result<(), InvalidParameter> {
        if !(self.sigma_m.is_finite() && self.sigma_m >= 0.0) {
            return Err(InvalidParameter {
                estimator,
                field: "excess.sigma_m",
                reason: "must be finite and non-negative",
            });
        }
        if !(self.correlation_s.is_finite() && self.correlation_s > 0.0) {
            return Err(InvalidParameter {
                estimator,
                field: "excess.correlation_s",
                reason: "must be finite and positive",
            });
        }
        Ok(())
    }

    fn enabled(&self) -> bool {
        self.sigma_m > 0.0
    }
}

/// The slots of a filter whose state holds [`EXCESS_SLOTS`] excess paths
/// from index `first`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ExcessSlots {
    params: ExcessParams,
    first: usize,
    anchors: [Option<[f64; 3]>; EXCESS_SLOTS],
    heard_s: [f64; EXCESS_SLOTS],
}

impl ExcessSlots {
    /// Empty slots at state indices `first..first + EXCESS_SLOTS`.
    pub(crate) fn new(params: ExcessParams, first: usize) -> Self {
        Self {
            params,
            first,
            anchors: [None; EXCESS_SLOTS],
            heard_s: [f64::NEG_INFINITY; EXCESS_SLOTS],
        }
    }

    /// The prior variance of a slot. Without the model the states are
    /// never observed (no column in `H`); any positive variance keeps the
    /// covariance invertible.
    fn prior_variance(&self) -> f64 {
        if self.params.enabled() {
            self.params.sigma_m.powi(2)
        } else {
            1.0
        }
    }

    /// Sets the slots' prior in a fresh covariance.
    pub(crate) fn init<const T: usize>(&self, p: &mut SMatrix<f64, T, T>) {
        for k in 0..EXCESS_SLOTS {
            let i = self.first + k;
            p[(i, i)] = self.prior_variance();
        }
    }

    /// The Gauss-Markov decay over `dt` seconds: `e <- phi e`, variance
    /// `phi^2 var + sigma^2 (1 - phi^2)`, cross terms scaled by `phi`.
    /// Call after the rest of the state was predicted (the transition is
    /// block-diagonal).
    pub(crate) fn decay<const T: usize>(
        &self,
        x: &mut SVector<f64, T>,
        p: &mut SMatrix<f64, T, T>,
        dt: f64,
    ) {
        if !self.params.enabled() || dt.is_nan() || dt <= 0.0 {
            return;
        }
        let phi = (-dt / self.params.correlation_s).exp();
        let q = self.params.sigma_m.powi(2) * (1.0 - phi * phi);
        for k in 0..EXCESS_SLOTS {
            let i = self.first + k;
            x[i] *= phi;
            for j in 0..T {
                p[(i, j)] *= phi;
                p[(j, i)] *= phi;
            }
            p[(i, i)] += q;
        }
    }

    /// The slot of the anchor at `anchor_m`, if it has one.
    fn find(&self, anchor_m: &[f64; 3]) -> Option<usize> {
        self.anchors
            .iter()
            .position(|a| a.as_ref() == Some(anchor_m))
    }

    /// `dh/de` of the measurement `m` (`+1` on B's slot, `-1` on A's) and
    /// the excess it predicts, with the slots it has now; anchors without a
    /// slot see none.
    pub(crate) fn observe<const T: usize>(
        &self,
        x: &SVector<f64, T>,
        m: &RangeDifferenceSample,
    ) -> (SMatrix<f64, 1, T>, f64) {
        let mut h = SMatrix::<f64, 1, T>::zeros();
        let mut predicted = 0.0;
        if !self.params.enabled() {
            return (h, predicted);
        }
        for (anchor, sign) in [(&m.b_m, 1.0), (&m.a_m, -1.0)] {
            if let Some(k) = self.find(anchor) {
                let i = self.first + k;
                h[(0, i)] += sign;
                predicted += sign * x[i];
            }
        }
        (h, predicted)
    }

    /// Gives both anchors of `m` a slot (a new anchor takes the slot heard
    /// longest ago, restarted at its prior) and notes them heard at
    /// `m.t_s`.
    pub(crate) fn assign<const T: usize>(
        &mut self,
        x: &mut SVector<f64, T>,
        p: &mut SMatrix<f64, T, T>,
        m: &RangeDifferenceSample,
    ) {
        if !self.params.enabled() {
            return;
        }
        for anchor in [m.a_m, m.b_m] {
            let k = match self.find(&anchor) {
                Some(k) => k,
                None => {
                    let other = if anchor == m.a_m { m.b_m } else { m.a_m };
                    let k = self.oldest_except(&other);
                    self.anchors[k] = Some(anchor);
                    let i = self.first + k;
                    x[i] = 0.0;
                    for j in 0..T {
                        p[(i, j)] = 0.0;
                        p[(j, i)] = 0.0;
                    }
                    p[(i, i)] = self.prior_variance();
                    k
                }
            };
            self.heard_s[k] = m.t_s;
        }
    }

    /// The slot heard longest ago (empty slots first), not the one of
    /// `keep`.
    fn oldest_except(&self, keep: &[f64; 3]) -> usize {
        let kept = self.find(keep);
        (0..EXCESS_SLOTS)
            .filter(|&k| Some(k) != kept)
            .min_by(|&a, &b| self.heard_s[a].total_cmp(&self.heard_s[b]))
            .unwrap_or(0)
    }

    /// Clamps the excess paths at zero: a path is never shortened.
    pub(crate) fn clamp<const T: usize>(&self, x: &mut SVector<f64, T>) {
        for k in 0..EXCESS_SLOTS {
            let i = self.first + k;
            x[i] = x[i].max(0.0);
        }
    }

    /// Keeps the excess paths (they belong to the arena, not to the lost
    /// track) but forgets their correlation with the restarted rest.
    pub(crate) fn decouple<const T: usize>(&self, p: &mut SMatrix<f64, T, T>) {
        let range = self.first..self.first + EXCESS_SLOTS;
        for i in range.clone() {
            for j in 0..T {
                if !range.contains(&j) {
                    p[(i, j)] = 0.0;
                    p[(j, i)] = 0.0;
                }
            }
        }
    }

    /// The excess-path estimates of the anchors with a slot: `(anchor,
    /// metres, standard deviation)`.
    pub(crate) fn estimates<const T: usize>(
        &self,
        x: &SVector<f64, T>,
        p: &SMatrix<f64, T, T>,
    ) -> Vec<([f64; 3], f64, f64)> {
        (0..EXCESS_SLOTS)
            .filter_map(|k| {
                let i = self.first + k;
                self.anchors[k].map(|a| (a, x[i], p[(i, i)].sqrt()))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type V = SVector<f64, 10>;
    type M = SMatrix<f64, 10, 10>;

    fn params() -> ExcessParams {
        ExcessParams {
            sigma_m: 0.1,
            correlation_s: 1.0,
        }
    }

    fn pair(a: f64, b: f64) -> RangeDifferenceSample {
        RangeDifferenceSample {
            t_s: a + b,
            a_t_s: None,
            a_m: [a, 0.0, 0.0],
            b_m: [b, 0.0, 0.0],
            d_m: 0.0,
            sigma_m: 0.1,
            clocks: None,
            speed_rel_sigma: None,
        }
    }

    #[test]
    fn decay_keeps_the_steady_state_variance_and_shrinks_the_mean() {
        let s = ExcessSlots::new(params(), 2);
        let (mut x, mut p) = (V::zeros(), M::identity());
        s.init(&mut p);
        x[2] = 0.2;
        s.decay(&mut x, &mut p, 1.0);
        assert!((x[2] - 0.2 * (-1.0f64).exp()).abs() < 1e-12);
        assert!((p[(2, 2)] - 0.01).abs() < 1e-12);
    }

    #[test]
    fn a_range_difference_sees_b_minus_a() {
        let mut s = ExcessSlots::new(params(), 2);
        let (mut x, mut p) = (V::zeros(), M::identity());
        s.init(&mut p);
        let m = pair(1.0, 2.0);
        s.assign(&mut x, &mut p, &m);
        x[2] = 0.3; // A took the first slot.
        x[3] = 0.1;
        let (h, e) = s.observe(&x, &m);
        assert_eq!((h[(0, 2)], h[(0, 3)]), (-1.0, 1.0));
        assert!((e - (0.1 - 0.3)).abs() < 1e-12);
    }

    #[test]
    fn a_ninth_anchor_takes_the_slot_heard_longest_ago_at_its_prior() {
        let mut s = ExcessSlots::new(params(), 2);
        let (mut x, mut p) = (V::zeros(), M::identity());
        s.init(&mut p);
        for k in 0..4 {
            s.assign(&mut x, &mut p, &pair(2.0 * k as f64, 2.0 * k as f64 + 1.0));
        }
        x[2] = 0.5;
        p[(2, 0)] = 0.3;
        p[(0, 2)] = 0.3;
        // Anchor 0 was heard first: the new one (9) takes its slot.
        s.assign(&mut x, &mut p, &pair(9.0, 7.0));
        assert_eq!(s.find(&[9.0, 0.0, 0.0]), Some(0));
        assert_eq!((x[2], p[(2, 0)]), (0.0, 0.0));
        assert!((p[(2, 2)] - 0.01).abs() < 1e-12);
        assert!(s.find(&[0.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn without_the_model_nothing_is_observed() {
        let mut s = ExcessSlots::new(ExcessParams::default(), 2);
        let (mut x, mut p) = (V::zeros(), M::zeros());
        s.init(&mut p);
        let m = pair(1.0, 2.0);
        s.assign(&mut x, &mut p, &m);
        let (h, e) = s.observe(&x, &m);
        assert_eq!((h, e), (SMatrix::zeros(), 0.0));
        assert_eq!(p[(2, 2)], 1.0);
    }

    #[test]
    fn bad_parameters_are_named() {
        let bad = ExcessParams {
            sigma_m: -0.1,
            ..params()
        };
        assert!(bad.validate("x").is_err());
        let bad = ExcessParams {
            correlation_s: 0.0,
            ..params()
        };
        assert!(bad.validate("x").is_err());
        assert!(params().validate("x").is_ok());
    }
}
