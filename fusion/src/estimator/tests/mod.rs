//! Behaviour tests across all estimators: a small deterministic robot
//! simulation, hand-computed filter steps, late and bad inputs, and random
//! input sequences.

mod filters;
mod props;
mod runs;
pub(super) mod sim;
