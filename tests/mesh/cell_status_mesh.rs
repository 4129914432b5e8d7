//! The MSU agent hears the cells' statuses (`cell/<id>/status`, the sync
//! sigma behind `learn_cell_sync`) over a real loopback mesh, and takes
//! only what a cell may say: a status under another cell's key (forged; on
//! a mesh without access control anyone may publish) and a status of a cell
//! not on the site are refused, each logged with its reason, while a
//! cell's own status is taken without a word.

use std::process::Command;
use std::time::Duration;

use ickon_proto::keys::Keys;
use ickon_proto::msg::control::CellStatus;
use ickon_proto::time::Time;
use ickon_testkit::{ChildGuard, Observer, poll_until};
use support::ICKON;
use zenoh::Wait;

const WAIT: Duration = Duration::from_secs(60);

fn status(cell: &str) -> Vec<u8> {
    ickon_proto::encode(&CellStatus {
        cell_id: cell.into(),
        stamp: Time::from_secs_f64(1.0),
        offset_ns: 0,
        drift_ppb: 0,
        offset_sigma_ns: 50_000,
        sync_samples: 12,
        last_cycle_fired: 0,
        cycles_fired: 0,
        slots_skipped: 0,
        faults: Vec::new(),
        inputs_refused: 0,
        device: String::new(),
    })
    .expect("encode")
}

#[test]
fn a_status_under_another_cells_key_or_of_a_foreign_cell_is_refused_by_the_live_agent() {
    let dir = tempfile::tempdir().expect("temp dir");
    let site = format!("status-{}", std::process::id());
    let file = ickon_testkit::lab_site_file(dir.path(), &site);
    let endpoint = ickon_testkit::loopback_endpoint().expect("port");
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", "central", "--no-multicast-scouting", "--listen"])
        .arg(&endpoint)
        .args(["--site-name", &site])
        .arg("--site")
        .arg(&file);
    let _central = ChildGuard::spawn("central", cmd, dir.path()).expect("central starts");
    let mut cmd = Command::new(ICKON);
    cmd.args(["node", "msu", "--robot", "r1", "--estimator", "tdoa-ekf"])
        .args(["--no-multicast-scouting", "--listen", "tcp/127.0.0.1:0"])
        .args(["--connect", &endpoint, "--site-name", &site])
        .arg("--site")
        .arg(&file)
        .env("RUST_LOG", "info,ickon_msu=debug");
    let mut msu = ChildGuard::spawn("msu", cmd, dir.path()).expect("msu starts");

    let observer = Observer::open(std::slice::from_ref(&endpoint)).expect("observer");
    let keys = Keys::new(&site).expect("keys");
    let session = observer.session();
    let put = |key: String, bytes: Vec<u8>| session.put(key, bytes).wait().expect("put");
    // Until the agent has said both: its subscriber comes up when it has
    // the site, so the statuses are put again every 100 ms.
    poll_until(WAIT, "the agent refusing both statuses", || {
        if let Some(exit) = msu.exit_status() {
            panic!("msu {exit}:\n{}", msu.log());
        }
        put(keys.cell_status("c1").unwrap(), status("c2"));
        put(keys.cell_status("zz").unwrap(), status("zz"));
        put(keys.cell_status("c1").unwrap(), status("c1"));
        std::thread::sleep(Duration::from_millis(100));
        let log = msu.log();
        (log.contains("status of cell \"c2\": heard under another cell's key")
            && log.contains("status of cell \"zz\": not a cell of this site"))
        .then_some(())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", msu.log()));
    let log = msu.log();
    assert!(!log.contains("status of cell \"c1\""), "{log}");
    assert!(msu.exit_status().is_none(), "{log}");
}
