//! Answers to the queries the loop takes itself: the admin commands (a
//! reload excepted, read off the loop) and any reply.

use ickon_proto::decode;
use ickon_proto::encode;
use ickon_proto::keys::{Key, Keys};
use ickon_proto::msg::admin::{CoverageRequest, RobotCounts, RobotPage, RobotsRequest};
use ickon_proto::time::Time;
use ickon_runtime::{LogLimiter, zerr};
use zenoh::query::Query;

use crate::core::CentralCore;

/// Answers a query. A requester that went away is its own problem: the
/// failure is logged and the central unit carries on.
pub(super) async fn reply<T: serde::Serialize>(query: &Query, value: &T) {
    let sent = match encode(value) {
        Ok(bytes) => query
            .reply(query.key_expr().clone(), bytes)
            .await
            .map_err(zerr),
        Err(e) => Err(e.into()),
    };
    if let Err(e) = sent {
        tracing::warn!("reply on {} failed: {e}", query.key_expr());
    }
}

/// Answers one admin query (`reload` excepted: see [`reload`]). Queries
/// naming no command are logged through `unknown`: anyone allowed on the
/// admin keys can send them by the thousand.
pub(super) async fn answer_admin(
    keys: &Keys,
    core: &mut CentralCore,
    q: &Query,
    now: Time,
    unknown: &mut LogLimiter<()>,
) {
    let Ok(Key::CentralAdmin(command)) = keys.parse(q.key_expr().as_str()) else {
        return;
    };
    match command.as_str() {
        // With a request, a page of the robots; without, the whole status
        // (the recorder's Foxglove view and older admins' question).
        "robots" if q.payload().is_some() => {
            let page = match q.payload().map(|p| decode::<RobotsRequest>(&p.to_bytes())) {
                Some(Ok(request)) => core.robots_page(now, &request),
                _ => RobotPage {
                    error: "the payload is not a robots request".into(),
                    page: 0,
                    pages: 1,
                    matching: 0,
                    counts: RobotCounts::default(),
                    robots: Vec::new(),
                },
            };
            reply(q, &page).await;
        }
        "robots" => reply(q, &core.status(now)).await,
        "status" | "cells" | "sync" => reply(q, &core.status_summary(now)).await,
        "schedule" => reply(q, &core.current_firing()).await,
        "transmitters" => reply(q, &core.transmitters(now)).await,
        "coverage" => {
            // No payload (or an unreadable one): the default grid.
            let resolution_m = q
                .payload()
                .and_then(|p| decode::<CoverageRequest>(&p.to_bytes()).ok())
                .map_or(crate::coverage::DEFAULT_RESOLUTION_M, |r| r.resolution_m);
            reply(q, &core.coverage(resolution_m)).await;
        }
        "pause" => reply(q, &core.set_paused(true)).await,
        "resume" => reply(q, &core.set_paused(false)).await,
        other => {
            if let Some(held) = unknown.admit((), std::time::Instant::now()) {
                tracing::warn!(
                    "unknown admin command {other:?} ignored ({held} more since the last such line)"
                );
            }
        }
    }
}
