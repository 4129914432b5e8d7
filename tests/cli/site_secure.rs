//! `ickon site secure` on the command line: what it writes (private files,
//! one credential per node), that it never overwrites, and that a broken
//! ACL, dictionary or credential file is a clear message naming the file
//! and the field, with exit code 2, for `ickon router` and `ickon sim --secure DIR`.

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Output};
use support::ICKON;

fn ickon(args: &[&str], dir: &Path) -> Output {
    Command::new(ICKON)
        .args(args)
        .current_dir(dir)
        .output()
        .expect("ickon runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn writes_private_files_with_one_credential_per_node_and_never_overwrites() {
    let tmp = tempfile::tempdir().unwrap();
    let out = ickon(&["site", "secure", "--out", "s", "--sim"], tmp.path());
    assert!(out.status.success(), "{}", stderr(&out));
    let dir = tmp.path().join("s");
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&dir), 0o700);
    for f in ["router.json5", "users.txt"] {
        assert_eq!(mode(&dir.join(f)), 0o600, "{f}");
    }
    let clients: Vec<_> = std::fs::read_dir(dir.join("clients"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    // lab: central, admin, recorder, world, observer, 4 cells, 5 robots.
    assert_eq!(clients.len(), 14, "{clients:?}");
    for c in &clients {
        assert_eq!(mode(c), 0o600, "{}", c.display());
    }
    let users = std::fs::read_to_string(dir.join("users.txt")).unwrap();
    let passwords: std::collections::BTreeSet<&str> = users
        .lines()
        .map(|l| l.split_once(':').unwrap().1)
        .collect();
    assert_eq!(passwords.len(), 14, "every password differs");
    let before = std::fs::read_to_string(dir.join("users.txt")).unwrap();
    let again = ickon(&["site", "secure", "--out", "s"], tmp.path());
    assert_eq!(again.status.code(), Some(2), "{}", stderr(&again));
    assert!(stderr(&again).contains("not empty"), "{}", stderr(&again));
    assert_eq!(
        std::fs::read_to_string(dir.join("users.txt")).unwrap(),
        before
    );
}

#[test]
fn a_broken_dictionary_or_acl_stops_the_router_with_exit_code_2() {
    let tmp = tempfile::tempdir().unwrap();
    let out = ickon(&["site", "secure", "--out", "s"], tmp.path());
    assert!(out.status.success(), "{}", stderr(&out));
    let dir = tmp.path().join("s");
    let users = dir.join("users.txt");
    let good = std::fs::read_to_string(&users).unwrap();
    std::fs::write(&users, format!("{good}robot-x\n")).unwrap();
    let router = ickon(
        &[
            "router",
            "--zenoh-config",
            "s/router.json5",
            "-l",
            "tcp/127.0.0.1:0",
        ],
        tmp.path(),
    );
    assert_eq!(router.status.code(), Some(2), "{}", stderr(&router));
    let lines = good.lines().count() + 1;
    assert!(
        stderr(&router).contains(&format!("users.txt:{lines}: expected <user>:<password>")),
        "{}",
        stderr(&router)
    );
    std::fs::write(&users, &good).unwrap();

    let config = dir.join("router.json5");
    let text = std::fs::read_to_string(&config).unwrap();
    let broken = text.replacen("\"central-0\"", "\"central-zero\"", 1);
    assert_ne!(broken, text);
    std::fs::write(&config, broken).unwrap();
    let router = ickon(
        &[
            "router",
            "--zenoh-config",
            "s/router.json5",
            "-l",
            "tcp/127.0.0.1:0",
        ],
        tmp.path(),
    );
    assert_eq!(router.status.code(), Some(2), "{}", stderr(&router));
    assert!(
        stderr(&router).contains("router.json5: access_control.policies[0].rules[0]"),
        "{}",
        stderr(&router)
    );
    let misspelt = text.replacen("\"key_exprs\"", "\"keys\"", 1);
    std::fs::write(&config, misspelt).unwrap();
    let router = ickon(
        &[
            "router",
            "--zenoh-config",
            "s/router.json5",
            "-l",
            "tcp/127.0.0.1:0",
        ],
        tmp.path(),
    );
    assert_eq!(router.status.code(), Some(2), "{}", stderr(&router));
    assert!(
        stderr(&router).contains("router.json5"),
        "{}",
        stderr(&router)
    );
}

#[test]
fn sim_secure_refuses_a_credential_without_a_password_before_starting() {
    let tmp = tempfile::tempdir().unwrap();
    let out = ickon(&["site", "secure", "--out", "s", "--sim"], tmp.path());
    assert!(out.status.success(), "{}", stderr(&out));
    let cell = tmp.path().join("s/clients/cell-c2.json5");
    let text = std::fs::read_to_string(&cell).unwrap();
    let without: String = text
        .lines()
        .filter(|l| !l.contains("\"password\""))
        .map(|l| format!("{l}\n"))
        .collect::<String>()
        .replace("\"cell-c2\",", "\"cell-c2\"");
    std::fs::write(&cell, without).unwrap();
    let sim = ickon(&["sim", "--secure", "s", "--duration", "1"], tmp.path());
    assert_eq!(sim.status.code(), Some(2), "{}", stderr(&sim));
    assert!(
        stderr(&sim).contains("cell-c2.json5") && stderr(&sim).contains("password"),
        "{}",
        stderr(&sim)
    );
}
