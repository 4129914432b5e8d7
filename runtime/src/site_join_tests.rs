//! The site join against a central unit stood in for by a queryable of the
//! same in-process session (no network: scouting off, nothing listened on).

use std::time::Duration;

use ickon_proto::keys::Keys;
use ickon_proto::msg::control::SiteInfo;
use zenoh::Wait;

use super::*;

const LAB: &str = include_str!("../../deploy/sites/lab.toml");

fn info(site_toml: &str) -> SiteInfo {
    SiteInfo {
        site: "lab".into(),
        version: 3,
        site_toml: site_toml.into(),
    }
}

/// A session that talks to itself only.
async fn lone_session() -> Session {
    let mut config = zenoh::Config::default();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    config.insert_json5("listen/endpoints", "[]").unwrap();
    zenoh::open(config).await.unwrap()
}

#[test]
fn a_site_parses_and_a_broken_one_is_a_site_error() {
    let site = parse_site(&info(LAB)).unwrap();
    assert!(!site.robots.is_empty());
    let err = parse_site(&info("name = ")).unwrap_err();
    assert!(matches!(err, NodeError::Site(_)), "{err}");
    assert!(err.to_string().contains(FETCHED_ORIGIN), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_site_is_fetched_parsed_and_the_token_seen() {
    let session = lone_session().await;
    let keys = Keys::new("lab").unwrap();
    let answer = ickon_proto::encode(&info(LAB)).unwrap();
    let _central = session
        .declare_queryable(keys.central_site())
        .callback(move |query| {
            let _ = query.reply(query.key_expr().clone(), answer.clone()).wait();
        })
        .await
        .unwrap();
    let join = SiteJoin::new(&session, &keys);
    let watch = join.watch_tokens(keys.alive_all()).await.unwrap();
    let _token = join
        .announce(keys.alive_robot("r1").unwrap())
        .await
        .unwrap();
    let seen = tokio::time::timeout(Duration::from_secs(5), watch.recv_async())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(
        seen.key_expr().as_str(),
        keys.alive_robot("r1").unwrap().as_str()
    );
    let mut never = Box::pin(std::future::pending::<()>());
    let joined = tokio::time::timeout(Duration::from_secs(10), join.site(&mut never))
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    assert_eq!(joined.info.version, 3);
    assert_eq!(joined.site.name, parse_site(&info(LAB)).unwrap().name);
    session.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_central_unit_and_a_shutdown_give_no_site() {
    let session = lone_session().await;
    let keys = Keys::new("lab").unwrap();
    let join = SiteJoin::new(&session, &keys);
    let mut stopped = Box::pin(std::future::ready(()));
    let site = join.site(&mut stopped).await.unwrap();
    assert!(site.is_none());
    let schedule = join
        .schedule_once(Duration::from_millis(100))
        .await
        .unwrap();
    assert!(schedule.is_none());
    session.close().await.unwrap();
}
