//! Fuzz target of the hedgehog stream's decoder (run long with
//! `ICKON_FUZZ_CASES=1000000 cargo nextest run --cargo-profile fuzz -p
//! ickon-marvelmind fuzz_`): whatever bytes arrive, cut however, nothing
//! panics, the deframer holds at most one frame's bytes, every frame it
//! delivers checks, and valid frames hidden in the garbage are all found.

use crate::packet::length_fits;
use crate::{Deframer, HEADER_LEN, MAX_FRAME_LEN, Packet, crc16_modbus, encode_frame};
use proptest::prelude::*;

/// A stream: random bytes, valid frames of random codes and payloads, and
/// mutated frames, in random order, cut at random places.
fn stream() -> impl Strategy<Value = (Vec<Vec<u8>>, Vec<u8>, Vec<usize>)> {
    let piece = prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..64).prop_map(|b| (b, false)),
        (
            any::<u16>(),
            proptest::collection::vec(any::<u8>(), 0..=255)
        )
            .prop_map(|(code, payload)| {
                let fits = length_fits(code, payload.len() as u8);
                (encode_frame(code, &payload).expect("<= 255"), fits)
            }),
        (
            prop::sample::select(vec![
                1u16, 2, 3, 4, 5, 6, 7, 0x11, 0x12, 0x81, 0x83, 0x84, 0x85
            ]),
            proptest::collection::vec(any::<u8>(), 0..64),
            any::<usize>(),
            any::<u8>()
        )
            .prop_map(|(code, payload, at, flip)| {
                let mut f = encode_frame(code, &payload).expect("<= 255");
                let i = at % f.len();
                f[i] ^= flip;
                (f, false)
            }),
    ];
    (
        proptest::collection::vec(piece, 0..24),
        proptest::collection::vec(any::<usize>(), 0..8),
    )
        .prop_map(|(pieces, cuts)| {
            let valid: Vec<Vec<u8>> = pieces
                .iter()
                .filter(|(_, v)| *v)
                .map(|(b, _)| b.clone())
                .collect();
            let bytes: Vec<u8> = pieces.into_iter().flat_map(|(b, _)| b).collect();
            (valid, bytes, cuts)
        })
}

proptest! {
    #![proptest_config(ickon_proto::fuzz::config())]

    #[test]
    fn fuzz_hedgehog_stream((valid, bytes, cuts) in stream()) {
        let mut deframer = Deframer::new();
        let mut delivered = Vec::new();
        let mut rest: &[u8] = &bytes;
        for cut in cuts {
            let at = if rest.is_empty() { 0 } else { cut % rest.len() };
            let (now, later) = rest.split_at(at);
            deframer.feed(now, |f| delivered.push(f));
            rest = later;
        }
        deframer.feed(rest, |f| delivered.push(f));
        let frames: Vec<_> = delivered.into_iter().filter_map(Result::ok).collect();
        for f in &frames {
            let mut whole = vec![0xFF, 0x47, f.code as u8, (f.code >> 8) as u8, f.payload.len() as u8];
            whole.extend_from_slice(&f.payload);
            let crc = crc16_modbus(&whole).to_le_bytes();
            whole.extend_from_slice(&crc);
            prop_assert!(whole.len() <= MAX_FRAME_LEN && whole.len() > HEADER_LEN);
            // Decoding never panics; a delivered frame's length fits its code.
            let _ = Packet::decode(f);
        }
        prop_assert_eq!(deframer.stats().frames as usize, frames.len());
        prop_assert!(deframer.buffered() < MAX_FRAME_LEN);
        // Garbage can forge a frame (it only needs a matching CRC) or hide a
        // valid one behind a false length; but when the stream is only valid
        // frames, each is found exactly once.
        if valid.concat() == bytes {
            prop_assert_eq!(frames.len(), valid.len());
        }
    }
}
