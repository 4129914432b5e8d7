//! A transmitter surveyed again by the fleet's fixes after it moved
//! ([`crate::transmitter_health::resurvey`]): the calibration forgets what
//! it learnt of that transmitter's position, without changing what it
//! learnt of the others, and learns its offset from the new position on.
//!
//! What the fixes said of the moved transmitter's offset is marginalised
//! out of the information (its Schur complement): the other parameters'
//! estimate and uncertainty are exactly what they were, so the neighbours
//! do not move. The transmitter then starts again from the new position
//! with the re-survey's uncertainty as its prior.

use ickon_proto::msg::control::MAX_RESURVEYED_OFFSET_M;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use super::SurveyCalibration;

/// Why a transmitter could not be surveyed again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum RebaseRefused {
    /// The site has no transmitter of that id.
    #[error("the site has no such transmitter")]
    UnknownTransmitter,
    /// The new position is not a number, or further from the surveyed one
    /// than [`MAX_RESURVEYED_OFFSET_M`]; or a sigma is not a positive number.
    #[error("the new position is out of bounds")]
    OutOfBounds,
    /// The information held of it cannot be inverted (numbers gone wrong).
    #[error("the information held of it is singular")]
    Singular,
}

impl SurveyCalibration {
    /// Takes transmitter `tx_id` to be at `position_m`, each coordinate to
    /// `sigma_m`, from now on (see the module's documentation).
    pub fn rebase(
        &mut self,
        tx_id: u32,
        position_m: [f64; 3],
        sigma_m: [f64; 3],
    ) -> Result<(), RebaseRefused> {
        let &(tx, _) = self
            .index
            .get(&tx_id)
            .ok_or(RebaseRefused::UnknownTransmitter)?;
        let rebased = Vector3::from(position_m) - self.surveyed_m[tx];
        if !rebased
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_RESURVEYED_OFFSET_M)
            || !sigma_m.iter().all(|s| s.is_finite() && *s > 0.0)
        {
            return Err(RebaseRefused::OutOfBounds);
        }
        let k = [3 * tx, 3 * tx + 1, 3 * tx + 2];
        let n = self.weighted.len();
        let own = Matrix3::from_fn(|i, j| self.information[(k[i], k[j])]);
        let own_inverse = own.try_inverse().ok_or(RebaseRefused::Singular)?;
        // The coupling of every other parameter to the transmitter's.
        let coupling = DMatrix::from_fn(n, 3, |r, j| {
            if k.contains(&r) {
                0.0
            } else {
                self.information[(r, k[j])]
            }
        });
        let own_inverse = DMatrix::from_fn(3, 3, |i, j| own_inverse[(i, j)]);
        let gain = &coupling * own_inverse;
        let own_weighted = DVector::from_fn(3, |i, _| self.weighted[k[i]]);
        self.information -= &gain * coupling.transpose();
        self.weighted -= &gain * own_weighted;
        for (i, &a) in k.iter().enumerate() {
            for r in 0..n {
                self.information[(a, r)] = 0.0;
                self.information[(r, a)] = 0.0;
            }
            self.information[(a, a)] = 1.0 / sigma_m[i].powi(2);
            self.weighted[a] = 0.0;
        }
        self.rebased_m[tx] = rebased;
        Ok(())
    }

    /// Where transmitter `tx_id` was surveyed again from its surveyed
    /// position, metres (zero: it was not, or is not the site's).
    pub fn rebased_of(&self, tx_id: u32) -> [f64; 3] {
        self.index
            .get(&tx_id)
            .map_or([0.0; 3], |&(tx, _)| self.rebased_m[tx].into())
    }

    /// Every transmitter surveyed again, `(id, offset from its surveyed
    /// position)`, in the site's order.
    pub fn rebased(&self) -> Vec<(u32, [f64; 3])> {
        self.ids
            .iter()
            .zip(&self.rebased_m)
            .filter(|(_, d)| **d != Vector3::zeros())
            .map(|(&id, d)| (id, (*d).into()))
            .collect()
    }

    /// Where transmitter `tx_id` is taken to be before anything learnt:
    /// its surveyed position, or where the fleet surveyed it again.
    pub fn base_of(&self, tx_id: u32) -> Option<[f64; 3]> {
        let &(tx, _) = self.index.get(&tx_id)?;
        Some((self.surveyed_m[tx] + self.rebased_m[tx]).into())
    }
}

#[cfg(test)]
mod tests;
