//! The message size limits a secured router enforces (`ickon site secure`
//! writes them as Zenoh's `low_pass_filter`): on a live `ickon router`,
//! robot r1, authenticated with its own credential, publishes on one of its
//! own keys messages just under, at and just over the robots' 64 KiB, and
//! one of a megabyte; a subscriber with the recorder's credential (allowed
//! to hear everything) receives every message within the limit and none
//! over it. The same router without its limits passes them all: the drops
//! are the limits', not the transport's.
//!
//! Every wait polls with a deadline; the router is killed when its guard
//! drops, whatever happens.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use ickon_operator::secure::limits::NODE_MESSAGE_BYTES;
use ickon_proto::keys::{Keys, RobotTopic};
use ickon_testkit::{ChildGuard, poll_until};
use support::ICKON;
use zenoh::Wait;
use zenoh::handlers::FifoChannel;

/// Generous but bounded: a loaded two-core machine starts a process slowly.
const START_TIMEOUT: Duration = Duration::from_secs(90);

fn client_file(dir: &Path, user: &str) -> PathBuf {
    dir.join("clients").join(format!("{user}.json5"))
}

/// A session authenticated as the client file `file` says, on `endpoint`.
fn open_as(file: &Path, endpoint: &str) -> zenoh::Session {
    let mut config = zenoh::Config::from_file(file).expect("a client file");
    config
        .insert_json5("connect/endpoints", &format!("[{endpoint:?}]"))
        .unwrap();
    config.insert_json5("connect/timeout_ms", "10000").unwrap();
    zenoh::open(config).wait().expect("the router lets it in")
}

/// A payload of `len` bytes that starts with its own length (the
/// subscriber tells the messages apart by it).
fn payload(len: usize) -> Vec<u8> {
    let mut bytes = vec![0xA5; len];
    bytes[..8].copy_from_slice(&(len as u64).to_le_bytes());
    bytes
}

/// A session with no credential on `endpoint`, as any client of the
/// default mesh.
fn open_plain(endpoint: &str) -> zenoh::Session {
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", "\"client\"").unwrap();
    config
        .insert_json5("connect/endpoints", &format!("[{endpoint:?}]"))
        .unwrap();
    config.insert_json5("connect/timeout_ms", "10000").unwrap();
    zenoh::open(config).wait().expect("the router lets it in")
}

/// What a subscriber with the recorder's credential receives of the
/// messages `sent` (their lengths) that robot r1 publishes on its
/// odometry key, through a router started with `router_config` on
/// `endpoint`, the credentials in `dir`. The last message sent must be a
/// small one.
fn through_router(
    router_config: &Path,
    dir: &Path,
    endpoint: &str,
    keys: &Keys,
    sent: &[usize],
) -> Vec<usize> {
    let mut cmd = Command::new(ICKON);
    cmd.args(["router", "--zenoh-config"])
        .arg(router_config)
        .args(["--listen", endpoint]);
    let open = |user: &str| open_as(&client_file(dir, user), endpoint);
    through(cmd, dir.parent().unwrap(), endpoint, keys, sent, &open)
}

/// The same through the router `cmd` starts, the sessions opened by
/// `open` (by user), the router's log in `log_dir`.
fn through(
    cmd: Command,
    log_dir: &Path,
    endpoint: &str,
    keys: &Keys,
    sent: &[usize],
    open: &dyn Fn(&str) -> zenoh::Session,
) -> Vec<usize> {
    let mut router = ChildGuard::spawn("router", cmd, log_dir).expect("router");
    let port: u16 = endpoint.rsplit(':').next().unwrap().parse().unwrap();
    poll_until(START_TIMEOUT, "the router to listen", || {
        if let Some(status) = router.exit_status() {
            panic!("router {status}:\n{}", router.log());
        }
        ickon_testkit::port::accepts(port).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", router.log()));

    let key = keys.robot("r1", RobotTopic::Odom).unwrap();
    let recorder = open("recorder");
    let heard = recorder
        .declare_subscriber(&key)
        .with(FifoChannel::new(1_000))
        .wait()
        .unwrap();
    let robot = open("robot-r1");
    let publisher = robot
        .declare_publisher(&key)
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .wait()
        .unwrap();

    // The subscription reaches the router asynchronously: small messages
    // until one arrives.
    let mut received: Vec<usize> = Vec::new();
    poll_until(Duration::from_secs(30), "a first message through", || {
        publisher.put(payload(64)).wait().unwrap();
        std::thread::sleep(Duration::from_millis(50));
        while let Ok(Some(s)) = heard.try_recv() {
            received.push(s.payload().len());
        }
        (!received.is_empty()).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", router.log()));
    // Any of the first small ones still on their way.
    std::thread::sleep(Duration::from_millis(200));
    while let Ok(Some(_)) = heard.try_recv() {}
    received.clear();

    for &len in sent {
        publisher.put(payload(len)).wait().unwrap();
    }
    // Once the last (small) one arrives, every earlier one that passed has
    // arrived too: one publisher, one path, in order.
    let last = *sent.last().unwrap();
    poll_until(Duration::from_secs(30), "the last message", || {
        while let Ok(Some(s)) = heard.try_recv() {
            let bytes = s.payload().to_bytes();
            let len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
            assert_eq!(len, bytes.len(), "a message arrived whole");
            received.push(len);
        }
        received.contains(&last).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}: received {received:?}\n{}", router.log()));
    received
}

#[test]
fn a_secured_router_drops_a_robots_oversized_message_and_passes_the_rest() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let site = format!("limits-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(tmp.path(), &site);
    let keys = Keys::new(&site).unwrap();
    let endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let dir = tmp.path().join("secure");
    let secured = Command::new(ICKON)
        .args(["site", "secure"])
        .arg(&file)
        .arg("--out")
        .arg(&dir)
        .args(["--listen", &endpoint, "--connect", &endpoint])
        .output()
        .expect("ickon site secure runs");
    assert!(
        secured.status.success(),
        "{}",
        String::from_utf8_lossy(&secured.stderr)
    );

    // Zenoh counts the payload (and an attachment, none here), nothing of
    // the message's framing: the limit is on the payload's bytes.
    let under = NODE_MESSAGE_BYTES - 1_024;
    let over = NODE_MESSAGE_BYTES + 1_024;
    let sent = [1_024, over, under, 1 << 20, NODE_MESSAGE_BYTES, 2_048];
    let received = through_router(&dir.join("router.json5"), &dir, &endpoint, &keys, &sent);
    assert_eq!(
        received,
        vec![1_024, under, NODE_MESSAGE_BYTES, 2_048],
        "the router passes what fits a robot's {NODE_MESSAGE_BYTES} bytes and drops the rest"
    );

    // The same router with limits far above the messages (a router
    // without limits of its own gets every site's): everything passes.
    // JSON under a header of `//` comments.
    let text = std::fs::read_to_string(dir.join("router.json5")).unwrap();
    let json: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut config: serde_json::Value =
        serde_json::from_str(&json).expect("the router's configuration is JSON");
    let loose = serde_json::json!([{
        "id": "loose",
        "messages": ["put", "delete", "query", "reply"],
        "key_exprs": ["**"],
        "size_limit": 1u64 << 30,
    }]);
    assert!(
        config
            .as_object_mut()
            .unwrap()
            .insert("low_pass_filter".into(), loose)
            .is_some(),
        "the router's configuration has its limits"
    );
    let unlimited = tmp.path().join("router-without-limits.json5");
    std::fs::write(&unlimited, config.to_string()).unwrap();
    let endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let received = through_router(&unlimited, &dir, &endpoint, &keys, &sent);
    assert_eq!(
        received,
        sent.to_vec(),
        "under loose limits every message passes"
    );
}

/// A router the product starts without a configuration of its own (as
/// `ickon sim` starts its routers on the default mesh) drops an outside
/// client's messages of megabytes on a node's keys, and the link goes on
/// carrying the small ones after them.
#[test]
fn a_plain_router_drops_oversized_messages_and_keeps_the_link() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let site = format!("plain-limits-{}", std::process::id());
    let keys = Keys::new(&site).unwrap();
    let endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let mut cmd = Command::new(ICKON);
    cmd.args(["router", "--listen", &endpoint]);
    let eight_mib = 8 << 20;
    let sent = [
        1_024,
        eight_mib,
        2_048,
        eight_mib,
        NODE_MESSAGE_BYTES,
        4_096,
    ];
    let received = through(cmd, tmp.path(), &endpoint, &keys, &sent, &|_| {
        open_plain(&endpoint)
    });
    assert_eq!(
        received,
        vec![1_024, 2_048, NODE_MESSAGE_BYTES, 4_096],
        "the router drops the 8 MiB messages and passes the rest"
    );
}
