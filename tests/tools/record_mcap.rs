//! Recordings end to end: `ickon sim --record` for 15 s, every message of
//! the file decoded by the PyPI packages `mcap` and `mcap-ros2-support`
//! (counts per channel equal to what the sim reported), the replay
//! reproducing the live agents' poses bit for bit, `--estimator all`
//! printing `ickon eval`'s table, and a recorder killed with SIGKILL leaving
//! a file readable up to its last seconds.
//!
//! The Python checks need the interpreter of the virtual environment that
//! `.ci/run` makes (`ICKON_PYTHON`, else `target/venv/bin/python`); without
//! it the check is skipped with a note, except when `ICKON_PYTHON` names
//! an environment that is missing, which is a failure.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant, SystemTime};
use support::ICKON;

/// Mesh duration once every node is live, seconds.
const DURATION_S: &str = "15";

fn ickon() -> Command {
    Command::new(ICKON)
}

fn json(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not one JSON document ({e}):\n{}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// The venv's Python, or `None` (skip, said in one line). A Python named
/// by `ICKON_PYTHON` must be there: `.ci/run` names the one it makes.
fn python() -> Option<PathBuf> {
    let named = std::env::var_os("ICKON_PYTHON").filter(|v| !v.is_empty());
    let candidate = named
        .clone()
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/venv/bin/python"));
    if candidate.exists() {
        return Some(candidate);
    }
    assert!(
        named.is_none(),
        "ICKON_PYTHON names {}, which is missing (.ci/run makes the environment with mcap and mcap-ros2-support)",
        candidate.display()
    );
    eprintln!(
        "skipped: {} missing: the independent Python decoding is skipped (run .ci/run once to make the venv)",
        candidate.display()
    );
    None
}

/// What `tests/py/decode_mcap.py` makes of `file` (it fails the test when
/// a message does not decode).
fn decoded_in_python(py: &Path, file: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/py/decode_mcap.py");
    let out = Command::new(py)
        .arg(script)
        .arg(file)
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "Python decoding failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    json(&out)
}

/// `ickon replay mcap --json` of `file`, which must succeed.
fn replayed(file: &Path) -> serde_json::Value {
    let out = ickon()
        .args(["replay", "mcap", "--json"])
        .arg(file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "replay failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    json(&out)
}

#[test]
fn a_recorded_sim_decodes_in_python_and_replays_the_live_poses_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    let out = ickon()
        .args(["sim", "--robots", "2", "--json", "--duration", DURATION_S])
        .arg("--record")
        .arg(&file)
        .output()
        .expect("ickon sim starts");
    assert!(
        out.status.success(),
        "ickon sim failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sim = json(&out);
    let recorded = &sim["recorded"];
    let per_topic = recorded["per_topic"].as_object().expect("per-topic counts");
    assert_eq!(recorded["undecodable"], 0, "{recorded}");
    // Every stream of the site is in the file.
    for r in ["r1", "r2"] {
        for t in ["ultrasound", "odom", "imu", "range", "fix", "pose"] {
            let topic = format!("/ickon/lab/robot/{r}/{t}");
            assert!(
                per_topic.get(&topic).and_then(|v| v.as_u64()).unwrap_or(0) > 0,
                "{topic} missing: {recorded}"
            );
        }
        assert!(per_topic.contains_key(&format!("/ickon/lab/sim/truth/{r}")));
    }
    for t in [
        "central/site",
        "central/schedule",
        "central/cycle",
        "cell/c1/burst",
        "cell/c1/status",
    ] {
        assert!(
            per_topic.contains_key(&format!("/ickon/lab/{t}")),
            "{t}: {recorded}"
        );
    }
    // The recorder saw what the launcher's observer saw (both sessions of
    // the launcher; the observer joins a moment later, so at most a few more).
    for r in sim["robots"].as_array().unwrap() {
        let id = r["id"].as_str().unwrap();
        let poses = per_topic[&format!("/ickon/lab/robot/{id}/pose")]
            .as_u64()
            .unwrap();
        let observed = r["poses"].as_u64().unwrap();
        assert!(
            poses >= observed && poses <= observed + 100,
            "{id}: recorded {poses}, observed {observed}"
        );
    }

    if let Some(py) = python() {
        let py = decoded_in_python(&py, &file);
        assert_eq!(py["profile"], "ros2");
        assert_eq!(
            &py["per_topic"], &recorded["per_topic"],
            "counts per channel"
        );
        assert_eq!(py["statistics_messages"], recorded["messages"]);
        assert_eq!(py["compression"], serde_json::json!(["zstd"]));
        assert!(
            py["chunks"].as_u64().unwrap() >= 10,
            "a chunk per second: {py}"
        );
        assert_eq!(
            py["schemas"]["/ickon/lab/robot/r1/pose"],
            "geometry_msgs/msg/PoseWithCovarianceStamped"
        );
        assert_eq!(
            py["schemas"]["/ickon/lab/robot/r1/fix"],
            "ickon_msgs/msg/Fix"
        );
        // One serialization format: rosbag2 opens no other file.
        assert_eq!(py["message_encodings"], serde_json::json!(["cdr"]));
    }

    // The replay with the estimator that ran live reproduces every live pose.
    let replay = replayed(&file);
    assert_eq!(replay["problems"], serde_json::json!([]));
    for r in replay["robots"].as_array().unwrap() {
        let live = &r["live"];
        assert!(live["live_poses"].as_u64().unwrap() > 500, "{live}");
        assert_eq!(live["identical"], live["live_poses"], "{}: {live}", r["id"]);
        assert_eq!(live["reproduced"], true);
    }
    // Twice the same.
    let again = ickon()
        .args(["replay", "mcap", "--json"])
        .arg(&file)
        .output()
        .unwrap();
    let mut a = replay.clone();
    let mut b = json(&again);
    a["wall_s"] = 0.into();
    b["wall_s"] = 0.into();
    assert_eq!(a, b, "two replays differ");

    // Every estimator, scored like `ickon eval`, and the new poses written out.
    let poses = dir.path().join("replayed.mcap");
    let out = ickon()
        .args(["replay", "mcap", "--estimator", "all"])
        .arg(&file)
        .arg("--out")
        .arg(&poses)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("tour  mean_mm   std_mm  <30mm  <60mm  <100mm  rmse_mm"),
        "{text}"
    );
    for name in [
        "odometry",
        "msu-raw",
        "ickon-akf",
        "gyro-ckf",
        "cda",
        "cda-msu",
        "tdoa-ekf",
    ] {
        assert!(text.contains(&format!("{name} on r1")), "{name}: {text}");
    }
    assert!(std::fs::metadata(&poses).unwrap().len() > 10_000);

    // A copy cut in the middle: a clear message, exit 2, the first part replayed.
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = ickon()
        .args(["replay", "mcap", "--json"])
        .arg(&cut)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let doc = json(&out);
    assert!(doc["problems"].to_string().contains("ends early"), "{doc}");
    assert!(doc["messages"].as_u64().unwrap() > 1000, "{doc}");
}

/// `--record-foxglove-view`: the live Foxglove server's channels in the
/// file, decoded in Python with Foxglove's own schemas, and a replay that
/// leaves them aside.
#[test]
fn a_recording_with_the_foxglove_view_holds_the_live_channels_and_still_replays() {
    let Some(py) = python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("view.mcap");
    let out = ickon()
        .args(["sim", "--robots", "2", "--json", "--duration", "8"])
        .arg("--record")
        .arg(&file)
        .arg("--record-foxglove-view")
        .output()
        .expect("ickon sim starts");
    assert!(
        out.status.success(),
        "ickon sim failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let recorded = json(&out)["recorded"].clone();
    let py = decoded_in_python(&py, &file);
    assert_eq!(
        &py["per_topic"], &recorded["per_topic"],
        "counts per channel"
    );
    // The Foxglove view, as the live server shows it, in Foxglove's
    // own schemas and marked as the view.
    let view = &py["view"];
    for (topic, schema) in [
        ("/site/scene", "foxglove.SceneUpdate"),
        ("/site/cells", "foxglove.SceneUpdate"),
        ("/robots/scene", "foxglove.SceneUpdate"),
        ("/tf", "foxglove.FrameTransforms"),
        ("/robot/r1/pose", "foxglove.PoseInFrame"),
        ("/robot/r1/truth", "foxglove.PoseInFrame"),
        ("/cell/c1/sync", "ickon.CellSync"),
    ] {
        assert_eq!(py["schemas"][topic], schema, "{topic}: {py}");
        assert_eq!(view["metadata"][topic], "foxglove", "{topic}");
    }
    assert!(
        view["scene_entities"]
            .as_array()
            .is_some_and(|e| e.iter().any(|x| x == "walls")),
        "{view}"
    );
    let (site, _, _) = ickon_proto::site::Site::load_or_default(None).expect("lab site");
    let cells: Vec<String> = site
        .cells
        .iter()
        .map(|c| format!("cell/{}", c.id))
        .collect();
    assert_eq!(view["cell_entities"], serde_json::json!(cells), "{view}");
    assert_eq!(
        view["tf_children"],
        serde_json::json!(["r1", "r2"]),
        "{view}"
    );
    assert!(
        recorded["view_messages"].as_u64().unwrap_or(0) > 100,
        "{recorded}"
    );

    let replay = replayed(&file);
    assert_eq!(replay["problems"], serde_json::json!([]));
    for r in replay["robots"].as_array().unwrap() {
        assert_eq!(r["live"]["reproduced"], true, "{r}");
    }
}

#[test]
fn a_recorder_killed_with_sigkill_leaves_its_file_readable_to_its_last_seconds() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("killed.mcap");
    let mut child = ickon()
        .args(["sim", "--robots", "1", "--duration", "120", "--json"])
        .arg("--record")
        .arg(&file)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Until the site has run for a few seconds (the file grows by a chunk a second).
    let deadline = Instant::now() + Duration::from_secs(90);
    while std::fs::metadata(&file).map_or(0, |m| m.len()) < 150_000 {
        assert!(Instant::now() < deadline, "the recording never grew");
        assert!(child.try_wait().unwrap().is_none(), "ickon sim ended early");
        std::thread::sleep(Duration::from_millis(200));
    }
    let killed_at = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i64;
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();

    let out = ickon()
        .args(["replay", "mcap", "--json"])
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "an unfinished file is reported");
    let doc = json(&out);
    assert_eq!(doc["complete"], false);
    let problems = doc["problems"].to_string();
    assert!(problems.contains("killed"), "{problems}");
    assert!(doc["messages"].as_u64().unwrap() > 1000, "{doc}");
    // The readable part reaches to within a few seconds of the kill (one
    // chunk a second; receive times are the system clock).
    let last = doc["last_log_time_ns"].as_i64().unwrap();
    let lag_s = (killed_at - last) as f64 * 1e-9;
    assert!(
        (0.0..3.0).contains(&lag_s),
        "the file ends {lag_s:.2} s before the kill"
    );
    let r1 = &doc["robots"][0];
    assert!(r1["live"]["live_poses"].as_u64().unwrap() > 0, "{doc}");
}
