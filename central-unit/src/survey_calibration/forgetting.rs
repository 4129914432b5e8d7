//! The cells' lateness as a quantity that changes: unlike a transmitter's
//! position, a cell's sync error is its network path's asymmetry, which
//! changes when the path does (a link re-routed, a switch replaced). Each
//! cell's lateness is a first-order Gauss-Markov process whose stationary
//! sigma is the sync's prior and whose correlation time is
//! [`CalibrationConfig::cell_sync_memory_s`]: over `dt` it keeps the
//! fraction `a = exp(-dt / memory)` of itself and gains fresh noise of
//! variance `sigma^2 (1 - a^2)`. Without it, a lateness learnt over weeks
//! (and kept across restarts by `--survey-file`) would hold a re-routed
//! cell at its old lateness for good.
//!
//! The step is exact in information form and needs no inverse of the
//! whole matrix: with `S` the cells' parameters, `R` the rest and
//! `D = I_SS + a^2 / q`, marginalising the old lateness out of the joint
//! of old and new gives `I_RR - I_RS D^-1 I_SR`, `a / q I_RS D^-1`,
//! `1 / q - a^2 / q^2 D^-1` and the information vector
//! `(w_R - I_RS D^-1 w_S, a / q D^-1 w_S)`.

use nalgebra::DMatrix;

use super::SurveyCalibration;

impl SurveyCalibration {
    /// The parameters of the cells' lateness: their first index and count.
    pub(super) fn cell_parameters(&self) -> (usize, usize) {
        let first = 3 * self.ids.len();
        // The last parameter is the speed of sound's.
        (first, self.weighted.len() - first - 1)
    }

    /// Lets every cell's lateness drift for `dt_s` seconds (see the module
    /// docs). Nothing changes for a step that is not positive, with no
    /// memory limit (0) or with every cell held on time (a zero prior).
    pub fn forget_cell_sync(&mut self, dt_s: f64) {
        let memory_s = self.config.cell_sync_memory_s;
        let sigma_m = self.config.cell_sync_sigma_m;
        if !(dt_s > 0.0 && memory_s > 0.0 && sigma_m > 0.0) {
            return;
        }
        let (first, m) = self.cell_parameters();
        let keep = (-dt_s / memory_s).exp();
        let fresh = sigma_m.powi(2) * (1.0 - keep * keep);
        if m == 0 || !(fresh > 0.0 && fresh.is_finite()) {
            return;
        }
        let fresh_info = 1.0 / fresh;
        let d = self.information.view((first, first), (m, m)).into_owned()
            + DMatrix::identity(m, m) * (keep * keep * fresh_info);
        let Some(d_inverse) = d.cholesky().map(|c| c.inverse()) else {
            return;
        };
        let columns = self.information.columns(first, m).into_owned();
        let through = &columns * &d_inverse;
        let w_through = &d_inverse * self.weighted.rows(first, m);
        // The rest: I_RR - I_RS D^-1 I_SR (computed for every entry; the
        // cells' rows and columns are replaced below).
        let mut information = &self.information - &through * columns.transpose();
        let mut weighted = &self.weighted - &columns * &w_through;
        let linked = &through * (keep * fresh_info);
        information.columns_mut(first, m).copy_from(&linked);
        information
            .rows_mut(first, m)
            .copy_from(&linked.transpose());
        let own = DMatrix::identity(m, m) * fresh_info - &d_inverse * (keep * fresh_info).powi(2);
        information.view_mut((first, first), (m, m)).copy_from(&own);
        weighted
            .rows_mut(first, m)
            .copy_from(&(&w_through * (keep * fresh_info)));
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
