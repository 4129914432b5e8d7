//! `ickon emulate` and `ickon device check` as a board maker runs them: an
//! emulated board on a TCP port or a pseudo-terminal, checked through the
//! whole host side (link, framing, handshake, clock exchanges, bursts);
//! a board of the wrong kind refused by name; a noisy line survived.

use std::process::Command;
use std::time::Duration;

use ickon_testkit::{ChildGuard, poll_until};
use support::ICKON;

fn ickon() -> Command {
    Command::new(ICKON)
}

/// Starts `ickon emulate ARGS` and returns it with the address it printed.
fn emulate(dir: &std::path::Path, name: &str, args: &[&str]) -> (ChildGuard, String) {
    let mut cmd = ickon();
    cmd.arg("emulate").args(args);
    let child = ChildGuard::spawn(name, cmd, dir).unwrap();
    let address = poll_until(
        Duration::from_secs(20),
        "the emulated board's address",
        || {
            child
                .log()
                .lines()
                .find(|l| l.starts_with("tcp:") || l.starts_with("serial:"))
                .map(str::to_string)
        },
    )
    .unwrap();
    (child, address)
}

fn check(args: &[&str]) -> (i32, String) {
    let out = ickon()
        .args(["device", "check"])
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

#[test]
fn a_good_emulated_transmitter_board_passes_the_check_over_tcp() {
    let dir = tempfile::tempdir().unwrap();
    let (_board, address) = emulate(
        dir.path(),
        "tx-board",
        &[
            "transmitter-board",
            "--tx",
            "11,12,13,14",
            "--listen",
            "127.0.0.1:0",
            "--drift-ppm",
            "40",
            "--jitter-us",
            "2",
        ],
    );
    let (code, text) = check(&[&address, "--bursts", "8"]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("transmitter board v1"), "{text}");
    assert!(text.contains("transmitters: [11, 12, 13, 14]"), "{text}");
    assert!(
        text.contains("8 armed, 8 reported fired, 0 refused"),
        "{text}"
    );
    assert!(text.trim_end().ends_with("ok"), "{text}");
}

#[test]
fn a_board_on_a_pseudo_terminal_is_checked_as_a_serial_port() {
    let dir = tempfile::tempdir().unwrap();
    let (_board, address) = emulate(
        dir.path(),
        "rx-board",
        &["receiver-board", "--receivers", "6"],
    );
    assert!(address.starts_with("serial:/dev/"), "{address}");
    let (code, text) = check(&[&address, "--kind", "receiver", "--listen-s", "0.5"]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("receivers at (deg): [0.0, 60.0, 120.0, 180.0, -120.0, -60.0]"),
        "{text}"
    );
}

#[test]
fn a_receiver_board_where_a_transmitter_board_belongs_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let (_board, address) = emulate(
        dir.path(),
        "rx-board",
        &["receiver-board", "--listen", "127.0.0.1:0"],
    );
    let (code, text) = check(&[&address]);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("a receiver board answered where a transmitter board was expected"),
        "{text}"
    );
}

#[test]
fn a_noisy_line_costs_frames_and_is_reported_but_the_board_stays_usable() {
    let dir = tempfile::tempdir().unwrap();
    let (_board, address) = emulate(
        dir.path(),
        "noisy-board",
        &[
            "transmitter-board",
            "--tx",
            "11,12",
            "--listen",
            "127.0.0.1:0",
            "--garbage",
            "0.2",
            "--seed",
            "7",
        ],
    );
    let (code, text) = check(&[&address, "--bursts", "30"]);
    assert_eq!(
        code, 1,
        "the refused frames are reported as a failure: {text}"
    );
    assert!(text.contains("problem: "), "{text}");
    let fired: u32 = text
        .split(" reported fired")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        fired >= 15,
        "most bursts still fire and are reported: {text}"
    );
}

#[test]
fn bad_addresses_are_bad_input() {
    for bad in ["/dev/ttyUSB0", "tcp:host", "serial:"] {
        let (code, text) = check(&[bad]);
        assert_eq!(code, 2, "{bad}: {text}");
        assert!(
            text.contains("serial:PATH[@BAUD]") || text.contains("tcp:HOST:PORT"),
            "{text}"
        );
    }
}

#[test]
fn nobody_at_the_address_fails_with_what_the_link_saw() {
    let port = ickon_testkit::free_tcp_port().unwrap();
    let (code, text) = check(&[&format!("tcp:127.0.0.1:{port}")]);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("no handshake"), "{text}");
}
