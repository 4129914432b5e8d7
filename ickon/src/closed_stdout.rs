//! A reader that goes away ends the command quietly, as it ends a Unix
//! filter: `ickon site secure ... | head -1` prints one line and stops.
//!
//! Rust's runtime ignores SIGPIPE, so that a node writing to a socket whose
//! peer left gets an error instead of dying; the cost is that `println!` to
//! a closed pipe panics. This process turns that one panic into a quiet
//! exit with the status a shell gives a process SIGPIPE ended; every other
//! panic is reported as before.

/// The exit status of a process a closed pipe ended (128 + SIGPIPE).
const CLOSED_PIPE_EXIT: i32 = 141;

/// Installs the hook; the panic report it replaces is kept for every other
/// panic.
pub(crate) fn exit_quietly_when_stdout_closes() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied());
        if message.is_some_and(is_closed_stdout) {
            std::process::exit(CLOSED_PIPE_EXIT);
        }
        report(info);
    }));
}

/// Whether `message` is the standard library's panic for printing to a
/// stdout whose reader went away (`print!`, `println!`).
fn is_closed_stdout(message: &str) -> bool {
    message
        .strip_prefix("failed printing to stdout: ")
        .is_some_and(|why| why.starts_with("Broken pipe"))
}
