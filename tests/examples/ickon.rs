//! The `ickon` binary under test: the `ickon` package's program, built as
//! a target of the test package (see `support/ickon.rs` for why).

fn main() -> std::process::ExitCode {
    ickon::main()
}
