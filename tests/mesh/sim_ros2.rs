//! `ickon sim --ros2`: the simulated robots' odometry and gyro travel as
//! ROS 2 topics (rmw_zenoh keys, attachment) and the MSU agents read them
//! there. The poses must come at the odometry rate (so the ROS 2 odometry
//! arrived and was used) and be as accurate as the mesh test without it.

use std::process::Command;
use support::ICKON;

const DURATION_S: f64 = 12.0;
/// The simulated world's odometry rate.
const ODOMETRY_HZ: f64 = 50.0;

#[test]
fn robots_on_the_ros2_path_are_accurate_and_posed_at_the_odometry_rate() {
    let out = Command::new(ICKON)
        .args(["sim", "--robots", "2", "--json", "--seed", "2", "--ros2"])
        .args(["--duration", &DURATION_S.to_string()])
        .output()
        .expect("ickon sim starts");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "ickon sim --ros2 failed:\n{stderr}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document ({e}):\n{stderr}"));
    assert_eq!(doc["ros2"], true, "{doc}");
    let robots = doc["robots"].as_array().expect("robots");
    assert_eq!(robots.len(), 2, "{doc}");
    for r in robots {
        let mean_mm = r["mean_mm"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            mean_mm < 150.0,
            "robot {}: mean {mean_mm} mm\n{doc}",
            r["id"]
        );
        let fixes = r["fixes"].as_u64().unwrap_or(0);
        let poses = r["poses"].as_u64().unwrap_or(0);
        // Without odometry a pose follows each fix only (up to about 11
        // a second on `lab` with occupancy firing); the world's odometry
        // runs at 50 Hz. Counted over all but the first 3 s (start-up).
        assert!(fixes > 0, "{doc}");
        let odometry_poses = 0.8 * ODOMETRY_HZ * (DURATION_S - 3.0);
        assert!(
            poses as f64 > odometry_poses,
            "robot {}: {poses} poses ({fixes} fixes) in {DURATION_S} s\n{doc}",
            r["id"]
        );
    }
    assert_eq!(doc["bad_messages"], 0, "{doc}");
}
