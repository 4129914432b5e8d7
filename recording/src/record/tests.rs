//! The recorder's core against bad luck: a full disk mid-recording, and the
//! reader against files cut short, damaged, or written by another tool.

use std::collections::BTreeMap;
use std::io::{Cursor, Seek, SeekFrom, Write};

use ickon_proto::keys::{Keys, RobotTopic};
use ickon_proto::msg::robot::Imu;
use ickon_proto::{Time, encode};

use super::writer::{FLUSH_EVERY, RecordError, Recorder};
use crate::replay::read::parse;

/// A file that takes `room` bytes and then fails like a full disk.
struct FullDisk {
    inner: Cursor<Vec<u8>>,
    room: usize,
}

impl Write for FullDisk {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let pos = self.inner.position() as usize;
        if pos + buf.len() > self.room {
            return Err(std::io::Error::from_raw_os_error(
                nix::errno::Errno::ENOSPC as i32,
            ));
        }
        self.inner.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for FullDisk {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

fn imu(k: i64) -> Vec<u8> {
    encode(&Imu {
        stamp: Time::from_nanos(k * 10_000_000),
        gyro_z_rad_s: 0.01 * k as f64,
    })
    .unwrap()
}

/// A finished recording of `n` gyro samples at 100 Hz (a chunk a second).
fn recording(n: i64) -> Vec<u8> {
    let keys = Keys::new("lab").unwrap();
    let key = keys.robot("r1", RobotTopic::Imu).unwrap();
    let mut r = Recorder::new(Cursor::new(Vec::new()), keys, &BTreeMap::new()).unwrap();
    for k in 0..n {
        r.record(
            &key,
            &imu(k),
            Time::from_nanos(1_000_000_000 + k * 10_000_000),
        )
        .unwrap();
    }
    let (stats, out) = r.finish().unwrap();
    assert_eq!(stats.messages, n as u64);
    out.into_inner()
}

#[test]
fn a_full_disk_is_a_clear_error_and_what_was_flushed_stays_readable() {
    let keys = Keys::new("lab").unwrap();
    let key = keys.robot("r1", RobotTopic::Imu).unwrap();
    let disk = FullDisk {
        inner: Cursor::new(Vec::new()),
        room: 6_000,
    };
    let mut r = Recorder::new(disk, keys, &BTreeMap::new()).unwrap();
    let mut failure = None;
    for k in 0..100_000 {
        if let Err(e) = r.record(&key, &imu(k), Time::from_nanos(k * 10_000_000)) {
            failure = Some(e);
            break;
        }
    }
    let e = failure.expect("the disk filled up");
    assert!(matches!(e, RecordError::Write(_)), "{e}");
    assert!(e.disk_full(), "{e}");
    assert!(super::write_failure(std::path::Path::new("x.mcap"), &e).contains("disk is full"));
    drop(r);
}

#[test]
fn a_file_cut_anywhere_keeps_every_chunk_before_the_cut() {
    let full = recording(1_000);
    let whole = parse(&full).unwrap();
    assert!(
        whole.complete && whole.problems.is_empty(),
        "{:?}",
        whole.problems
    );
    assert_eq!(whole.messages.len(), 1_000);
    // Ten seconds of samples: about ten chunks. Cutting anywhere loses at
    // most the chunk being cut (a second) and everything after.
    let mut previous = 0;
    for cut in (9..full.len()).step_by(997) {
        let part = parse(&full[..cut]).unwrap();
        // Cut inside the summary (after the data end): every message is there.
        assert!(part.complete || !part.problems.is_empty(), "cut at {cut}");
        let got = part.messages.len();
        assert!(got >= previous, "cut at {cut}: {got} < {previous}");
        previous = got;
        let lost_s = (1_000 - got) as f64 * 0.01;
        let cut_share = 1.0 - cut as f64 / full.len() as f64;
        assert!(
            lost_s <= cut_share * 10.0 + 2.0 * FLUSH_EVERY.as_secs_f64(),
            "cut at {cut}: {got} messages kept"
        );
    }
}

#[test]
fn damaged_chunks_garbage_and_foreign_files_are_reported_not_fatal() {
    let mut bytes = recording(1_000);
    assert!(parse(b"not an mcap file at all").is_none());
    assert!(parse(&[]).is_none());
    // Overwrite the middle of the data section with garbage.
    let mid = bytes.len() / 3;
    for b in &mut bytes[mid..mid + 64] {
        *b = 0xA5;
    }
    let damaged = parse(&bytes).unwrap();
    assert!(!damaged.problems.is_empty());
    assert!(damaged.messages.len() < 1_000);

    // A file of another tool: a valid MCAP whose channel is no ICKON stream.
    let mut w = mcap::Writer::new(Cursor::new(Vec::new())).unwrap();
    let schema = w
        .add_schema("std_msgs/msg/String", "ros2msg", b"string data")
        .unwrap();
    let ch = w
        .add_channel(schema, "/chatter", "cdr", &BTreeMap::new())
        .unwrap();
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 1,
            log_time: 1,
            publish_time: 1,
        },
        &[0, 1, 0, 0, 3, 0, 0, 0, b'h', b'i', 0],
    )
    .unwrap();
    w.finish().unwrap();
    let foreign = parse(&w.into_inner().into_inner()).unwrap();
    assert!(foreign.messages.is_empty());
    assert!(
        foreign.problems.iter().any(|p| p.0.contains("/chatter")),
        "{:?}",
        foreign.problems
    );
}
