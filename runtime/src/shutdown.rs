//! The one shutdown future of every node process.

use std::future::Future;
use std::time::Duration;

use tokio::signal::unix::{Signal, SignalKind, signal};

/// Completes on Ctrl-C, SIGTERM, or (with `exit_with_parent`) when the parent goes away.
///
/// The signal handlers are installed when this is called, not when the
/// future is first polled: a SIGTERM that arrives while the process is
/// still starting up is held for the future instead of killing the
/// process on the spot (which would skip every clean-up). Call it from
/// inside a tokio runtime.
pub fn shutdown_signal(exit_with_parent: bool) -> impl Future<Output = ()> + Send + 'static {
    let parent = std::os::unix::process::parent_id();
    let interrupt = signal(SignalKind::interrupt()).ok();
    let terminate = signal(SignalKind::terminate()).ok();
    async move {
        let orphaned = async move {
            if !exit_with_parent {
                // Nothing to watch: no wake-up four times a second for it.
                return std::future::pending::<()>().await;
            }
            loop {
                tokio::time::sleep(Duration::from_millis(250)).await;
                if std::os::unix::process::parent_id() != parent {
                    return;
                }
            }
        };
        tokio::select! {
            _ = received(interrupt) => {}
            _ = received(terminate) => {}
            _ = orphaned => {}
        }
    }
}

/// Completes when `signal` arrives; never when its handler could not be installed.
async fn received(signal: Option<Signal>) {
    match signal {
        Some(mut s) => {
            s.recv().await;
        }
        None => std::future::pending::<()>().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A SIGTERM sent after the future was made, before it is first polled,
    /// completes it (and does not end the test process).
    #[test]
    fn a_sigterm_before_the_first_poll_is_held_for_the_future() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let shutdown = shutdown_signal(false);
            nix::sys::signal::raise(nix::sys::signal::Signal::SIGTERM).unwrap();
            tokio::time::timeout(Duration::from_secs(5), shutdown)
                .await
                .expect("the held SIGTERM completes the future");
        });
    }
}
