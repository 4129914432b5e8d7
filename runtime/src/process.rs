//! What every node binary does around its async work: logging to stderr,
//! a small tokio runtime, and the outcome as the process exit code.

use std::future::Future;
use std::process::ExitCode;

/// Sets up `tracing` for a binary: the `RUST_LOG` filter when set, else
/// `default` (e.g. `"info"`), written to stderr so stdout stays clean.
pub fn init_tracing(default: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
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
/// with its causes and gives exit code 1, as does a runtime that cannot
/// start.
pub fn run_node<T, E: std::fmt::Display>(
    worker_threads: usize,
    work: impl Future<Output = Result<T, E>>,
) -> ExitCode {
    match block_on(worker_threads, work) {
        Some(Ok(_)) => ExitCode::SUCCESS,
        Some(Err(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
        None => ExitCode::FAILURE,
    }
}

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
            run_node::<(), _>(1, async {
                Err(crate::NodeError::Setup("no central unit".into()))
            }),
            ExitCode::FAILURE
        );
    }
}
