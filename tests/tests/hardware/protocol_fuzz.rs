//! Random input for the Protocol 2.0 codec and the servo emulator: byte streams and mutated
//! packets never panic the decoder, and whatever garbage reached the emulated servos, once
//! the packet timeout has passed they answer a valid request correctly.
//!
//! Case counts are bounded so the file runs in a few seconds optimized.

use std::time::{Duration, Instant};

use proptest::prelude::*;
use softcbf::hardware::emulator::EmulatorSettings;
use softcbf::hardware::emulator::device::Device;
use softcbf::hardware::mapping::TendonMap;
use softcbf::integrator::Tolerances;
use softcbf::model::Model;
use softcbf::plant::Plant;
use softcbf::protocol::{
    BROADCAST_ID, Decoder, Instruction, MAX_SERVO_ID, PacketBuf, encode_instruction, encode_ping,
    encode_read, encode_status,
};
use softcbf_description::robot::Robot;

/// Model number of the example robot's servos (XM430-W350), little-endian.
const MODEL_1020: [u8; 2] = [0xFC, 0x03];

fn robot() -> Robot {
    softcbf_tests::robots::hardware_example()
}

fn model() -> &'static Model {
    softcbf_tests::robots::hardware_example_model()
}

/// Pushes `bytes` in pieces of the given sizes, draining after each; the packets and
/// rejections seen. Checks the decoder's own promises on the way.
fn decode(decoder: &mut Decoder, bytes: &[u8], pieces: &[usize]) -> Vec<Result<PacketBuf, ()>> {
    let mut seen = Vec::new();
    let mut rest = bytes;
    let mut k = 0;
    while !rest.is_empty() {
        let size = pieces
            .get(k)
            .copied()
            .unwrap_or(rest.len())
            .clamp(1, rest.len());
        k += 1;
        let mut piece = &rest[..size];
        rest = &rest[size..];
        while !piece.is_empty() {
            let n = decoder.push(piece);
            piece = &piece[n..];
            while let Some(result) = decoder.next_packet() {
                seen.push(result.map(|p| p.to_buf()).map_err(|_| ()));
            }
            assert!(n > 0 || piece.is_empty(), "a drained decoder takes bytes");
        }
    }
    for packet in seen.iter().flatten() {
        assert!(packet.id <= MAX_SERVO_ID || packet.id == BROADCAST_ID);
        if packet.instruction == Instruction::Status {
            assert!(packet.id != BROADCAST_ID && packet.error.is_some());
        } else {
            assert!(packet.error.is_none());
        }
    }
    seen
}

fn instruction() -> impl Strategy<Value = Instruction> {
    prop::sample::select(&softcbf_tests::protocol::INSTRUCTIONS[..])
}

/// A valid instruction or status packet.
fn valid_packet() -> impl Strategy<Value = Vec<u8>> {
    let params = prop::collection::vec(
        prop_oneof![3 => any::<u8>(), 1 => Just(0xFF), 1 => Just(0xFD)],
        0..40,
    );
    (
        any::<bool>(),
        0u8..=MAX_SERVO_ID,
        instruction(),
        any::<u8>(),
        params,
    )
        .prop_map(|(status, id, instruction, error, params)| {
            let mut out = Vec::new();
            if status {
                encode_status(id, error, &params, &mut out).unwrap();
            } else {
                encode_instruction(id, instruction, &params, &mut out).unwrap();
            }
            out
        })
}

/// One change to a packet.
#[derive(Clone, Debug)]
enum Mutation {
    Flip(usize, u8),
    Insert(usize, u8),
    Delete(usize),
    Length(u16),
    Truncate(usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(at, x)| Mutation::Flip(at, x)),
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Mutation::Insert(at, b)),
        any::<usize>().prop_map(Mutation::Delete),
        any::<u16>().prop_map(Mutation::Length),
        any::<usize>().prop_map(Mutation::Truncate),
    ]
}

fn mutate(packet: &mut Vec<u8>, m: &Mutation) {
    if packet.is_empty() {
        return;
    }
    let n = packet.len();
    match *m {
        Mutation::Flip(at, x) => packet[at % n] ^= x,
        Mutation::Insert(at, b) => packet.insert(at % (n + 1), b),
        Mutation::Delete(at) => {
            packet.remove(at % n);
        }
        Mutation::Length(len) if n >= 7 => packet[5..7].copy_from_slice(&len.to_le_bytes()),
        Mutation::Length(_) => {}
        Mutation::Truncate(at) => packet.truncate(at % n),
    }
}

/// Something that may be on a bus: random bytes, a header with random fields and a body
/// of any length (often an incomplete packet), a valid ping or read, or one with a byte
/// changed (a CRC error).
fn segment() -> impl Strategy<Value = Vec<u8>> {
    let id = prop_oneof![1u8..=6, Just(BROADCAST_ID), any::<u8>()];
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..80),
        (
            id.clone(),
            0u16..1200,
            prop::collection::vec(any::<u8>(), 0..80)
        )
            .prop_map(|(id, len, body)| {
                let mut v = vec![0xFF, 0xFF, 0xFD, 0x00, id];
                v.extend_from_slice(&len.to_le_bytes());
                v.extend(body);
                v
            }),
        (1u8..=6, any::<bool>(), any::<u16>(), 0usize..24, 1u8..=255).prop_map(
            |(id, ping, addr, flip_at, x)| {
                let mut v = Vec::new();
                if ping {
                    encode_ping(id, &mut v).unwrap();
                } else {
                    encode_read(id, addr % 150, 4, &mut v).unwrap();
                }
                if flip_at < v.len() {
                    v[flip_at] ^= x;
                }
                v
            }
        ),
    ]
}

fn device(baud: u32) -> (Device<'static>, Instant) {
    let mut settings = EmulatorSettings::new(baud);
    settings.settle = 0.0;
    let map = TendonMap::new(&robot()).unwrap();
    let plant = Plant::new(model(), Tolerances::default()).unwrap();
    let start = Instant::now();
    (Device::new(map, plant, &settings, start).unwrap(), start)
}

/// Status packets due by `now`, decoded.
fn replies(device: &mut Device<'_>, now: Instant) -> Vec<PacketBuf> {
    device.poll(now).unwrap();
    let mut decoder = Decoder::default();
    let mut out = Vec::new();
    while let Some(o) = device.take_due(now) {
        assert_eq!(decoder.push(&o.bytes), o.bytes.len());
        while let Some(p) = decoder.next_packet() {
            out.push(p.expect("the emulator sends valid packets").to_buf());
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic_the_decoder(
        bytes in prop::collection::vec(any::<u8>(), 0..3000),
        pieces in prop::collection::vec(1usize..600, 0..20),
        max in prop_oneof![Just(1024u16), 0u16..64],
    ) {
        decode(&mut Decoder::new(max), &bytes, &pieces);
    }

    #[test]
    fn mutated_packets_never_panic_the_decoder(
        packets in prop::collection::vec(
            (valid_packet(), prop::collection::vec(mutation(), 0..4)), 1..8),
        pieces in prop::collection::vec(1usize..64, 0..20),
    ) {
        let mut stream = Vec::new();
        let mut intact = Vec::new();
        for (packet, mutations) in &packets {
            let mut p = packet.clone();
            for m in mutations {
                mutate(&mut p, m);
            }
            if mutations.is_empty() {
                intact.push(p.clone());
            }
            stream.extend(p);
        }
        let seen = decode(&mut Decoder::default(), &stream, &pieces);
        // With nothing changed every packet comes out, in order.
        if intact.len() == packets.len() {
            prop_assert_eq!(seen.iter().filter(|r| r.is_ok()).count(), packets.len());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn after_any_garbage_and_the_packet_timeout_the_servos_answer(
        segments in prop::collection::vec(segment(), 0..12),
        pieces in prop::collection::vec((1usize..200, 0u64..300), 1..30),
        id in 1u8..=6,
        slow in any::<bool>(),
    ) {
        let baud = if slow { 57_600 } else { 1_000_000 };
        let (mut device, start) = device(baud);
        let stream: Vec<u8> = segments.concat();
        // The stream arrives in pieces, some microseconds apart.
        let mut now = start;
        let mut rest = &stream[..];
        let mut k = 0;
        while !rest.is_empty() {
            let (size, gap) = pieces[k % pieces.len()];
            k += 1;
            let size = size.min(rest.len());
            now += Duration::from_micros(gap);
            device.receive(&rest[..size], now).unwrap();
            rest = &rest[size..];
            replies(&mut device, now);
        }
        // Whatever it caused is answered or timed out within 2 s (1 200 bytes take 0.2 s
        // at 57 600 bit/s); then a ping and a read of the Model Number.
        now += Duration::from_secs(2);
        replies(&mut device, now);
        let mut ping = Vec::new();
        encode_ping(id, &mut ping).unwrap();
        device.receive(&ping, now).unwrap();
        now += Duration::from_millis(20);
        let answer = replies(&mut device, now);
        prop_assert_eq!(answer.len(), 1);
        prop_assert_eq!(answer[0].id, id);
        prop_assert_eq!(answer[0].error.unwrap().code, 0);
        prop_assert_eq!(&answer[0].params[..2], &MODEL_1020[..]);
        let mut read = Vec::new();
        encode_read(id, 0, 2, &mut read).unwrap();
        device.receive(&read, now).unwrap();
        now += Duration::from_millis(20);
        let answer = replies(&mut device, now);
        prop_assert_eq!(answer.len(), 1);
        prop_assert_eq!(answer[0].id, id);
        prop_assert_eq!(&answer[0].params[..], &MODEL_1020[..]);
    }
}
