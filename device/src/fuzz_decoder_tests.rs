//! Fuzz targets of the device protocol's decoder (see `ickon_proto::fuzz`:
//! `ICKON_FUZZ_CASES=1000000 cargo nextest run --cargo-profile fuzz -p
//! ickon-device fuzz_`): random streams, and streams of valid frames
//! mutated. Decoding never panics, never holds more than a frame, and
//! every message it accepts encodes back to the body it came from.

use crate::frame::{MAX_ENCODED, cobs_decode, encode_frame};
use crate::message::MAX_ARRIVALS_PER_FRAME;
use crate::{BoardArrival, BoardKind, Decoder, Identify, Message, RefusedReason};
use ickon_proto::fuzz::config;
use ickon_proto::fuzz::mutate::{apply, mutations};
use proptest::prelude::*;

/// Any message, with valid field values.
fn message() -> impl Strategy<Value = Message> {
    let arrival = (any::<u32>(), any::<u8>(), any::<u64>(), any::<u8>()).prop_map(
        |(tx_id, receiver, board_ns, quality)| BoardArrival {
            tx_id,
            receiver,
            board_ns,
            quality,
        },
    );
    let identify = (
        any::<bool>(),
        any::<u16>(),
        any::<u32>(),
        any::<u16>(),
        proptest::collection::vec(any::<i16>(), 0..8),
    )
        .prop_map(|(tx, capabilities, serial, firmware, ch)| {
            let kind = if tx {
                BoardKind::Transmitter
            } else {
                BoardKind::Receiver
            };
            let channels = ch
                .into_iter()
                .map(|c| {
                    if tx {
                        i64::from(c as u16)
                    } else {
                        i64::from(c)
                    }
                })
                .collect();
            Message::Identify(Identify {
                version: 1,
                kind,
                capabilities,
                serial,
                firmware,
                channels,
            })
        });
    prop_oneof![
        (any::<u8>(), any::<u8>()).prop_map(|(min_version, max_version)| Message::Hello {
            min_version,
            max_version
        }),
        any::<u32>().prop_map(|exchange| Message::ClockRequest { exchange }),
        (any::<u16>(), any::<u32>(), any::<u64>()).prop_map(|(burst, tx_id, fire_at_board_ns)| {
            Message::Arm {
                burst,
                tx_id,
                fire_at_board_ns,
            }
        }),
        Just(Message::HealthRequest),
        Just(Message::AirTemperatureRequest),
        (any::<u64>(), any::<i16>()).prop_map(|(board_ns, temperature_cdeg_c)| {
            Message::AirTemperature {
                board_ns,
                temperature_cdeg_c,
            }
        }),
        identify,
        (any::<u32>(), any::<u64>(), any::<u64>()).prop_map(
            |(exchange, t2_board_ns, t3_board_ns)| Message::ClockReply {
                exchange,
                t2_board_ns,
                t3_board_ns
            }
        ),
        (any::<u16>(), any::<u32>(), any::<u64>()).prop_map(|(burst, tx_id, fired_board_ns)| {
            Message::Fired {
                burst,
                tx_id,
                fired_board_ns,
            }
        }),
        (any::<u16>(), any::<i16>(), any::<u32>()).prop_map(
            |(supply_mv, temperature_cdeg_c, faults)| Message::Health {
                supply_mv,
                temperature_cdeg_c,
                faults
            }
        ),
        (any::<u8>(), any::<u8>(), any::<u8>()).prop_map(|(msg_type, seq, r)| Message::Refused {
            msg_type,
            seq,
            reason: match r {
                1 => RefusedReason::UnknownType,
                2 => RefusedReason::BadLength,
                3 => RefusedReason::TooLate,
                4 => RefusedReason::UnknownTransmitter,
                5 => RefusedReason::Busy,
                6 => RefusedReason::UnsupportedVersion,
                b => RefusedReason::Other(b),
            }
        }),
        (
            any::<u16>(),
            any::<bool>(),
            proptest::collection::vec(arrival, 0..=MAX_ARRIVALS_PER_FRAME)
        )
            .prop_map(|(group, last, arrivals)| Message::Arrivals {
                group,
                last,
                arrivals
            }),
        (any::<u64>(), any::<i64>(), any::<i64>()).prop_map(|(board_ns, left, right)| {
            Message::WheelTicks {
                board_ns,
                left,
                right,
            }
        }),
        (any::<u64>(), any::<i32>()).prop_map(|(board_ns, gyro_z_urad_s)| Message::ImuSample {
            board_ns,
            gyro_z_urad_s
        }),
    ]
}

/// A stream: random bytes, or valid frames around a mutated one.
fn stream() -> impl Strategy<Value = Vec<u8>> {
    let random = proptest::collection::vec(any::<u8>(), 0..1024);
    let mutated = (
        proptest::collection::vec(message(), 1..4),
        mutations(),
        any::<u8>(),
    )
        .prop_map(|(messages, m, seq)| {
            let mut out = Vec::new();
            for (i, msg) in messages.iter().enumerate() {
                let mut frame = encode_frame(&msg.encode(seq.wrapping_add(i as u8)));
                if i == 0 {
                    apply(&mut frame, &m);
                }
                out.extend(frame);
            }
            out
        });
    let body = (message(), mutations()).prop_map(|(msg, m)| {
        // A mutated body with a correct CRC: the message decoder's own checks.
        let mut body = msg.encode(0);
        apply(&mut body, &m);
        encode_frame(&body)
    });
    prop_oneof![1 => random, 2 => mutated, 2 => body]
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn fuzz_device_stream(bytes in stream(), cut in any::<usize>()) {
        let mut d = Decoder::new();
        let cut = cut % (bytes.len() + 1);
        let mut out = d.feed(&bytes[..cut]);
        out.extend(d.feed(&bytes[cut..]));
        for (seq, message) in out.into_iter().flatten() {
            // Accepted: it encodes to a body that decodes to itself.
            let body = message.encode(seq);
            prop_assert_eq!(Message::decode(&body), Ok((seq, message)));
        }
        let c = d.counters();
        prop_assert_eq!(c.bytes, bytes.len() as u64);
    }

    #[test]
    fn fuzz_device_round_trip(msg in message(), seq in any::<u8>()) {
        let frame = encode_frame(&msg.encode(seq));
        prop_assert!(frame.len() <= MAX_ENCODED + 1);
        prop_assert_eq!(Decoder::new().feed(&frame), vec![Ok((seq, msg))]);
    }

    #[test]
    fn fuzz_cobs_decode(bytes in proptest::collection::vec(1u8.., 0..600)) {
        // Encodings of one input differ only in a final 0xFF run's
        // optional code byte; whatever decodes survives encoding again.
        if let Ok(raw) = cobs_decode(&bytes) {
            let again = crate::frame::cobs_encode(&raw);
            prop_assert!(!again.contains(&0));
            prop_assert_eq!(cobs_decode(&again), Ok(raw));
        }
    }
}
