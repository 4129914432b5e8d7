//! The one shutdown future of every node process.

use std::time::Duration;

/// Completes on Ctrl-C, SIGTERM, or (with `exit_with_parent`) when the parent goes away.
pub async fn shutdown_signal(exit_with_parent: bool) {
    let parent = std::os::unix::process::parent_id();
    let orphaned = async move {
        loop {
            tokio::time::sleep(Duration::from_millis(250)).await;
            if exit_with_parent && std::os::unix::process::parent_id() != parent {
                return;
            }
        }
    };
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
        _ = orphaned => {}
    }
}
