//! Device links over TCP and over pseudo-terminal pairs the test creates:
//! bytes both ways, and a device that goes away and comes back (the
//! server restarts, the serial path disappears and returns) is reconnected
//! without being asked.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::link::pty::Pty;
use crate::link::{Backoff, Link, LinkAddress, LinkEvent, LinkState};

/// Every wait of these tests is bounded by this.
const WAIT: Duration = Duration::from_secs(10);

/// Quick retries: the tests wait for reconnections.
const FAST: Backoff = Backoff {
    first: Duration::from_millis(20),
    max: Duration::from_millis(200),
};

fn open(address: LinkAddress) -> (Link, mpsc::Receiver<LinkEvent>) {
    let (tx, rx) = mpsc::channel();
    let link = Link::open(address, FAST, move |e| {
        let _ = tx.send(e);
    });
    (link, rx)
}

/// Waits for an event `want` accepts, skipping others.
fn wait_for(
    rx: &mpsc::Receiver<LinkEvent>,
    what: &str,
    want: impl Fn(&LinkEvent) -> bool,
) -> LinkEvent {
    let deadline = Instant::now() + WAIT;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(e) if want(&e) => return e,
            Ok(_) => {}
            Err(_) => panic!("no {what} within {WAIT:?}"),
        }
    }
}

/// Collects `n` bytes from the link's events.
fn read_bytes(rx: &mpsc::Receiver<LinkEvent>, n: usize) -> Vec<u8> {
    let mut got = Vec::new();
    while got.len() < n {
        if let LinkEvent::Bytes(b) = wait_for(rx, "bytes", |e| matches!(e, LinkEvent::Bytes(_))) {
            got.extend(b);
        }
    }
    got
}

/// Sends until the link is up (the event may come a moment before the writer).
fn send_when_up(link: &Link, bytes: &[u8]) {
    let deadline = Instant::now() + WAIT;
    while link.send(bytes).is_err() {
        assert!(Instant::now() < deadline, "link never writable");
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn tcp_link_carries_bytes_and_reconnects_after_the_server_restarts() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let (link, rx) = open(format!("tcp:127.0.0.1:{port}").parse().unwrap());
    let (mut board, _) = listener.accept().unwrap();
    board.set_read_timeout(Some(WAIT)).unwrap();
    wait_for(&rx, "connection", |e| *e == LinkEvent::Connected);
    board.write_all(b"\x00frame\x00").unwrap();
    assert_eq!(read_bytes(&rx, 7), b"\x00frame\x00");
    send_when_up(&link, b"hello");
    let mut buf = [0u8; 5];
    board.read_exact(&mut buf).unwrap();
    assert_eq!(&buf, b"hello");

    // The board goes away: the link says so, and is back when it is.
    drop(board);
    wait_for(&rx, "disconnection", |e| {
        matches!(e, LinkEvent::Disconnected(_))
    });
    let (mut board, _) = listener.accept().unwrap();
    wait_for(&rx, "reconnection", |e| *e == LinkEvent::Connected);
    board.write_all(b"again").unwrap();
    assert_eq!(read_bytes(&rx, 5), b"again");
    let status = link.status();
    assert_eq!(status.state, LinkState::Up);
    assert_eq!(status.connects, 2);
    assert!(status.last_error.is_some());
}

#[test]
fn serial_link_over_a_pty_survives_the_path_disappearing_and_returning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("board");
    let pty = Pty::open().unwrap();
    std::os::unix::fs::symlink(pty.path(), &path).unwrap();
    let (link, rx) = open(format!("serial:{}@115200", path.display()).parse().unwrap());
    wait_for(&rx, "connection", |e| *e == LinkEvent::Connected);
    let (mut reader, mut writer) = pty.device_end(WAIT).unwrap();
    writer.write_all(&[0x03, 0x01, 0x01, 0x00]).unwrap();
    assert_eq!(read_bytes(&rx, 4), [0x03, 0x01, 0x01, 0x00]);
    send_when_up(&link, b"to the board");
    let mut buf = [0u8; 12];
    reader.read_exact(&mut buf).unwrap();
    assert_eq!(&buf, b"to the board");

    // Unplugged: the pty closes and the path goes away.
    drop((reader, writer, pty));
    std::fs::remove_file(&path).unwrap();
    wait_for(&rx, "disconnection", |e| {
        matches!(e, LinkEvent::Disconnected(_))
    });
    std::thread::sleep(Duration::from_millis(300));
    assert_ne!(link.status().state, LinkState::Up);

    // Plugged back: a new pty at the same path.
    let pty = Pty::open().unwrap();
    std::os::unix::fs::symlink(pty.path(), &path).unwrap();
    wait_for(&rx, "reconnection", |e| *e == LinkEvent::Connected);
    let (_reader, mut writer) = pty.device_end(WAIT).unwrap();
    writer.write_all(b"back").unwrap();
    assert_eq!(read_bytes(&rx, 4), b"back");
    assert_eq!(link.status().connects, 2);
}

#[test]
fn a_missing_device_is_reported_down_until_it_appears() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("later");
    let (link, rx) = open(format!("serial:{}", path.display()).parse().unwrap());
    let deadline = Instant::now() + WAIT;
    while link.status().last_error.is_none() {
        assert!(Instant::now() < deadline, "no error reported");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_ne!(link.status().state, LinkState::Up);
    assert!(link.send(b"x").is_err());
    let pty = Pty::open().unwrap();
    std::os::unix::fs::symlink(pty.path(), &path).unwrap();
    wait_for(&rx, "connection", |e| *e == LinkEvent::Connected);
}
