//! Mutual TLS on a secured site (`ickon site secure` with `tls/`
//! endpoints, the default): on a live router with the central unit and
//! four cells, a client speaking plain TCP, one without a client
//! certificate, one with a certificate of another CA and one with an
//! expired certificate of the site CA cannot open a session; a robot's
//! certificate cannot carry another robot's user, nor publish the central
//! unit's cycle triggers, while the central unit's own reach the cells.
//! `ickon sim --secure` runs its mesh over TLS and every robot fixes.
//! A node given an expired, soon-expiring or malformed certificate or key
//! says so at start, naming the file.
//!
//! Every wait polls with a deadline; every process is killed when its
//! guard drops, whatever happens.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use ickon_operator::secure::certs::{Role, SiteCa, Validity};
use ickon_proto::keys::{Keys, RobotTopic};
use ickon_testkit::{ChildGuard, poll_until};
use support::ICKON;
use zenoh::Wait;
use zenoh::handlers::FifoChannel;

/// Generous but bounded: a loaded two-core machine starts a process slowly.
const START_TIMEOUT: Duration = Duration::from_secs(90);

/// A free loopback TLS endpoint, `tls/127.0.0.1:<port>`, and its port.
fn tls_endpoint() -> (String, u16) {
    let tcp = ickon_testkit::loopback_endpoint().expect("port");
    let port = tcp.rsplit(':').next().unwrap().parse().unwrap();
    (tcp.replacen("tcp/", "tls/", 1), port)
}

/// `ickon site secure` of `site` into `out`, the router on `endpoint`.
fn secure(site: &Path, out: &Path, endpoint: &str) {
    let output = Command::new(ICKON)
        .args(["site", "secure"])
        .arg(site)
        .arg("--out")
        .arg(out)
        .args(["--listen", endpoint, "--connect", endpoint])
        .output()
        .expect("ickon site secure runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn client_file(dir: &Path, user: &str) -> PathBuf {
    dir.join("clients").join(format!("{user}.json5"))
}

/// The client configuration `file`, to connect to `endpoint` and give up
/// at once if the router refuses.
fn config_of(file: &Path, endpoint: &str) -> zenoh::Config {
    let mut config = zenoh::Config::from_file(file).expect("client file");
    config
        .insert_json5("connect/endpoints", &format!("[{endpoint:?}]"))
        .unwrap();
    config.insert_json5("connect/timeout_ms", "3000").unwrap();
    config
}

fn set(config: &mut zenoh::Config, key: &str, value: &Path) {
    config
        .insert_json5(key, &format!("{:?}", value.display().to_string()))
        .unwrap();
}

/// `ickon node <role>` as a client of the secured router, as `user`.
fn node(role: &str, site: &str, endpoint: &str, dir: &Path, user: &str) -> Command {
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", role, "--zenoh-config"])
        .arg(client_file(dir, user))
        .args(["--connect", endpoint, "--site-name", site]);
    cmd
}

type Sub = zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

fn drain(sub: &Sub) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    while let Ok(Some(s)) = sub.try_recv() {
        out.push(s.payload().to_bytes().to_vec());
    }
    out
}

/// Writes `issued` as `<name>.crt` and `<name>.key` in `dir`.
fn write_pair(dir: &Path, name: &str, cert: &str, key: &str) -> (PathBuf, PathBuf) {
    let (c, k) = (
        dir.join(format!("{name}.crt")),
        dir.join(format!("{name}.key")),
    );
    std::fs::write(&c, cert).unwrap();
    std::fs::write(&k, key).unwrap();
    (c, k)
}

#[test]
fn the_tls_router_refuses_strangers_and_forgers() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let site = format!("tls-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(tmp.path(), &site);
    let keys = Keys::new(&site).unwrap();
    let (endpoint, port) = tls_endpoint();
    let dir = tmp.path().join("secure");
    secure(&file, &dir, &endpoint);

    let mut router_cmd = Command::new(ICKON);
    router_cmd
        .args(["router", "--zenoh-config"])
        .arg(dir.join("router.json5"))
        .args(["--listen", &endpoint]);
    let mut router = ChildGuard::spawn("router", router_cmd, tmp.path()).expect("router");
    poll_until(START_TIMEOUT, "the router to listen", || {
        if let Some(status) = router.exit_status() {
            panic!("router {status}:\n{}", router.log());
        }
        ickon_testkit::port::accepts(port).then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", router.log()));

    let mut nodes = Vec::new();
    let mut central = node("central", &site, &endpoint, &dir, "central");
    central.arg("--site").arg(&file);
    nodes.push(ChildGuard::spawn("central", central, tmp.path()).expect("central"));
    for cell in ["c1", "c2", "c3", "c4"] {
        let mut cmd = node("cell", &site, &endpoint, &dir, &format!("cell-{cell}"));
        cmd.args(["--cell", cell]);
        nodes.push(ChildGuard::spawn(&format!("cell-{cell}"), cmd, tmp.path()).expect("cell"));
    }

    // Refused at the handshake: nothing of theirs can reach anyone.
    let robot_file = client_file(&dir, "robot-r1");
    let plain = config_of(&robot_file, &endpoint.replacen("tls/", "tcp/", 1));
    assert!(zenoh::open(plain).wait().is_err(), "plain TCP refused");
    let mut no_cert = config_of(&robot_file, &endpoint);
    // A TLS client that trusts the site CA but shows no certificate.
    no_cert
        .insert_json5("transport/link/tls/enable_mtls", "false")
        .unwrap();
    assert!(
        zenoh::open(no_cert).wait().is_err(),
        "TLS without a client certificate refused"
    );
    let now = ickon_runtime::certificate::unix_now_s();
    let other_ca = SiteCa::generate(
        &site,
        Validity::from_unix(now - 3600, now + 86_400).unwrap(),
    )
    .unwrap();
    let stranger = other_ca
        .issue(
            "robot-r1",
            Role::Client,
            &[],
            Validity::from_unix(now - 3600, now + 86_400).unwrap(),
        )
        .unwrap();
    let (c, k) = write_pair(
        tmp.path(),
        "stranger",
        &stranger.cert_pem,
        &stranger.key_pem,
    );
    let mut foreign = config_of(&robot_file, &endpoint);
    set(&mut foreign, "transport/link/tls/connect_certificate", &c);
    set(&mut foreign, "transport/link/tls/connect_private_key", &k);
    assert!(
        zenoh::open(foreign).wait().is_err(),
        "a certificate of another CA refused"
    );
    let ca_dir = dir.join("ca");
    let site_ca = SiteCa::load(
        &std::fs::read_to_string(ca_dir.join("ca.crt")).unwrap(),
        &std::fs::read_to_string(ca_dir.join("ca.key")).unwrap(),
    )
    .unwrap();
    let expired = site_ca
        .issue(
            "robot-r1",
            Role::Client,
            &[],
            Validity::from_unix(now - 10 * 86_400, now - 86_400).unwrap(),
        )
        .unwrap();
    let (c, k) = write_pair(tmp.path(), "expired", &expired.cert_pem, &expired.key_pem);
    let mut old = config_of(&robot_file, &endpoint);
    set(&mut old, "transport/link/tls/connect_certificate", &c);
    set(&mut old, "transport/link/tls/connect_private_key", &k);
    assert!(
        zenoh::open(old).wait().is_err(),
        "an expired certificate of the site CA refused"
    );
    // The same site CA, the right password, a fresh certificate: accepted
    // (what made the three above fail was the certificate alone).
    let fresh = site_ca
        .issue(
            "robot-r1",
            Role::Client,
            &[],
            Validity::from_unix(now - 3600, now + 86_400).unwrap(),
        )
        .unwrap();
    let (c, k) = write_pair(tmp.path(), "fresh", &fresh.cert_pem, &fresh.key_pem);
    let mut renewed = config_of(&robot_file, &endpoint);
    set(&mut renewed, "transport/link/tls/connect_certificate", &c);
    set(&mut renewed, "transport/link/tls/connect_private_key", &k);
    let renewed = zenoh::open(renewed).wait().expect("a renewed certificate");
    let _ = renewed.close().wait();

    // Inside: what cell c1 receives, what the recorder hears of r2's keys.
    let cell_view = zenoh::open(config_of(&client_file(&dir, "cell-c1"), &endpoint))
        .wait()
        .expect("cell c1 connects");
    let cycles = cell_view
        .declare_subscriber(keys.central_cycle())
        .with(FifoChannel::new(100_000))
        .wait()
        .unwrap();
    let recorder = zenoh::open(config_of(&client_file(&dir, "recorder"), &endpoint))
        .wait()
        .expect("recorder connects");
    let r2_odom = recorder
        .declare_subscriber(keys.robot("r2", RobotTopic::Odom).unwrap())
        .with(FifoChannel::new(100_000))
        .wait()
        .unwrap();
    // Robot r1 with its own certificate forges cycle triggers; robot r1's
    // certificate with robot r2's user and password publishes as r2.
    let robot = zenoh::open(config_of(&robot_file, &endpoint))
        .wait()
        .expect("robot r1 connects");
    let mut borrowed = config_of(&client_file(&dir, "robot-r2"), &endpoint);
    let r1_tls = dir.join("tls");
    set(
        &mut borrowed,
        "transport/link/tls/connect_certificate",
        &r1_tls.join("robot-r1.crt"),
    );
    set(
        &mut borrowed,
        "transport/link/tls/connect_private_key",
        &r1_tls.join("robot-r1.key"),
    );
    // The handshake and the password pass; no ACL subject matches the
    // pair, so every message it sends is dropped.
    let posing = zenoh::open(borrowed).wait().ok();
    const FORGED: &[u8] = b"forged by robot r1";
    let started = Instant::now();
    let mut genuine_cycles = 0;
    while started.elapsed() < Duration::from_secs(60) && genuine_cycles < 5 {
        for n in nodes.iter_mut() {
            if let Some(status) = n.exit_status() {
                panic!("{} {status}:\n{}", n.name(), n.log_tail(30));
            }
        }
        robot.put(keys.central_cycle(), FORGED).wait().unwrap();
        if let Some(posing) = &posing {
            let _ = posing
                .put(keys.robot("r2", RobotTopic::Odom).unwrap(), FORGED)
                .wait();
        }
        let got = drain(&cycles);
        assert!(
            got.iter().all(|p| p != FORGED),
            "a forged cycle trigger reached a cell"
        );
        genuine_cycles += got.len();
        assert!(
            drain(&r2_odom).is_empty(),
            "robot r1's certificate published as robot r2"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        genuine_cycles >= 5,
        "the central unit's triggers reach a cell over TLS ({genuine_cycles}):\n{}",
        nodes[0].log_tail(30)
    );
    // And r2's own credential does publish: the check above can fail.
    let r2 = zenoh::open(config_of(&client_file(&dir, "robot-r2"), &endpoint))
        .wait()
        .expect("robot r2 connects");
    let got = poll_until(Duration::from_secs(20), "robot r2's own odometry", || {
        r2.put(
            keys.robot("r2", RobotTopic::Odom).unwrap(),
            b"r2".as_slice(),
        )
        .wait()
        .unwrap();
        std::thread::sleep(Duration::from_millis(50));
        (!drain(&r2_odom).is_empty()).then_some(())
    });
    assert!(got.is_ok(), "robot r2's odometry never arrived");
    // The router said why it refused the handshakes (Zenoh's own log).
    let said = router.log();
    // Plain TCP; no certificate; another CA's (of the same name, so its
    // signature fails); an expired one.
    for why in [
        "received corrupt message",
        "peer sent no certificates",
        "invalid peer certificate: BadSignature",
        "invalid peer certificate: certificate expired",
    ] {
        assert!(said.contains(why), "{why}:\n{said}");
    }
    let _ = (
        cell_view.close().wait(),
        recorder.close().wait(),
        robot.close().wait(),
        r2.close().wait(),
    );
}

#[test]
fn ickon_sim_secure_runs_over_tls_and_every_robot_fixes() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let out = Command::new(ICKON)
        .args([
            "sim",
            "--secure",
            "--robots",
            "3",
            "--duration",
            "8",
            "--json",
        ])
        .current_dir(tmp.path())
        .output()
        .expect("ickon sim runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert_eq!(report["secure"], true);
    let endpoint = report["central_endpoint"].as_str().unwrap_or_default();
    assert!(endpoint.starts_with("tls/"), "{endpoint}");
    let robots = report["robots"].as_array().unwrap();
    assert_eq!(robots.len(), 3);
    // The TLS links hold: with Zenoh's unpatched TLS link (a data race
    // between its reader and writer) the central unit's link closed and
    // reopened several times in a few seconds.
    assert!(
        !stderr.contains("alive/central went away"),
        "the central unit's link dropped:\n{stderr}"
    );
    for robot in robots {
        let fixes = robot["fixes"].as_u64().unwrap_or(0);
        assert!(fixes >= 3, "{robot}\n{stderr}");
    }
}

/// A client file of `dir`'s `user` with its certificate and key replaced.
fn with_tls_files(dir: &Path, user: &str, cert: &Path, key: &Path, out: &Path) -> PathBuf {
    let text = std::fs::read_to_string(client_file(dir, user)).unwrap();
    let tls = dir.join("tls");
    let text = text
        .replace(
            &tls.join(format!("{user}.crt")).display().to_string(),
            &cert.display().to_string(),
        )
        .replace(
            &tls.join(format!("{user}.key")).display().to_string(),
            &key.display().to_string(),
        );
    std::fs::write(out, text).unwrap();
    out.to_path_buf()
}

#[test]
fn a_node_checks_its_certificate_and_key_at_start() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let (endpoint, _) = tls_endpoint();
    let dir = tmp.path().join("secure");
    let site = ickon_testkit::lab_site_file(tmp.path(), "lab");
    secure(&site, &dir, &endpoint);
    let ca_dir = dir.join("ca");
    let site_ca = SiteCa::load(
        &std::fs::read_to_string(ca_dir.join("ca.crt")).unwrap(),
        &std::fs::read_to_string(ca_dir.join("ca.key")).unwrap(),
    )
    .unwrap();
    let now = ickon_runtime::certificate::unix_now_s();
    let issue = |from: i64, to: i64| {
        site_ca
            .issue(
                "robot-r1",
                Role::Client,
                &[],
                Validity::from_unix(from, to).unwrap(),
            )
            .unwrap()
    };
    // The MSU agent, as a robot starts it; nothing listens at the endpoint,
    // so a node that passes its checks keeps trying to connect: it is
    // stopped after a few seconds.
    let start = |config: &Path| {
        let mut cmd = Command::new(ICKON);
        cmd.args(["node", "msu", "--robot", "r1", "--zenoh-config"])
            .arg(config)
            .args(["--connect", &endpoint]);
        cmd
    };

    let expired = issue(now - 10 * 86_400, now - 60);
    let (c, k) = write_pair(tmp.path(), "expired", &expired.cert_pem, &expired.key_pem);
    let config = with_tls_files(&dir, "robot-r1", &c, &k, &tmp.path().join("expired.json5"));
    let out = start(&config).output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(
        said.contains("expired.crt") && said.contains("expired"),
        "{said}"
    );

    let (_, good_key) = (dir.join("tls/robot-r1.crt"), dir.join("tls/robot-r1.key"));
    let garbage = tmp.path().join("garbage.crt");
    std::fs::write(&garbage, "-----BEGIN CERTIFICATE-----\nnot base64\n").unwrap();
    let config = with_tls_files(
        &dir,
        "robot-r1",
        &garbage,
        &good_key,
        &tmp.path().join("g.json5"),
    );
    let out = start(&config).output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(said.contains("garbage.crt"), "{said}");

    let bad_key = tmp.path().join("bad.key");
    std::fs::write(
        &bad_key,
        "-----BEGIN PRIVATE KEY-----\nAAAA\n-----END PRIVATE KEY-----\n",
    )
    .unwrap();
    let config = with_tls_files(
        &dir,
        "robot-r1",
        &dir.join("tls/robot-r1.crt"),
        &bad_key,
        &tmp.path().join("k.json5"),
    );
    let out = start(&config).output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(said.contains("bad.key"), "{said}");

    // Ten days left: the node starts, and warns.
    let soon = issue(now - 3600, now + 10 * 86_400 + 600);
    let (c, k) = write_pair(tmp.path(), "soon", &soon.cert_pem, &soon.key_pem);
    let config = with_tls_files(&dir, "robot-r1", &c, &k, &tmp.path().join("soon.json5"));
    let mut agent = ChildGuard::spawn("msu-soon", start(&config), tmp.path()).expect("msu");
    poll_until(Duration::from_secs(30), "the expiry warning", || {
        if let Some(status) = agent.exit_status() {
            panic!("the agent stopped ({status}):\n{}", agent.log());
        }
        agent.log().contains("expires in 10 day").then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", agent.log()));
    assert!(agent.log().contains("soon.crt"), "{}", agent.log());
}
