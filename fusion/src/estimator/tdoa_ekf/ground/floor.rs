//! The floor plan as a constraint on the state.

use super::TdoaEkf;
use crate::estimator::tdoa_ekf::ground_state::{X, Y};

impl TdoaEkf {
    /// A position off the floor is impossible: it is moved onto its edge.
    pub(super) fn project_on_floor(&mut self) {
        let (Some(floor), Some((x, _))) = (self.params.floor, &mut self.state) else {
            return;
        };
        x[X] = x[X].clamp(floor.min_m[0], floor.max_m[0]);
        x[Y] = x[Y].clamp(floor.min_m[1], floor.max_m[1]);
    }
}
