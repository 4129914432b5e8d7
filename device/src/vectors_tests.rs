//! The test vectors of `docs/device-protocol.md` ("Test vectors"): each
//! message, its sequence number and its bytes on the wire. The CRCs were
//! checked against Python's `binascii.crc_hqx(body, 0xFFFF)`, an
//! independent implementation of CRC-16/IBM-3740.

use crate::{BoardArrival, BoardKind, Decoder, Identify, Message, RefusedReason, encode_frame};

fn bytes(hex: &str) -> Vec<u8> {
    hex.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("hex byte"))
        .collect()
}

fn vectors() -> Vec<(u8, Message, &'static str)> {
    vec![
        (
            0,
            Message::Hello {
                min_version: 1,
                max_version: 1,
            },
            "03 01 01 05 01 01 f9 ee 00",
        ),
        (
            1,
            Message::ClockRequest { exchange: 7 },
            "05 01 02 01 07 01 01 03 93 39 00",
        ),
        (
            2,
            Message::Arm {
                burst: 258,
                tx_id: 11,
                fire_at_board_ns: 5_000_000_000,
            },
            "07 01 03 02 02 01 0b 01 01 01 05 f2 05 2a 01 01 01 03 d8 eb 00",
        ),
        (3, Message::HealthRequest, "06 01 04 03 0b 07 00"),
        (
            0,
            Message::Identify(Identify {
                version: 1,
                kind: BoardKind::Transmitter,
                capabilities: 0x11,
                serial: 0x0A0B_0C0D,
                firmware: 0x0102,
                channels: vec![11, 12, 13, 14],
            }),
            "03 01 81 04 01 01 11 09 0d 0c 0b 0a 02 01 04 0b 01 01 02 0c 01 01 02 0d 01 01 02 0e 01 01 03 35 cb 00",
        ),
        (
            0,
            Message::Identify(Identify {
                version: 1,
                kind: BoardKind::Receiver,
                capabilities: 0x1E,
                serial: 42,
                firmware: 0x0100,
                channels: vec![0, 6000, 12000, 18000, -12000, -6000],
            }),
            "03 01 81 04 01 02 1e 02 2a 01 01 01 03 01 06 01 0d 70 17 e0 2e 50 46 20 d1 90 e8 91 30 00",
        ),
        (
            1,
            Message::ClockReply {
                exchange: 7,
                t2_board_ns: 1_000_000_000,
                t3_board_ns: 1_000_020_000,
            },
            "05 01 82 01 07 01 01 01 04 ca 9a 3b 01 01 01 05 20 18 9b 3b 01 01 01 03 ba ca 00",
        ),
        (
            2,
            Message::Fired {
                burst: 258,
                tx_id: 11,
                fired_board_ns: 5_000_000_250,
            },
            "07 01 83 02 02 01 0b 01 01 06 fa f2 05 2a 01 01 01 03 58 3f 00",
        ),
        (
            3,
            Message::Health {
                supply_mv: 12_050,
                temperature_cdeg_c: -525,
                faults: 0b100,
            },
            "09 01 84 03 12 2f f3 fd 04 01 01 03 8f b5 00",
        ),
        (
            4,
            Message::Refused {
                msg_type: 0x03,
                seq: 2,
                reason: RefusedReason::TooLate,
            },
            "09 01 85 04 03 02 03 97 8f 00",
        ),
        (
            5,
            Message::Arrivals {
                group: 9,
                last: true,
                arrivals: vec![
                    BoardArrival {
                        tx_id: 11,
                        receiver: 2,
                        board_ns: 5_012_345_678,
                        quality: 200,
                    },
                    BoardArrival {
                        tx_id: 12,
                        receiver: 3,
                        board_ns: 5_062_000_000,
                        quality: 90,
                    },
                ],
            },
            "05 01 86 05 09 04 01 02 0b 01 01 07 02 4e 53 c2 2a 01 01 01 03 c8 0c 01 01 07 03 80 fd b7 2d 01 01 01 04 5a fe 44 00",
        ),
        (
            6,
            Message::WheelTicks {
                board_ns: 6_000_000_000,
                left: 1234,
                right: -56,
            },
            "04 01 87 06 05 bc a0 65 01 01 01 03 d2 04 01 01 01 01 01 0b c8 ff ff ff ff ff ff ff c0 da 00",
        ),
        (
            7,
            Message::ImuSample {
                board_ns: 6_000_500_000,
                gyro_z_urad_s: -350_000,
            },
            "09 01 88 07 20 5d a8 65 01 01 01 07 d0 a8 fa ff 66 c3 00",
        ),
        (8, Message::AirTemperatureRequest, "06 01 05 08 51 85 00"),
        (
            9,
            Message::AirTemperature {
                board_ns: 7_000_000_000,
                temperature_cdeg_c: 2137,
            },
            "04 01 89 09 05 86 3b a1 01 01 01 05 59 08 7c dd 00",
        ),
        (
            10,
            Message::AirTemperature {
                board_ns: 7_000_000_000,
                temperature_cdeg_c: crate::NO_TEMPERATURE,
            },
            "04 01 89 0a 05 86 3b a1 01 01 01 01 04 80 21 01 00",
        ),
    ]
}

#[test]
fn every_message_encodes_to_the_bytes_of_the_specification() {
    for (seq, message, wire) in vectors() {
        assert_eq!(
            encode_frame(&message.encode(seq)),
            bytes(wire),
            "{message:?}"
        );
    }
}

#[test]
fn the_bytes_of_the_specification_decode_to_their_messages() {
    for (seq, message, wire) in vectors() {
        let out = Decoder::new().feed(&bytes(wire));
        assert_eq!(out, vec![Ok((seq, message))], "{wire}");
    }
}

#[test]
fn the_vectors_in_the_document_are_these() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../docs/device-protocol.md"
    ))
    .expect("docs/device-protocol.md");
    for (_, message, wire) in vectors() {
        assert!(
            doc.contains(wire),
            "{message:?}: `{wire}` is not in the specification"
        );
    }
}
