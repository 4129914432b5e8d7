//! Why an input could not be used by the MSU core.

use ickon_fusion::estimator::EstimatorError;
use ickon_fusion::tdoa;

use crate::assembly::AssemblyError;

/// Why a message could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MsuError {
    /// No schedule yet: arrivals cannot be matched to emissions.
    #[error("no schedule received yet")]
    NoSchedule,
    /// The cycle could not be assembled.
    #[error(transparent)]
    Assembly(#[from] AssemblyError),
    /// The cycle's signals are malformed (cannot come from a working MSU).
    #[error(transparent)]
    Solve(#[from] tdoa::SolveError),
    /// The estimator rejected the input.
    #[error(transparent)]
    Estimator(#[from] EstimatorError),
    /// The schedule was refused (see [`ickon_proto::epoch`]).
    #[error(transparent)]
    Schedule(#[from] ickon_proto::epoch::ScheduleRefused),
    /// A cell status that cannot be used.
    #[error("status of cell {cell:?}: {reason}")]
    CellStatus {
        /// The cell it names.
        cell: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A survey calibration that cannot be used.
    #[error("survey calibration {version} of epoch {epoch}: {reason}")]
    Survey {
        /// Its epoch.
        epoch: u64,
        /// Its version.
        version: u32,
        /// What is wrong with it.
        reason: String,
    },
    /// Distances to beacons that the site cannot explain (the good ones of
    /// the same reading were used).
    #[error("{refused} of {of} distance(s) refused; {reason}")]
    BeaconDistances {
        /// How many were refused.
        refused: usize,
        /// How many the reading had.
        of: usize,
        /// Why the first was refused.
        reason: String,
    },
    /// A ranging kit's position that cannot be used.
    #[error("kit position refused: {reason}")]
    KitPosition {
        /// Why.
        reason: String,
    },
    /// The input is stamped far ahead of every input before it (see [`crate::time_gate`]).
    #[error("input stamped {ahead_s:.3} s ahead of the newest: refused")]
    FromTheFuture {
        /// How far ahead, seconds.
        ahead_s: f64,
    },
}
