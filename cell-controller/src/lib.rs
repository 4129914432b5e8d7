//! # ickon-cell
//!
//! The cell controller of ICKON (seed 000 section 3.1.1, "CCU"): it keeps its
//! clock synchronised with the central unit ([`sync`]) and fires its
//! transmitters at `cycle start + offset` on the master time base
//! ([`timer`]). Both are pure; the Zenoh node (feature `zenoh`) drives them.

#[cfg(feature = "zenoh")]
pub mod node;
pub mod sync;
pub mod timer;
