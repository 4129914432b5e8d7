//! The reader finds its way back after whatever a line does to a stream:
//! garbage before, inside and between frames, cut frames, bad CRCs, unknown
//! types and versions, and a flood of noise; every refusal is counted and
//! the next good frame decodes.

use crate::frame::DELIMITER;
use crate::{Decoder, Encoder, Message, MessageError, ProtocolError, encode_frame};

fn clock_reply(exchange: u32) -> Message {
    Message::ClockReply {
        exchange,
        t2_board_ns: 1_000 + u64::from(exchange),
        t3_board_ns: 2_000 + u64::from(exchange),
    }
}

/// The messages decoded from `stream`, and the decoder.
fn decode_all(stream: &[u8]) -> (Vec<Message>, Decoder) {
    let mut d = Decoder::new();
    let messages = d
        .feed(stream)
        .into_iter()
        .filter_map(Result::ok)
        .map(|(_, m)| m)
        .collect();
    (messages, d)
}

#[test]
fn garbage_before_the_first_frame_costs_nothing_after_it() {
    let mut enc = Encoder::new();
    let mut stream: Vec<u8> = (1..=200u8).cycle().take(700).collect();
    stream.push(DELIMITER);
    for i in 0..3 {
        stream.extend(enc.frame(&clock_reply(i)));
    }
    let (messages, d) = decode_all(&stream);
    assert_eq!(messages, (0..3).map(clock_reply).collect::<Vec<_>>());
    assert_eq!(
        d.counters().refused,
        1,
        "the garbage is one oversized frame"
    );
}

#[test]
fn garbage_inside_a_frame_loses_that_frame_only() {
    let mut enc = Encoder::new();
    let good = enc.frame(&clock_reply(1));
    let mut hit = enc.frame(&clock_reply(2));
    hit.splice(4..4, [0x13, 0x37, 0x42]);
    let after = enc.frame(&clock_reply(3));
    let stream = [good, hit, after].concat();
    let (messages, d) = decode_all(&stream);
    assert_eq!(messages, vec![clock_reply(1), clock_reply(3)]);
    assert_eq!(d.counters().refused, 1);
    assert_eq!(
        d.counters().lost,
        1,
        "the sequence numbers show the frame lost"
    );
}

#[test]
fn a_frame_cut_short_merges_into_one_refusal_and_the_next_decodes() {
    let mut enc = Encoder::new();
    let cut = enc.frame(&clock_reply(1));
    let cut = &cut[..cut.len() / 2];
    let stream = [
        cut,
        &enc.frame(&clock_reply(2)),
        &enc.frame(&clock_reply(3)),
    ]
    .concat();
    let (messages, d) = decode_all(&stream);
    assert_eq!(messages, vec![clock_reply(3)]);
    assert_eq!(d.counters().refused, 1);
}

#[test]
fn every_way_of_cutting_the_stream_gives_the_same_messages() {
    let mut enc = Encoder::new();
    let stream: Vec<u8> = (0..4).flat_map(|i| enc.frame(&clock_reply(i))).collect();
    for cut in 0..stream.len() {
        let mut d = Decoder::new();
        let mut got = d.feed(&stream[..cut]);
        got.extend(d.feed(&stream[cut..]));
        assert_eq!(got.len(), 4, "cut at {cut}");
        assert!(got.iter().all(Result::is_ok), "cut at {cut}");
    }
}

#[test]
fn unknown_types_versions_and_lengths_are_refused_by_name() {
    let unknown_type = encode_frame(&[1, 0x7E, 0]);
    let version_two = encode_frame(&[2, 0x82, 0, 1, 2, 3]);
    let short_arm = encode_frame(&[1, 0x03, 0, 1, 2]);
    let trailing = encode_frame(&[1, 0x04, 0, 9]);
    let stream = [
        unknown_type,
        version_two,
        short_arm,
        trailing,
        encode_frame(&clock_reply(5).encode(1)),
    ]
    .concat();
    let out = Decoder::new().feed(&stream);
    let errors: Vec<_> = out
        .iter()
        .filter_map(|r| r.as_ref().err().copied())
        .collect();
    assert_eq!(
        errors,
        vec![
            ProtocolError::Message(MessageError::UnknownType(0x7E)),
            ProtocolError::Message(MessageError::UnsupportedVersion(2)),
            ProtocolError::Message(MessageError::BadLength {
                msg_type: 3,
                got: 2,
                want: 14
            }),
            ProtocolError::Message(MessageError::BadLength {
                msg_type: 4,
                got: 1,
                want: 0
            }),
        ]
    );
    assert_eq!(out.last(), Some(&Ok((1, clock_reply(5)))));
}

#[test]
fn a_flood_of_noise_keeps_memory_bounded_and_the_link_usable() {
    // 4 MB of noise from a xorshift generator, zeros included.
    let mut d = Decoder::new();
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut chunk = vec![0u8; 4096];
    for _ in 0..1024 {
        for b in chunk.iter_mut() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *b = x as u8;
        }
        // A random frame that passes a 16-bit CRC and decodes is possible
        // (about one in 65536 frames); it is a message like any other.
        d.feed(&chunk);
    }
    assert!(d.counters().refused > 10_000, "{:?}", d.counters());
    let mut tail = vec![DELIMITER];
    tail.extend(encode_frame(&clock_reply(9).encode(0)));
    assert_eq!(d.feed(&tail), vec![Ok((0, clock_reply(9)))]);
    assert_eq!(d.counters().bytes, 4 * 1024 * 1024 + tail.len() as u64);
}
