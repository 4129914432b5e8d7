//! `ickon`: the command line of ICKON-rs (the program is the library's
//! `main`). The checks of the command line against its documentation, of
//! every crate's imports, of its functions' lengths and of the workspace's
//! build profile run as this binary's unit tests.

#[cfg(test)]
mod docs_check;
#[cfg(test)]
mod fn_length_check;
#[cfg(test)]
mod import_check;
#[cfg(test)]
mod profile_check;

use std::process::ExitCode;

fn main() -> ExitCode {
    ickon::main()
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// clap checks a command line's definition only when it is parsed: a
    /// flag defined twice (a node's own `--config` beside the Zenoh one)
    /// would panic in the first process that starts that node.
    #[test]
    fn every_subcommand_is_well_formed() {
        ickon::cli::Cli::command().debug_assert();
    }
}
