//! What every node binary does around its async work: logging to stderr,
//! a small tokio runtime, and the outcome as the process exit code.

use std::future::Future;
use std::process::ExitCode;

use crate::NodeError;

/// Whether stderr is a terminal: only then do log lines carry colour
/// codes (in a file, a journal or a pipe they are noise).
pub fn stderr_is_terminal() -> bool {
    std::io::IsTerminal::is_terminal(&std::io::stderr())
}

/// Sets up `tracing` for a binary: the `RUST_LOG` filter when set, else
/// `default` (e.g. `"info"`), written to stderr so stdout stays clean,
/// coloured only on a terminal; warnings and errors are also kept for
/// whoever shows them ([`crate::warnings`]).
pub fn init_tracing(default: &str) {
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::registry()
        .with(filter)
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_ansi(stderr_is_terminal()),
        )
        .with(crate::warnings::WarningTap)
        .init();
}

/// Runs `work` to completion on a multi-threaded tokio runtime with
/// `worker_threads` workers (nodes are small: one or two are plenty, and a
/// site runs many of them on one machine); `None`, after saying why on
/// stderr, when the runtime cannot start.
pub fn block_on<F: Future>(worker_threads: usize, work: F) -> Option<F::Output> {
    match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(worker_threads.max(1))
        .enable_all()
        .build()
    {
        Ok(runtime) => Some(runtime.block_on(work)),
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            None
        }
    }
}

/// [`block_on`] for a node: success is exit code 0; an error is printed
/// with its causes and gives exit code 2 when it is bad input the user can
/// fix (an invalid Zenoh configuration or credential file:
/// [`NodeError::Config`]), else 1, as does a runtime that cannot start.
pub fn run_node<T>(
    worker_threads: usize,
    work: impl Future<Output = Result<T, NodeError>>,
) -> ExitCode {
    match block_on(worker_threads, work) {
        Some(Ok(_)) => ExitCode::SUCCESS,
        Some(Err(e)) => {
            eprintln!("error: {e:#}");
            match e {
                NodeError::Config { .. } => ExitCode::from(EXIT_BAD_CONFIG),
                _ => ExitCode::FAILURE,
            }
        }
        None => ExitCode::FAILURE,
    }
}

/// The exit code of a node whose configuration is invalid.
pub const EXIT_BAD_CONFIG: u8 = 2;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_outcome_of_the_work_is_the_exit_code() {
        assert_eq!(
            run_node(1, async { Ok::<_, crate::NodeError>(7) }),
            ExitCode::SUCCESS
        );
        assert_eq!(
            run_node::<()>(1, async {
                Err(crate::NodeError::Setup("no central unit".into()))
            }),
            ExitCode::FAILURE
        );
        assert_eq!(
            run_node::<()>(1, async {
                Err(crate::NodeError::Config {
                    what: "cell-c1.json5".into(),
                    reason: "no password".into(),
                })
            }),
            ExitCode::from(EXIT_BAD_CONFIG)
        );
    }
}
