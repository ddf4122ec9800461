//! Tests of the Dynamixel Protocol 2.0 codec and bus client against the e-Manual's example
//! packets, an independent bitwise CRC and stuffing reference, property tests and fake ports.

use proptest::prelude::*;
use softcbf::protocol::{
    BROADCAST_ID, Bus, BusError, DecodeError, Decoder, Instruction, PacketBuf, StatusError, crc16,
    crc16_update, encode_action, encode_factory_reset, encode_instruction, encode_ping,
    encode_read, encode_reboot, encode_reg_write, encode_status, encode_sync_read,
    encode_sync_write, encode_write, parse_read, parse_sync_read, parse_sync_write, parse_write,
};
use std::collections::VecDeque;
use std::io::{self, ErrorKind, Read, Write};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::thread;
use std::time::{Duration, Instant};

// ---------------------------------------------------------------------------------------
// Example packets copied from the ROBOTIS e-Manual page "DYNAMIXEL Protocol 2.0"
// (https://emanual.robotis.com/docs/en/dxl/protocol2/, source docs/en/dxl/protocol2.md of
// ROBOTIS-GIT/emanual), section "Instruction Details"; servos are XM430-W210.
// ---------------------------------------------------------------------------------------

/// Ping, Example 1: instruction packet to ID 1.
const PING_1: &[u8] = &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];
/// Ping, Examples 1 and 2: status of ID 1 (model 1030 = 0x0406, firmware 38 = 0x26).
const PING_1_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D,
];
/// Ping, Example 2: broadcast instruction packet.
const PING_BROADCAST: &[u8] = &[0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x03, 0x00, 0x01, 0x31, 0x42];
/// Ping, Example 2: status of ID 2.
const PING_2_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x6F, 0x6D,
];
/// Read, Example: Present Position (132, 4 bytes) of ID 1.
const READ_1: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15,
];
/// Read, Example (and Sync Read, Example): status of ID 1, Present Position = 166.
const READ_1_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55, 0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C, 0xC0,
];
/// Write, Example: 512 to Goal Position (116, 4 bytes) of ID 1.
const WRITE_1: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00, 0x00, 0xCA, 0x89,
];
/// Write / Reg Write / Action / Reboot, Examples: status of ID 1 without parameters.
const ACK_1_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C,
];
/// Reg Write, Example: 200 to Goal Velocity (104, 4 bytes) of ID 1.
const REG_WRITE_1: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x04, 0x68, 0x00, 0xC8, 0x00, 0x00, 0x00, 0xAE, 0x8E,
];
/// Action, Example: ID 1.
const ACTION_1: &[u8] = &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x05, 0x02, 0xCE];
/// Factory Reset, Example: ID 1, option 0x01 (all but the ID).
const FACTORY_RESET_1: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x06, 0x01, 0xA1, 0xE6,
];
/// Reboot, Example: ID 1.
const REBOOT_1: &[u8] = &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x08, 0x2F, 0x4E];
/// Clear, Example: ID 1, multi-turn reset (P1 = 0x01, fixed 0x44 0x58 0x4C 0x22).
const CLEAR_1: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x10, 0x01, 0x44, 0x58, 0x4C, 0x22, 0xB1, 0xDC,
];
/// Sync Read, Example: Present Position (132, 4 bytes) of IDs 1 and 2.
const SYNC_READ_1_2: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82, 0x84, 0x00, 0x04, 0x00, 0x01, 0x02, 0xCE, 0xFA,
];
/// Sync Read, Example: status of ID 2, Present Position = 2079 (0x081F).
const SYNC_READ_2_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x08, 0x00, 0x55, 0x00, 0x1F, 0x08, 0x00, 0x00, 0xBA, 0xBE,
];
/// Sync Write, Example: Goal Position (116, 4 bytes) 150 to ID 1 and 170 to ID 2.
const SYNC_WRITE_1_2: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83, 0x74, 0x00, 0x04, 0x00, 0x01, 0x96, 0x00, 0x00,
    0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87,
];
/// Bulk Read, Example: Present Voltage (144, 2) of ID 1, Present Temperature (146, 1) of ID 2.
const BULK_READ_1_2: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x0D, 0x00, 0x92, 0x01, 0x90, 0x00, 0x02, 0x00, 0x02, 0x92, 0x00,
    0x01, 0x00, 0x1A, 0x05,
];
/// Bulk Read, Example: status of ID 1, voltage 119 (0x0077).
const BULK_READ_1_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x06, 0x00, 0x55, 0x00, 0x77, 0x00, 0xC3, 0x69,
];
/// Bulk Read, Example: status of ID 2, temperature 36 (0x24).
const BULK_READ_2_STATUS: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x05, 0x00, 0x55, 0x00, 0x24, 0x8B, 0xA9,
];
/// Bulk Write, Example: Max Voltage Limit (32, 2) = 160 to ID 1, Temperature Limit (31, 1)
/// = 80 to ID 2.
const BULK_WRITE_1_2: &[u8] = &[
    0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x10, 0x00, 0x93, 0x01, 0x20, 0x00, 0x02, 0x00, 0xA0, 0x00, 0x02,
    0x1F, 0x00, 0x01, 0x00, 0x50, 0xB7, 0x68,
];

/// Documented instruction packets: (bytes, id, instruction, params).
const DOC_INSTRUCTIONS: &[(&[u8], u8, Instruction, &[u8])] = &[
    (PING_1, 1, Instruction::Ping, &[]),
    (PING_BROADCAST, 0xFE, Instruction::Ping, &[]),
    (READ_1, 1, Instruction::Read, &[0x84, 0x00, 0x04, 0x00]),
    (
        WRITE_1,
        1,
        Instruction::Write,
        &[0x74, 0x00, 0x00, 0x02, 0x00, 0x00],
    ),
    (
        REG_WRITE_1,
        1,
        Instruction::RegWrite,
        &[0x68, 0x00, 0xC8, 0x00, 0x00, 0x00],
    ),
    (ACTION_1, 1, Instruction::Action, &[]),
    (FACTORY_RESET_1, 1, Instruction::FactoryReset, &[0x01]),
    (REBOOT_1, 1, Instruction::Reboot, &[]),
    (
        CLEAR_1,
        1,
        Instruction::Clear,
        &[0x01, 0x44, 0x58, 0x4C, 0x22],
    ),
    (
        SYNC_READ_1_2,
        0xFE,
        Instruction::SyncRead,
        &[0x84, 0x00, 0x04, 0x00, 0x01, 0x02],
    ),
    (
        SYNC_WRITE_1_2,
        0xFE,
        Instruction::SyncWrite,
        &[
            0x74, 0x00, 0x04, 0x00, 0x01, 0x96, 0x00, 0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00,
        ],
    ),
    (
        BULK_READ_1_2,
        0xFE,
        Instruction::BulkRead,
        &[0x01, 0x90, 0x00, 0x02, 0x00, 0x02, 0x92, 0x00, 0x01, 0x00],
    ),
    (
        BULK_WRITE_1_2,
        0xFE,
        Instruction::BulkWrite,
        &[
            0x01, 0x20, 0x00, 0x02, 0x00, 0xA0, 0x00, 0x02, 0x1F, 0x00, 0x01, 0x00, 0x50,
        ],
    ),
];

/// Documented status packets: (bytes, id, error byte, params).
const DOC_STATUSES: &[(&[u8], u8, u8, &[u8])] = &[
    (PING_1_STATUS, 1, 0, &[0x06, 0x04, 0x26]),
    (PING_2_STATUS, 2, 0, &[0x06, 0x04, 0x26]),
    (READ_1_STATUS, 1, 0, &[0xA6, 0x00, 0x00, 0x00]),
    (SYNC_READ_2_STATUS, 2, 0, &[0x1F, 0x08, 0x00, 0x00]),
    (ACK_1_STATUS, 1, 0, &[]),
    (BULK_READ_1_STATUS, 1, 0, &[0x77, 0x00]),
    (BULK_READ_2_STATUS, 2, 0, &[0x24]),
];

// ---------------------------------------------------------------------------------------
// Independent references: bitwise CRC and a straightforward stuffing/packet builder.
// ---------------------------------------------------------------------------------------

/// CRC-16/UMTS bit by bit (poly 0x8005, init 0, MSB first), independent of the table.
fn crc_bitwise(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &b in bytes {
        for i in (0..8).rev() {
            let bit = (b >> i) & 1 == 1;
            let top = crc & 0x8000 != 0;
            crc <<= 1;
            if bit != top {
                crc ^= 0x8005;
            }
        }
    }
    crc
}

/// The e-Manual's transmission rule: insert FD after each FF FF FD of `raw`.
fn stuff_reference(raw: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < raw.len() {
        if raw[i..].starts_with(&[0xFF, 0xFF, 0xFD]) {
            out.extend_from_slice(&[0xFF, 0xFF, 0xFD, 0xFD]);
            i += 3;
        } else {
            out.push(raw[i]);
            i += 1;
        }
    }
    out
}

/// A packet built by the rule: header, ID, length of the stuffed body + 2, body, CRC.
fn packet_reference(id: u8, raw_body: &[u8]) -> Vec<u8> {
    let body = stuff_reference(raw_body);
    let length = (body.len() + 2) as u16;
    let mut p = vec![0xFF, 0xFF, 0xFD, 0x00, id];
    p.extend_from_slice(&length.to_le_bytes());
    p.extend_from_slice(&body);
    let crc = crc_bitwise(&p);
    p.extend_from_slice(&crc.to_le_bytes());
    p
}

/// Every result the decoder produces for `bytes` pushed in `chunk`-sized pieces.
fn decode_all(
    decoder: &mut Decoder,
    bytes: &[u8],
    chunk: usize,
) -> Vec<Result<PacketBuf, DecodeError>> {
    let mut results = Vec::new();
    for mut piece in bytes.chunks(chunk.max(1)) {
        while !piece.is_empty() {
            let n = decoder.push(piece);
            piece = &piece[n..];
            while let Some(r) = decoder.next_packet() {
                results.push(r.map(|p| p.to_buf()));
            }
        }
    }
    results
}

fn only_packet(bytes: &[u8]) -> PacketBuf {
    let results = decode_all(&mut Decoder::default(), bytes, bytes.len());
    assert_eq!(results.len(), 1, "{results:?}");
    results.into_iter().next().unwrap().unwrap()
}

// ---------------------------------------------------------------------------------------
// CRC
// ---------------------------------------------------------------------------------------

#[test]
fn crc_of_documented_ping_is_0x4e19() {
    assert_eq!(crc16(&PING_1[..8]), 0x4E19);
}

#[test]
fn crc_catalogue_check_value() {
    // CRC-16/UMTS (= CRC-16/BUYPASS) check value from the CRC catalogue.
    assert_eq!(crc16(b"123456789"), 0xFEE8);
    assert_eq!(crc_bitwise(b"123456789"), 0xFEE8);
}

#[test]
fn crc_of_every_documented_packet_matches_its_crc_field() {
    let all = DOC_INSTRUCTIONS
        .iter()
        .map(|r| r.0)
        .chain(DOC_STATUSES.iter().map(|r| r.0));
    for packet in all {
        let n = packet.len();
        let field = u16::from_le_bytes([packet[n - 2], packet[n - 1]]);
        assert_eq!(crc16(&packet[..n - 2]), field, "{packet:02X?}");
    }
}

// ---------------------------------------------------------------------------------------
// Documented packets: encode byte for byte, decode to the documented fields
// ---------------------------------------------------------------------------------------

#[test]
fn documented_instructions_encode_byte_for_byte() {
    for &(bytes, id, instruction, params) in DOC_INSTRUCTIONS {
        let mut out = vec![0xAA]; // appends after existing content
        encode_instruction(id, instruction, params, &mut out).unwrap();
        assert_eq!(&out[1..], bytes, "{instruction:?}");
        assert_eq!(out[0], 0xAA);
    }
}

#[test]
fn documented_statuses_encode_byte_for_byte() {
    for &(bytes, id, error, params) in DOC_STATUSES {
        let mut out = Vec::new();
        encode_status(id, error, params, &mut out).unwrap();
        assert_eq!(out, bytes);
    }
}

#[test]
fn documented_packets_decode_to_their_fields() {
    for &(bytes, id, instruction, params) in DOC_INSTRUCTIONS {
        let p = only_packet(bytes);
        assert_eq!((p.id, p.instruction, p.error), (id, instruction, None));
        assert_eq!(p.params, params);
    }
    for &(bytes, id, error, params) in DOC_STATUSES {
        let p = only_packet(bytes);
        assert_eq!((p.id, p.instruction), (id, Instruction::Status));
        assert_eq!(p.error, Some(StatusError::from_byte(error)));
        assert_eq!(p.params, params);
    }
}

#[test]
fn helpers_build_the_documented_packets() {
    let cases: Vec<(Vec<u8>, &[u8])> = vec![
        (build(|o| encode_ping(1, o)), PING_1),
        (build(|o| encode_ping(BROADCAST_ID, o)), PING_BROADCAST),
        (build(|o| encode_read(1, 132, 4, o)), READ_1),
        (
            build(|o| encode_write(1, 116, &512u32.to_le_bytes(), o)),
            WRITE_1,
        ),
        (
            build(|o| encode_reg_write(1, 104, &200u32.to_le_bytes(), o)),
            REG_WRITE_1,
        ),
        (build(|o| encode_action(1, o)), ACTION_1),
        (build(|o| encode_factory_reset(1, 0x01, o)), FACTORY_RESET_1),
        (build(|o| encode_reboot(1, o)), REBOOT_1),
        (
            build(|o| encode_sync_read(132, 4, &[1, 2], o)),
            SYNC_READ_1_2,
        ),
        (
            build(|o| {
                let (a, b) = (150u32.to_le_bytes(), 170u32.to_le_bytes());
                encode_sync_write(116, 4, [(1, &a[..]), (2, &b[..])], o)
            }),
            SYNC_WRITE_1_2,
        ),
    ];
    for (got, want) in cases {
        assert_eq!(got, want);
    }
}

fn build(f: impl FnOnce(&mut Vec<u8>) -> Result<(), softcbf::protocol::EncodeError>) -> Vec<u8> {
    let mut out = Vec::new();
    f(&mut out).unwrap();
    out
}

#[test]
fn parsers_read_the_documented_parameters() {
    assert_eq!(parse_read(&only_packet(READ_1).params), Some((132, 4)));
    let write = only_packet(WRITE_1);
    assert_eq!(
        parse_write(&write.params),
        Some((116, &512u32.to_le_bytes()[..]))
    );
    let sync_read = only_packet(SYNC_READ_1_2);
    assert_eq!(
        parse_sync_read(&sync_read.params),
        Some((132, 4, &[1u8, 2][..]))
    );
    let sync_write = only_packet(SYNC_WRITE_1_2);
    let (addr, len, items) = parse_sync_write(&sync_write.params).unwrap();
    assert_eq!((addr, len), (116, 4));
    let items: Vec<(u8, u32)> = items
        .map(|(id, d)| (id, u32::from_le_bytes(d.try_into().unwrap())))
        .collect();
    assert_eq!(items, [(1, 150), (2, 170)]);
    // Malformed parameter lists are refused, not misread.
    assert_eq!(parse_read(&[0x84, 0x00, 0x04]), None);
    assert_eq!(parse_write(&[0x84]), None);
    assert_eq!(parse_sync_read(&[0x84, 0x00, 0x04]), None);
    assert!(parse_sync_write(&[0x74, 0x00, 0x04, 0x00, 0x01, 0x96]).is_none());
}

#[test]
fn status_error_meanings_follow_the_manual() {
    let table = [
        (0x01, "result fail"),
        (0x02, "instruction error"),
        (0x03, "CRC error"),
        (0x04, "data range error"),
        (0x05, "data length error"),
        (0x06, "data limit error"),
        (0x07, "access error"),
    ];
    for (code, name) in table {
        let e = StatusError::from_byte(code);
        assert!(!e.alert && !e.is_ok());
        assert!(e.to_string().contains(name), "{e}");
    }
    let alert = StatusError::from_byte(0x80);
    assert!(alert.alert && alert.is_ok());
    assert!(alert.to_string().contains("alert"));
    let both = StatusError::from_byte(0x87);
    assert_eq!((both.alert, both.code, both.to_byte()), (true, 7, 0x87));
}

// ---------------------------------------------------------------------------------------
// Byte stuffing
// ---------------------------------------------------------------------------------------

#[test]
fn stuffed_write_both_ways() {
    // WRITE FF FF FD 00 at address 0x0074 of ID 1: the data's FF FF FD gets an FD.
    let data = [0xFF, 0xFF, 0xFD, 0x00];
    let expected_prefix = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x0A, 0x00, // length 10 = 1 + 2 + 5 + 2
        0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x00,
    ];
    let mut expected = expected_prefix.to_vec();
    expected.extend_from_slice(&crc_bitwise(&expected_prefix).to_le_bytes());
    let mut out = Vec::new();
    encode_write(1, 0x0074, &data, &mut out).unwrap();
    assert_eq!(out, expected);
    let p = only_packet(&expected);
    assert_eq!(parse_write(&p.params), Some((0x0074, &data[..])));
}

#[test]
fn stuffing_across_field_boundaries_and_at_the_end() {
    // Address FF FF then data FD: the pattern spans the address and the data.
    let mut out = Vec::new();
    encode_write(3, 0xFFFF, &[0xFD], &mut out).unwrap();
    assert_eq!(out, packet_reference(3, &[0x03, 0xFF, 0xFF, 0xFD]));
    assert_eq!(&out[7..12], &[0x03, 0xFF, 0xFF, 0xFD, 0xFD]);
    // A status whose parameters end in FF FF FD, and FF FF FF FD.
    for params in [
        &[0x10, 0xFF, 0xFF, 0xFD][..],
        &[0xFF, 0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD],
    ] {
        let mut out = Vec::new();
        encode_status(7, 0, params, &mut out).unwrap();
        let mut raw = vec![0x55, 0x00];
        raw.extend_from_slice(params);
        assert_eq!(out, packet_reference(7, &raw));
        assert_eq!(only_packet(&out).params, params);
    }
}

#[test]
fn missing_stuffing_is_rejected_even_with_a_good_crc() {
    // Built by hand without the stuffing FD, CRC correct.
    let mut p = vec![
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD,
    ];
    let crc = crc_bitwise(&p);
    p.extend_from_slice(&crc.to_le_bytes());
    let results = decode_all(&mut Decoder::default(), &p, p.len());
    assert_eq!(results, [Err(DecodeError::BadStuffing { id: 1 })]);
}

// ---------------------------------------------------------------------------------------
// Decoder behaviour
// ---------------------------------------------------------------------------------------

#[test]
fn decoder_finds_packets_in_any_fragmentation_with_garbage() {
    let mut stream = vec![0x00, 0xFF, 0x13, 0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0xFF];
    stream.extend_from_slice(READ_1_STATUS);
    stream.extend_from_slice(&[0xFF, 0xFD, 0x00, 0x42]);
    stream.extend_from_slice(SYNC_READ_2_STATUS);
    stream.extend_from_slice(PING_1);
    for chunk in 1..stream.len() {
        let results = decode_all(&mut Decoder::default(), &stream, chunk);
        let ids: Vec<(u8, Instruction)> = results
            .iter()
            .map(|r| {
                let p = r.as_ref().unwrap();
                (p.id, p.instruction)
            })
            .collect();
        assert_eq!(
            ids,
            [
                (1, Instruction::Status),
                (2, Instruction::Status),
                (1, Instruction::Ping)
            ],
            "chunk {chunk}"
        );
    }
}

#[test]
fn decoder_reports_bad_crc_then_resynchronizes() {
    let mut corrupt = READ_1_STATUS.to_vec();
    corrupt[10] ^= 0x01; // a data bit flips on the wire
    let mut stream = corrupt.clone();
    stream.extend_from_slice(SYNC_READ_2_STATUS);
    let mut decoder = Decoder::default();
    let results = decode_all(&mut decoder, &stream, stream.len());
    assert!(
        matches!(results[0], Err(DecodeError::BadCrc { id: 1, .. })),
        "{results:?}"
    );
    assert_eq!(results.len(), 2);
    assert_eq!(results[1].as_ref().unwrap().id, 2);
    assert_eq!(decoder.discarded(), corrupt.len() as u64);
}

#[test]
fn decoder_survives_corrupt_length_fields() {
    // Length too large for the decoder: rejected at once, next packet found.
    let mut huge = READ_1_STATUS.to_vec();
    huge[6] = 0x7F;
    // Length slightly too large: the packet swallows the next one's start, fails its CRC,
    // and the next packet is found by the resynchronization.
    let mut longer = READ_1_STATUS.to_vec();
    longer[5] += 6;
    for (first, expect_crc) in [(huge, false), (longer, true)] {
        let mut stream = first;
        stream.extend_from_slice(PING_2_STATUS);
        let results = decode_all(&mut Decoder::new(256), &stream, 3);
        assert_eq!(results.len(), 2, "{results:?}");
        if expect_crc {
            assert!(matches!(results[0], Err(DecodeError::BadCrc { .. })));
        } else {
            assert!(matches!(
                results[0],
                Err(DecodeError::BadLength { id: 1, .. })
            ));
        }
        assert_eq!(results[1].as_ref().unwrap().params, [0x06, 0x04, 0x26]);
    }
}

#[test]
fn decoder_rejects_invalid_ids_short_status_and_unknown_instructions() {
    let cases: Vec<(Vec<u8>, DecodeError)> = vec![
        (
            packet_reference(0xFF, &[0x01]),
            DecodeError::InvalidId { id: 0xFF },
        ),
        (
            packet_reference(0xFD, &[0x01]),
            DecodeError::InvalidId { id: 0xFD },
        ),
        (
            packet_reference(BROADCAST_ID, &[0x55, 0x00]),
            DecodeError::InvalidId { id: 0xFE },
        ),
        (
            packet_reference(4, &[0x55]),
            DecodeError::BadLength { id: 4, length: 3 },
        ),
        (
            packet_reference(4, &[0x77, 0x01]),
            DecodeError::UnknownInstruction { id: 4, code: 0x77 },
        ),
    ];
    for (bytes, error) in cases {
        let mut stream = bytes.clone();
        stream.extend_from_slice(ACK_1_STATUS);
        let results = decode_all(&mut Decoder::default(), &stream, 2);
        assert_eq!(results.len(), 2, "{results:?}");
        assert_eq!(results[0], Err(error));
        assert!(results[1].is_ok());
    }
    // Length field below 3 cannot hold an instruction and a CRC.
    let mut short = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x02, 0x00, 0x01, 0x00];
    short.extend_from_slice(PING_1);
    let results = decode_all(&mut Decoder::default(), &short, short.len());
    assert_eq!(results[0], Err(DecodeError::BadLength { id: 1, length: 2 }));
    assert_eq!(results[1].as_ref().unwrap().instruction, Instruction::Ping);
}

#[test]
fn decoder_buffer_is_bounded() {
    let mut decoder = Decoder::new(64);
    let capacity = decoder.free();
    let garbage = vec![0xFFu8; 10_000];
    let mut rest = &garbage[..];
    while !rest.is_empty() {
        let n = decoder.push(rest);
        assert!(n > 0);
        rest = &rest[n..];
        assert!(decoder.pending() <= capacity);
        while decoder.next_packet().is_some() {}
        assert!(decoder.pending() < 4);
    }
    // Without draining, push refuses what does not fit.
    let mut full = Decoder::new(64);
    assert_eq!(full.push(&garbage), capacity);
    assert_eq!(full.push(&garbage), 0);
}

#[test]
fn encoder_rejects_invalid_requests_without_writing() {
    let mut out = vec![1, 2, 3];
    assert!(encode_ping(0xFD, &mut out).is_err());
    assert!(encode_status(BROADCAST_ID, 0, &[], &mut out).is_err());
    assert!(encode_sync_read(0, 4, &[1, BROADCAST_ID], &mut out).is_err());
    let d = [0u8; 3];
    assert!(encode_sync_write(0, 4, [(1, &d[..])], &mut out).is_err());
    assert!(encode_write(1, 0, &vec![0u8; 70_000], &mut out).is_err());
    assert_eq!(out, [1, 2, 3]);
}

// ---------------------------------------------------------------------------------------
// Property tests
// ---------------------------------------------------------------------------------------

/// Bytes biased toward the header and stuffing values.
fn wire_byte() -> impl Strategy<Value = u8> {
    prop_oneof![Just(0xFF), Just(0xFD), Just(0x00), Just(0x55), any::<u8>()]
}

fn instruction() -> impl Strategy<Value = Instruction> {
    prop::sample::select(&softcbf_tests::protocol::INSTRUCTIONS[..])
}

fn instruction_id() -> impl Strategy<Value = u8> {
    prop_oneof![0u8..=252, Just(BROADCAST_ID)]
}

/// Garbage: raw bytes, a bare header, or a status packet with one bit flipped.
fn garbage_segment() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        prop::collection::vec(wire_byte(), 0..40),
        Just(vec![0xFF, 0xFF, 0xFD, 0x00]),
        (
            0u8..=252,
            prop::collection::vec(wire_byte(), 0..20),
            any::<prop::sample::Index>()
        )
            .prop_map(|(id, params, at)| {
                let mut out = Vec::new();
                encode_status(id, 0, &params, &mut out).unwrap();
                let i = at.index(out.len());
                out[i] ^= 0x10;
                out
            }),
    ]
}

/// A stream segment: garbage or a good status packet.
fn segment() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        garbage_segment(),
        (
            0u8..=252,
            0u8..=255,
            prop::collection::vec(wire_byte(), 0..20)
        )
            .prop_map(|(id, err, params)| {
                let mut out = Vec::new();
                encode_status(id, err, &params, &mut out).unwrap();
                out
            }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn table_crc_equals_bitwise_crc(bytes in prop::collection::vec(any::<u8>(), 0..300), split in 0usize..300) {
        prop_assert_eq!(crc16(&bytes), crc_bitwise(&bytes));
        let k = split.min(bytes.len());
        prop_assert_eq!(crc16_update(crc16(&bytes[..k]), &bytes[k..]), crc16(&bytes));
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_packets_found_were_sent(
        segments in prop::collection::vec(segment(), 0..30),
        chunk in 1usize..64,
        max_length in 3u16..300,
    ) {
        let stream: Vec<u8> = segments.concat();
        let mut decoder = Decoder::new(max_length);
        let capacity = decoder.free();
        for r in decode_all(&mut decoder, &stream, chunk) {
            prop_assert!(decoder.pending() <= capacity);
            if let Ok(p) = r {
                // A decoded packet re-encodes to bytes present in the stream.
                let mut again = Vec::new();
                match p.error {
                    Some(e) => encode_status(p.id, e.to_byte(), &p.params, &mut again).unwrap(),
                    None => encode_instruction(p.id, p.instruction, &p.params, &mut again).unwrap(),
                }
                prop_assert!(stream.windows(again.len()).any(|w| w == again));
            }
        }
    }

    #[test]
    fn valid_packet_after_garbage_is_found(
        garbage in prop::collection::vec(garbage_segment(), 0..8),
        id in 0u8..=252,
        params in prop::collection::vec(wire_byte(), 0..40),
        chunk in 1usize..50,
    ) {
        let max_length = 128;
        let mut packet = Vec::new();
        encode_status(id, 0x80, &params, &mut packet).unwrap();
        let garbage = garbage.concat();
        let mut stream = garbage.clone();
        stream.extend_from_slice(&packet);
        // Idle-line bytes: enough to complete any false packet the garbage started.
        stream.extend(std::iter::repeat_n(0u8, usize::from(max_length) + 7));
        let results = decode_all(&mut Decoder::new(max_length), &stream, chunk);
        let oks: Vec<PacketBuf> = results.into_iter().filter_map(Result::ok).collect();
        let ours = |p: &PacketBuf| {
            p.id == id && p.params == params && p.error == Some(StatusError::from_byte(0x80))
        };
        let found = oks.iter().any(ours);
        if garbage.windows(4).any(|w| w == [0xFF, 0xFF, 0xFD, 0x00]) {
            // A false header whose CRC happens to match (chance 2^-16) may swallow the
            // packet; then that false packet must have been reported.
            prop_assert!(found || oks.iter().any(|p| !ours(p)), "{:?}", oks);
        } else {
            prop_assert!(found && oks.len() == 1, "{:?}", oks);
        }
    }

    #[test]
    fn instruction_round_trip_matches_reference(
        id in instruction_id(),
        instruction in instruction(),
        params in prop::collection::vec(wire_byte(), 0..200),
        chunk in 1usize..80,
    ) {
        let mut out = Vec::new();
        encode_instruction(id, instruction, &params, &mut out).unwrap();
        let mut raw = vec![instruction.code()];
        raw.extend_from_slice(&params);
        prop_assert_eq!(&out, &packet_reference(id, &raw));
        let results = decode_all(&mut Decoder::default(), &out, chunk);
        prop_assert_eq!(results.len(), 1);
        let p = results[0].as_ref().unwrap();
        prop_assert_eq!((p.id, p.instruction, p.error), (id, instruction, None));
        prop_assert_eq!(&p.params, &params);
    }

    #[test]
    fn status_round_trip_matches_reference(
        id in 0u8..=252,
        error in any::<u8>(),
        params in prop::collection::vec(wire_byte(), 0..200),
        chunk in 1usize..80,
    ) {
        let mut out = Vec::new();
        encode_status(id, error, &params, &mut out).unwrap();
        prop_assert_eq!(&out, &packet_reference(id, &[&[0x55, error][..], &params].concat()));
        let results = decode_all(&mut Decoder::default(), &out, chunk);
        prop_assert_eq!(results.len(), 1);
        let p = results[0].as_ref().unwrap();
        prop_assert_eq!(p.error, Some(StatusError::from_byte(error)));
        prop_assert_eq!(&p.params, &params);
    }
}

// ---------------------------------------------------------------------------------------
// Bus over a scripted fake port
// ---------------------------------------------------------------------------------------

/// One step of a scripted reply.
#[derive(Clone, Debug)]
enum Step {
    /// Bytes delivered by the next read (at most the reader's buffer).
    Bytes(Vec<u8>),
    /// Nothing readable until this long after the step is reached.
    Delay(Duration),
}

/// A serial port stand-in: each flushed request releases the next scripted reply; reads
/// with nothing available wait ≤ 1 ms and report `TimedOut`, like a serial port.
#[derive(Default)]
struct ScriptedPort {
    written: Vec<u8>,
    replies: VecDeque<Vec<Step>>,
    current: VecDeque<Step>,
    delay_until: Option<Instant>,
}

impl ScriptedPort {
    fn new(replies: Vec<Vec<Step>>) -> Self {
        Self {
            replies: replies.into(),
            ..Self::default()
        }
    }
}

impl ScriptedPort {
    fn clear_input(&mut self) {
        self.current.clear();
        self.delay_until = None;
    }
}

impl Read for ScriptedPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        loop {
            if let Some(t) = self.delay_until {
                let now = Instant::now();
                if now < t {
                    thread::sleep((t - now).min(Duration::from_millis(1)));
                    return Err(ErrorKind::TimedOut.into());
                }
                self.delay_until = None;
            }
            match self.current.pop_front() {
                None => {
                    thread::sleep(Duration::from_micros(200));
                    return Err(ErrorKind::TimedOut.into());
                }
                Some(Step::Delay(d)) => self.delay_until = Some(Instant::now() + d),
                Some(Step::Bytes(b)) => {
                    let n = b.len().min(buf.len());
                    buf[..n].copy_from_slice(&b[..n]);
                    if n < b.len() {
                        self.current.push_front(Step::Bytes(b[n..].to_vec()));
                    }
                    return Ok(n);
                }
            }
        }
    }
}

impl Write for ScriptedPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.written.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        if let Some(reply) = self.replies.pop_front() {
            self.current.extend(reply);
        }
        Ok(())
    }
}

/// `bytes` split into fragments of the given sizes (the last takes the rest).
fn fragments(bytes: &[u8], sizes: &[usize]) -> Vec<Step> {
    let mut steps = Vec::new();
    let mut rest = bytes;
    for &s in sizes {
        let s = s.min(rest.len());
        steps.push(Step::Bytes(rest[..s].to_vec()));
        rest = &rest[s..];
    }
    if !rest.is_empty() {
        steps.push(Step::Bytes(rest.to_vec()));
    }
    steps
}

const TIMEOUT: Duration = Duration::from_millis(20);

#[test]
fn bus_ping_in_fragments() {
    let port = ScriptedPort::new(vec![fragments(PING_1_STATUS, &[1, 3, 2, 5])]);
    let mut bus = Bus::new(port, TIMEOUT);
    let info = bus.ping(1).unwrap();
    assert_eq!((info.model_number, info.firmware), (1030, 38));
    assert_eq!(bus.port_mut().written, PING_1);
    let c = bus.counters();
    assert_eq!((c.transactions, c.replies, c.timeouts), (1, 1, 0));
}

#[test]
fn bus_read_skips_garbage_and_echo() {
    let mut reply = vec![Step::Bytes(vec![0x00, 0xFF, 0xFF, 0x42])];
    // Header-like garbage with an impossible ID, then with an impossible length.
    reply.push(Step::Bytes(vec![0xFF, 0xFF, 0xFD, 0x00, 0xFF, 0x00, 0x00]));
    reply.push(Step::Bytes(vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x01, 0x00]));
    reply.extend(fragments(READ_1, &[5])); // a half-duplex adapter's echo
    reply.push(Step::Delay(Duration::from_millis(2)));
    reply.extend(fragments(READ_1_STATUS, &[7, 1]));
    let mut bus = Bus::new(ScriptedPort::new(vec![reply]), TIMEOUT);
    let mut out = [0u8; 4];
    let status = bus.read(1, 132, &mut out).unwrap();
    assert_eq!(u32::from_le_bytes(out), 166);
    assert!(status.is_ok() && !status.alert);
    assert_eq!(bus.port_mut().written, READ_1);
    let c = bus.counters();
    assert_eq!((c.stray_packets, c.decode_errors), (1, 2));
    assert_eq!(c.garbage_bytes, 4 + 7 + 7);
}

#[test]
fn bus_write_sync_read_sync_write_match_the_manual() {
    let replies = vec![
        fragments(ACK_1_STATUS, &[2]),
        [
            fragments(READ_1_STATUS, &[9]),
            fragments(SYNC_READ_2_STATUS, &[1, 1]),
        ]
        .concat(),
    ];
    let mut bus = Bus::new(ScriptedPort::new(replies), TIMEOUT);
    bus.write(1, 116, &512u32.to_le_bytes()).unwrap();
    let mut out = [0u8; 8];
    bus.sync_read(132, 4, &[1, 2], &mut out).unwrap();
    assert_eq!(u32::from_le_bytes(out[..4].try_into().unwrap()), 166);
    assert_eq!(u32::from_le_bytes(out[4..].try_into().unwrap()), 2079);
    let (a, b) = (150u32.to_le_bytes(), 170u32.to_le_bytes());
    bus.sync_write(116, 4, [(1, &a[..]), (2, &b[..])]).unwrap();
    let expected = [WRITE_1, SYNC_READ_1_2, SYNC_WRITE_1_2].concat();
    assert_eq!(bus.port_mut().written, expected);
    assert_eq!(bus.counters().replies, 3);
}

#[test]
fn bus_times_out_on_late_or_incomplete_replies() {
    let replies = vec![
        [
            vec![Step::Delay(TIMEOUT * 3)],
            fragments(PING_1_STATUS, &[]),
        ]
        .concat(),
        fragments(&PING_1_STATUS[..10], &[]),
        fragments(PING_2_STATUS, &[]),
    ];
    let mut bus = Bus::new(ScriptedPort::new(replies), TIMEOUT);
    for id in [1, 1] {
        let t0 = Instant::now();
        let e = bus.ping(id).unwrap_err();
        let elapsed = t0.elapsed();
        assert!(matches!(e, BusError::Timeout { id: 1, .. }), "{e}");
        assert!(elapsed >= TIMEOUT, "{elapsed:?}");
        assert!(elapsed < TIMEOUT * 10, "{elapsed:?}");
        // What a caller does before retrying: drop whatever the port still holds (a late
        // reply would otherwise pass for the next one), as serialport's clear(Input) does.
        bus.port_mut().clear_input();
        bus.note_retry();
    }
    // The partial reply left in the decoder does not merge with the next reply.
    assert_eq!(bus.ping(2).unwrap().model_number, 1030);
    let c = bus.counters();
    assert_eq!(
        (c.timeouts, c.retries, c.replies, c.transactions),
        (2, 2, 1, 3)
    );
}

#[test]
fn bus_reports_wrong_id_bad_crc_status_errors_and_alerts() {
    let mut bad_crc = READ_1_STATUS.to_vec();
    bad_crc[9] = 0xA7;
    let mut access_error = Vec::new();
    encode_status(1, 0x07, &[], &mut access_error).unwrap();
    let mut alert = Vec::new();
    encode_status(1, 0x80, &[0xA6, 0, 0, 0], &mut alert).unwrap();
    let mut short = Vec::new();
    encode_status(1, 0, &[0xA6, 0], &mut short).unwrap();
    let replies = vec![
        fragments(SYNC_READ_2_STATUS, &[]),
        fragments(&bad_crc, &[4]),
        fragments(&access_error, &[]),
        fragments(&alert, &[]),
        fragments(&short, &[]),
    ];
    let mut bus = Bus::new(ScriptedPort::new(replies), TIMEOUT);
    let mut out = [0u8; 4];
    let e = bus.read(1, 132, &mut out).unwrap_err();
    assert!(
        matches!(
            e,
            BusError::WrongId {
                expected: 1,
                got: 2
            }
        ),
        "{e}"
    );
    let e = bus.read(1, 132, &mut out).unwrap_err();
    assert!(
        matches!(
            e,
            BusError::Corrupt {
                source: DecodeError::BadCrc { .. },
                ..
            }
        ),
        "{e}"
    );
    let e = bus.write(1, 0, &[1]).unwrap_err();
    assert!(e.to_string().contains("access error"), "{e}");
    assert_eq!(out, [0; 4], "no data from failed replies");
    let status = bus.read(1, 132, &mut out).unwrap();
    assert!(status.alert);
    assert_eq!(out, [0xA6, 0, 0, 0]);
    let e = bus.read(1, 132, &mut out).unwrap_err();
    assert!(
        matches!(
            e,
            BusError::ReplyLength {
                expected: 4,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
    let c = bus.counters();
    assert_eq!(
        (c.wrong_id, c.crc_errors, c.status_errors, c.alerts),
        (1, 1, 1, 1)
    );
    assert!(matches!(
        bus.ping(BROADCAST_ID),
        Err(BusError::NoReplyId { .. })
    ));
    let mut small = [0u8; 3];
    assert!(matches!(
        bus.sync_read(0, 4, &[1], &mut small),
        Err(BusError::BufferSize { .. })
    ));
}

// ---------------------------------------------------------------------------------------
// Bus against a servo emulator thread built on the same codec (emulator side)
// ---------------------------------------------------------------------------------------

/// One end of an in-memory full-duplex byte pipe.
struct PipeEnd {
    tx: Sender<Vec<u8>>,
    rx: Receiver<Vec<u8>>,
    leftover: VecDeque<u8>,
}

fn pipe() -> (PipeEnd, PipeEnd) {
    let (a_tx, b_rx) = channel();
    let (b_tx, a_rx) = channel();
    let end = |tx, rx| PipeEnd {
        tx,
        rx,
        leftover: VecDeque::new(),
    };
    (end(a_tx, a_rx), end(b_tx, b_rx))
}

impl Read for PipeEnd {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.leftover.is_empty() {
            match self.rx.recv_timeout(Duration::from_millis(1)) {
                Ok(bytes) => self.leftover.extend(bytes),
                Err(RecvTimeoutError::Timeout) => return Err(ErrorKind::TimedOut.into()),
                Err(RecvTimeoutError::Disconnected) => return Ok(0),
            }
        }
        let n = buf.len().min(self.leftover.len());
        for (slot, b) in buf.iter_mut().zip(self.leftover.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

impl Write for PipeEnd {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        // Deliver in 3-byte pieces to exercise reassembly on the other side.
        for piece in buf.chunks(3) {
            self.tx
                .send(piece.to_vec())
                .map_err(|_| io::Error::from(ErrorKind::BrokenPipe))?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Servos 1..=3 with a 256-byte control table each; model 1030, firmware 38. Answers
/// until the controller hangs up; returns the number of instruction packets handled.
fn emulate_servos(mut port: PipeEnd) -> usize {
    let ids = [1u8, 2, 3];
    let mut tables = [[0u8; 256]; 3];
    let mut decoder = Decoder::default();
    let mut reply = Vec::new();
    let mut request = PacketBuf::default();
    let mut handled = 0;
    let mut buf = [0u8; 64];
    loop {
        let n = match port.read(&mut buf) {
            Ok(0) => return handled,
            Ok(n) => n,
            Err(_) => continue,
        };
        let mut rest = &buf[..n];
        while !rest.is_empty() {
            let k = decoder.push(rest);
            rest = &rest[k..];
            while let Some(result) = decoder.next_packet() {
                let Ok(packet) = result else { continue };
                request.copy_from(&packet);
                handled += 1;
                reply.clear();
                let p = &request.params;
                let slot = ids.iter().position(|&i| i == request.id);
                match (request.instruction, slot) {
                    (Instruction::Ping, Some(_)) => {
                        encode_status(request.id, 0, &[0x06, 0x04, 0x26], &mut reply).unwrap();
                    }
                    (Instruction::Read, Some(s)) => {
                        let (addr, len) = parse_read(p).unwrap();
                        let range = usize::from(addr)..usize::from(addr) + usize::from(len);
                        encode_status(request.id, 0, &tables[s][range], &mut reply).unwrap();
                    }
                    (Instruction::Write, Some(s)) => {
                        let (addr, data) = parse_write(p).unwrap();
                        let a = usize::from(addr);
                        tables[s][a..a + data.len()].copy_from_slice(data);
                        encode_status(request.id, 0, &[], &mut reply).unwrap();
                    }
                    (Instruction::SyncWrite, _) => {
                        let (addr, len, items) = parse_sync_write(p).unwrap();
                        let a = usize::from(addr);
                        for (id, data) in items {
                            if let Some(s) = ids.iter().position(|&i| i == id) {
                                tables[s][a..a + usize::from(len)].copy_from_slice(data);
                            }
                        }
                    }
                    (Instruction::SyncRead, _) => {
                        let (addr, len, wanted) = parse_sync_read(p).unwrap();
                        let range = usize::from(addr)..usize::from(addr) + usize::from(len);
                        for &id in wanted {
                            if let Some(s) = ids.iter().position(|&i| i == id) {
                                encode_status(id, 0, &tables[s][range.clone()], &mut reply)
                                    .unwrap();
                            }
                        }
                    }
                    (_, Some(_)) => {
                        let error = StatusError::INSTRUCTION_ERROR;
                        encode_status(request.id, error, &[], &mut reply).unwrap();
                    }
                    (_, None) => {}
                }
                if !reply.is_empty() && port.write_all(&reply).is_err() {
                    return handled;
                }
            }
        }
    }
}

#[test]
fn bus_against_emulated_servos() {
    let (controller, servos) = pipe();
    let emulator = thread::spawn(move || emulate_servos(servos));
    let mut bus = Bus::new(controller, Duration::from_millis(500));
    let ids = [1u8, 2, 3];
    for &id in &ids {
        assert_eq!(bus.ping(id).unwrap().model_number, 1030);
    }
    // Goal values chosen to contain FF FF FD so that stuffing runs both ways.
    let goals: [[u8; 4]; 3] = [
        [0xFF, 0xFF, 0xFD, 0x00],
        [0x10, 0xFF, 0xFF, 0xFD],
        [1, 2, 3, 4],
    ];
    bus.sync_write(116, 4, ids.iter().zip(&goals).map(|(&id, g)| (id, &g[..])))
        .unwrap();
    let mut out = [0u8; 12];
    bus.sync_read(116, 4, &ids, &mut out).unwrap();
    assert_eq!(out, goals.concat()[..]);
    bus.write(2, 10, &[0xFF, 0xFF, 0xFD]).unwrap();
    let mut back = [0u8; 5];
    bus.read(2, 9, &mut back).unwrap();
    assert_eq!(back, [0x00, 0xFF, 0xFF, 0xFD, 0x00]);
    let e = bus.reboot(3).unwrap_err();
    assert!(
        matches!(e, BusError::Status { id: 3, error } if error.code == 2),
        "{e}"
    );
    bus.set_timeout(Duration::from_millis(20));
    assert!(matches!(bus.ping(9), Err(BusError::Timeout { id: 9, .. })));
    let c = bus.counters();
    assert_eq!(
        (c.transactions, c.replies, c.timeouts, c.crc_errors),
        (9, 8, 1, 0)
    );
    drop(bus);
    assert_eq!(emulator.join().unwrap(), 9);
}
