//! The quantities of the calibration that change: unlike a transmitter's
//! position, a cell's sync error is its network path's asymmetry, which
//! changes when the path does (a link re-routed, a switch replaced), and
//! the speed of sound changes with the air (the day's swing, a door
//! opened). Each is a first-order Gauss-Markov process whose stationary
//! sigma is its prior and whose correlation time is its memory
//! ([`CalibrationConfig::cell_sync_memory_s`],
//! [`CalibrationConfig::sound_memory_s`]): over `dt` it keeps the fraction
//! `a = exp(-dt / memory)` of itself and gains fresh noise of variance
//! `q = sigma^2 (1 - a^2)`. Without it, a lateness learnt over weeks (and
//! kept across restarts by `--survey-file`) would hold a re-routed cell at
//! its old lateness for good, and the morning's air would be used in the
//! afternoon.
//!
//! The step is exact in information form and needs no inverse of the
//! whole matrix: with `S` the drifting parameters, `R` the rest, `A` and
//! `Q` the diagonal matrices of their `a` and `q`, and
//! `D = I_SS + A Q^-1 A`, marginalising the old values out of the joint of
//! old and new gives `I_RR - I_RS D^-1 I_SR`, `I_RS D^-1 A Q^-1`,
//! `Q^-1 - Q^-1 A D^-1 A Q^-1` and the information vector
//! `(w_R - I_RS D^-1 w_S, Q^-1 A D^-1 w_S)`.

use nalgebra::{DMatrix, DVector};

use super::SurveyCalibration;

impl SurveyCalibration {
    /// The parameters of the cells' lateness: their first index and count.
    pub(super) fn cell_parameters(&self) -> (usize, usize) {
        let first = 3 * self.ids.len();
        // The last parameter is the speed of sound's.
        (first, self.weighted.len() - first - 1)
    }

    /// Lets every cell's lateness and the speed of sound drift for `dt_s`
    /// seconds (see the module docs). A quantity with no memory limit (0)
    /// or held by a zero prior does not drift; nothing changes for a step
    /// that is not positive.
    pub fn forget_cell_sync(&mut self, dt_s: f64) {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return;
        }
        let (first, m) = self.cell_parameters();
        let c = self.config;
        let drifting: Vec<(usize, f64, f64)> = (first..first + m)
            .map(|i| (i, c.cell_sync_sigma_m, c.cell_sync_memory_s))
            .chain(std::iter::once((
                first + m,
                c.sound_prior_sigma(),
                c.sound_memory(),
            )))
            .filter_map(|(i, sigma, memory_s)| {
                if !(memory_s > 0.0 && sigma > 0.0) {
                    return None;
                }
                let keep = (-dt_s / memory_s).exp();
                let fresh = sigma * sigma * (1.0 - keep * keep);
                (fresh > 0.0 && fresh.is_finite()).then_some((i, keep, 1.0 / fresh))
            })
            .collect();
        self.drift(&drifting);
    }

    /// One Gauss-Markov step of the parameters `(index, a, 1 / q)`.
    fn drift(&mut self, drifting: &[(usize, f64, f64)]) {
        let m = drifting.len();
        if m == 0 {
            return;
        }
        let n = self.weighted.len();
        let s: Vec<usize> = drifting.iter().map(|d| d.0).collect();
        // A Q^-1, diagonal.
        let aq = DVector::from_iterator(m, drifting.iter().map(|&(_, a, qi)| a * qi));
        let mut d = DMatrix::from_fn(m, m, |i, k| self.information[(s[i], s[k])]);
        for (i, &(_, a, qi)) in drifting.iter().enumerate() {
            d[(i, i)] += a * a * qi;
        }
        let Some(d_inverse) = d.cholesky().map(|c| c.inverse()) else {
            return;
        };
        let columns = DMatrix::from_fn(n, m, |r, k| self.information[(r, s[k])]);
        let w_s = DVector::from_iterator(m, s.iter().map(|&i| self.weighted[i]));
        let through = &columns * &d_inverse;
        let w_through = &d_inverse * &w_s;
        // The rest: I_RR - I_RS D^-1 I_SR (computed for every entry; the
        // drifting rows and columns are replaced below).
        let mut information = &self.information - &through * columns.transpose();
        let mut weighted = &self.weighted - &columns * &w_through;
        let linked = DMatrix::from_fn(n, m, |r, k| through[(r, k)] * aq[k]);
        for (k, &i) in s.iter().enumerate() {
            for r in 0..n {
                information[(r, i)] = linked[(r, k)];
                information[(i, r)] = linked[(r, k)];
            }
        }
        for (a, &i) in s.iter().enumerate() {
            for (b, &k) in s.iter().enumerate() {
                let own = if a == b { drifting[a].2 } else { 0.0 };
                information[(i, k)] = own - aq[a] * d_inverse[(a, b)] * aq[b];
            }
            weighted[i] = aq[a] * w_through[a];
        }
        let information = (&information + information.transpose()) * 0.5;
        // Exact algebra keeps it positive definite; only numbers gone wrong
        // would not, and then nothing is forgotten rather than everything.
        if information
            .iter()
            .chain(weighted.iter())
            .all(|v| v.is_finite())
            && information.clone().cholesky().is_some()
        {
            self.information = information;
            self.weighted = weighted;
        }
    }
}
