//! End-to-end tests of the `ickon` command line on its own: site and
//! credential files, exit codes, emulated boards, `ickon eval`. One module
//! per subject.

mod closed_stdout;
mod device_cli;
mod endless_files;
mod eval_cli;
mod site_check;
mod site_secure;
