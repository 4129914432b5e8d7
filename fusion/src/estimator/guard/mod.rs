//! Robustness tools shared by the range-difference filters, so that no
//! filter drifts through metres on real data:
//! - [`FlightVolume`]: the box the receiver moves in (the anchors' box with
//!   a margin, or given); states are projected into it;
//! - [`LateArrivals`]: one-sided handling of late (non-line-of-sight)
//!   arrivals, which can only lengthen a path, by setting aside an anchor
//!   blamed for most of its recent measurements;
//! - [`Window`]: a position from a fraction of a second of measurements
//!   alone, trusted only when consistent, with the mirror solution of the
//!   geometry detected;
//! - [`Guarded`]: the watch that places a filter from a consistent window
//!   before it publishes anything, keeps it in the volume, and declares it
//!   lost (and re-places it) when it is.

mod late;
mod supervisor;
mod volume;
mod window;

#[cfg(test)]
mod tests;

pub use late::{LateArrivals, LateParams};
pub use supervisor::{
    GuardCounts, GuardParams, Guarded, GuardedFilter, LostParams, LostReason, Step,
};
pub use volume::{FlightVolume, VolumeError};
pub use window::{Window, WindowFix, WindowParams};
