//! # ickon-evaluation
//!
//! How well ICKON-rs positions, measured:
//!
//! - `ickon eval` ([`EvalArgs`], [`run_eval`]): every estimator on the
//!   simulated world in virtual time, scored as in the seed papers, one
//!   robot per route or a fleet at once;
//! - `ickon replay util` ([`UtilArgs`], [`run_util`]): the real UTIL TDOA
//!   flights through the 3D estimators, scored against motion capture;
//! - `ickon replay plaza` ([`PlazaArgs`], [`run_plaza`]): the ground
//!   filter on a real wheeled robot (CMU Plaza), scored against its truth;
//! - `ickon replay tdoa` ([`TdoaArgs`], [`run_tdoa`]) and `ickon convert
//!   util --to tdoa` ([`ConvertUtilArgs`], [`run_convert_util`]): anyone's
//!   arrival times in one documented log format ([`tdoa_log`]);
//! - [`chart`]: the font and styling every PNG picture of the tools shares;
//! - [`print_estimator_table`]: the papers' accuracy table, also printed by
//!   the MCAP replay.
//!
//! No Zenoh: everything here runs in one process from files and seeds.

pub mod chart;
mod eval;
mod plaza;
pub mod tdoa_log;
mod util;

pub use eval::table::print as print_estimator_table;
pub use eval::{EvalArgs, run as run_eval};
pub use plaza::{ConvertPlazaArgs, PlazaArgs, run as run_plaza, run_convert as run_convert_plaza};
pub use tdoa_log::{ConvertUtilArgs, TdoaArgs, run as run_tdoa, run_convert_util};
pub use util::{UtilArgs, run as run_util};
