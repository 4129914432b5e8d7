//! One fix read against the calibration: what its residuals say of the
//! transmitters' positions, the cells' lateness and the speed of sound
//! (see the parent module for the model), apart from adding it, so that
//! the fleet's check ([`super::consensus`]) can weigh a robot's fixes
//! before any of them is learnt from.

use nalgebra::{DMatrix, DVector, Matrix3};

use ickon_proto::msg::robot::Fix;

use super::{
    Applied, AppliedLate, FixSkipped, HUBER_SIGMAS, MIN_RANGE_SIGMA_M, SurveyCalibration,
    checked_receiver,
};

/// What one fix says of the calibration's parameters: its residuals with
/// the corrections it was solved with put back (the whole error), and how
/// they depend on the parameters it touches, its own unknowns projected out.
#[derive(Debug, Clone)]
pub struct ReadFix {
    /// The parameters it touches, ascending.
    columns: Vec<usize>,
    /// Its weight: the inverse of its residuals' variance, down-weighted
    /// when one of them is an outlier.
    weight: f64,
    /// `P J`: the residuals per unit of each parameter it touches, metres.
    pj: DMatrix<f64>,
    /// The whole error's residuals, metres.
    residuals: DVector<f64>,
}

impl ReadFix {
    /// How far the fix is from what the calibration `estimate` (of every
    /// parameter, [`SurveyCalibration::estimate`]) predicts: the root mean
    /// square of what is left of its residuals per degree of freedom (its
    /// own position and offset take three), metres. A fix of an honest
    /// robot leaves its timing noise; one that places transmitters
    /// elsewhere than the fleet's calibration leaves that displacement.
    pub fn misfit_m(&self, estimate: &DVector<f64>) -> f64 {
        let x = DVector::from_iterator(
            self.columns.len(),
            self.columns
                .iter()
                .map(|&c| estimate.get(c).copied().unwrap_or(0.0)),
        );
        let left = &self.residuals - &self.pj * x;
        let freedom = self.residuals.len().saturating_sub(3).max(1);
        (left.norm_squared() / freedom as f64).sqrt()
    }
}

impl SurveyCalibration {
    /// What one robot's fix, solved with the positions corrected by
    /// `applied` and the pseudo-ranges by `late` at the site's speed of
    /// sound, says of the parameters, without adding it (see [`Self::add`]).
    pub fn read_fix(
        &self,
        fix: &Fix,
        applied: &Applied,
        late: &AppliedLate,
    ) -> Result<ReadFix, FixSkipped> {
        self.read_fix_solved_with(fix, applied, late, 0.0)
    }

    /// [`Self::read_fix`] of a fix solved with the site's speed of sound
    /// changed by the fraction `sound_scale`.
    pub fn read_fix_solved_with(
        &self,
        fix: &Fix,
        applied: &Applied,
        late: &AppliedLate,
        sound_scale: f64,
    ) -> Result<ReadFix, FixSkipped> {
        let receiver = checked_receiver(fix)?;
        let n = fix.used.len();
        let rows = self.rows(fix, receiver, applied, late)?;
        // The fix's own unknowns: position (x, y) and the common offset.
        let a = DMatrix::from_fn(n, 3, |i, k| match k {
            0 => -rows[i].toward.x,
            1 => -rows[i].toward.y,
            _ => 1.0,
        });
        let ata: Matrix3<f64> = (a.transpose() * &a).fixed_view::<3, 3>(0, 0).into();
        let Some(ata_inv) = ata.try_inverse() else {
            return Err(FixSkipped::Degenerate);
        };
        let ata_inv = DMatrix::from_fn(3, 3, |i, k| ata_inv[(i, k)]);
        let projector = DMatrix::identity(n, n) - &a * ata_inv * a.transpose();
        // Columns of the parameters this fix touches.
        let scale = self.information.nrows() - 1;
        let mut columns: Vec<usize> = rows
            .iter()
            .flat_map(|r| [3 * r.tx, 3 * r.tx + 1, 3 * r.tx + 2, r.cell])
            .filter(|&c| c < scale)
            .collect();
        columns.push(scale);
        columns.sort_unstable();
        columns.dedup();
        let column_of = |p: usize| columns.binary_search(&p).unwrap_or(0);
        let mut jacobian = DMatrix::zeros(n, columns.len());
        for (i, r) in rows.iter().enumerate() {
            for axis in 0..3 {
                jacobian[(i, column_of(3 * r.tx + axis))] = r.toward[axis];
            }
            if r.cell < scale {
                jacobian[(i, column_of(r.cell))] = 1.0;
            }
            // The MSU turns times into metres with its speed of sound.
            jacobian[(i, column_of(scale))] = -r.range;
        }
        let pj = &projector * &jacobian;
        // Put back the offsets, lateness and speed of sound the MSU solved
        // with: the estimate is of the whole error.
        let used_offsets = DVector::from_fn(n, |i, _| {
            rows[i].toward.dot(&rows[i].offset) + rows[i].late - sound_scale * rows[i].range
        });
        let residuals = DVector::from_vec(fix.residuals_m.clone()) + &projector * used_offsets;
        let sigma = self.config.range_sigma_m.max(MIN_RANGE_SIGMA_M);
        let worst = fix.residuals_m.iter().fold(0.0_f64, |m, e| m.max(e.abs()));
        let huber = if worst > HUBER_SIGMAS * sigma {
            HUBER_SIGMAS * sigma / worst
        } else {
            1.0
        };
        let weight = huber / (sigma * sigma);
        let info = pj.transpose() * &pj * weight;
        let rhs = pj.transpose() * &residuals * weight;
        if !info.iter().chain(rhs.iter()).all(|v| v.is_finite()) {
            // One poisoned term would spoil everything learnt.
            return Err(FixSkipped::Malformed);
        }
        Ok(ReadFix {
            columns,
            weight,
            pj,
            residuals,
        })
    }

    /// Adds a fix read by [`Self::read_fix`] (of this calibration's site)
    /// to what was learnt.
    pub fn add(&mut self, read: &ReadFix) {
        let info = read.pj.transpose() * &read.pj * read.weight;
        let rhs = read.pj.transpose() * &read.residuals * read.weight;
        for (a_i, &p) in read.columns.iter().enumerate() {
            self.weighted[p] += rhs[a_i];
            for (b_i, &q) in read.columns.iter().enumerate() {
                self.information[(p, q)] += info[(a_i, b_i)];
            }
        }
        self.fixes_taken += 1;
    }

    /// The least-squares estimate of every parameter from everything taken
    /// so far (`None` only when numbers went wrong).
    pub fn estimate(&self) -> Option<DVector<f64>> {
        let cholesky = self.information.clone().cholesky()?;
        Some(cholesky.solve(&self.weighted))
    }
}
