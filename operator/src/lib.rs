//! # ickon-operator
//!
//! The tools a site's operator runs beside the nodes:
//!
//! - `ickon admin` ([`AdminCommand`], [`run_admin`]): status, cells, robots,
//!   sync, schedule, coverage, pause, resume and reload, asked of the
//!   central unit of a running site;
//! - `ickon site secure` ([`SecureArgs`], [`run_secure`], and [`secure`]
//!   for the files it writes): a site's routers with access control and one
//!   credential per node;
//! - `ickon site check` ([`check_site`]) and `ickon msu check`
//!   ([`check_msu_config`]): a site file or an MSU configuration validated
//!   and summarised;
//! - `ickon device check` ([`DeviceCheckArgs`], [`check_device`]): a
//!   board of the device protocol tried as a cell or an MSU would use it;
//! - `ickon router` ([`RouterArgs`], [`run_router`]): a Zenoh router, the
//!   hub of a floor.

mod admin;
mod device_check;
mod msu_check;
mod router;
pub mod secure;
mod site_check;

pub use admin::{AdminCommand, run as run_admin};
pub use device_check::{DeviceCheckArgs, ExpectedBoard, run as check_device};
pub use msu_check::check as check_msu_config;
pub use router::{RouterArgs, run as run_router};
pub use secure::{SecureArgs, run as run_secure};
pub use site_check::check as check_site;
