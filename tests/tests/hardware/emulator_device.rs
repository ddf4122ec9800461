//! The emulated servos against the ROBOTIS e-Manual, case by case: packet timeout, the
//! X-series control table's ranges and access rules, every Protocol 2.0 instruction, Status
//! Return Level, CRC errors, the Bus Watchdog, Ctrl-C and settings.
//!
//! Most tests drive the emulator's I/O-free core ([`Device`]) with times of their own, so
//! nothing sleeps and nothing depends on the machine's speed. Expected values are the
//! e-Manual's (XM430-W350 control table; "Protocol 2.0": error numbers, instruction
//! formats and example packets), written out here rather than taken from the code.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::thread;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use softcbf::hardware::emulator::device::Device;
use softcbf::hardware::emulator::{
    self, EmulatorError, EmulatorLog, EmulatorSettings, Faults, ReplyFate,
};
use softcbf::hardware::mapping::TendonMap;
use softcbf::integrator::Tolerances;
use softcbf::model::Model;
use softcbf::plant::Plant;
use softcbf::protocol::{
    BROADCAST_ID, Decoder, Instruction, PacketBuf, crc16, encode_ping, encode_read, encode_write,
};
use softcbf_description::robot::Robot;

// Error numbers of a status packet (e-Manual, Protocol 2.0, "Status Packet", Error).
const INSTRUCTION_ERROR: u8 = 0x02;
const CRC_ERROR: u8 = 0x03;
const DATA_RANGE_ERROR: u8 = 0x04;
const DATA_LENGTH_ERROR: u8 = 0x05;
const DATA_LIMIT_ERROR: u8 = 0x06;
const ACCESS_ERROR: u8 = 0x07;

// XM430-W350 control table (e-Manual): addresses.
const MODEL_NUMBER: u16 = 0;
const ID: u16 = 7;
const BAUD_RATE: u16 = 8;
const RETURN_DELAY_TIME: u16 = 9;
const DRIVE_MODE: u16 = 10;
const OPERATING_MODE: u16 = 11;
const PROTOCOL_TYPE: u16 = 13;
const HOMING_OFFSET: u16 = 20;
const MOVING_THRESHOLD: u16 = 24;
const TEMPERATURE_LIMIT: u16 = 31;
const MAX_VOLTAGE_LIMIT: u16 = 32;
const MIN_VOLTAGE_LIMIT: u16 = 34;
const PWM_LIMIT: u16 = 36;
const CURRENT_LIMIT: u16 = 38;
const ACCELERATION_LIMIT: u16 = 40;
const VELOCITY_LIMIT: u16 = 44;
const MAX_POSITION_LIMIT: u16 = 48;
const MIN_POSITION_LIMIT: u16 = 52;
const SHUTDOWN: u16 = 63;
const TORQUE_ENABLE: u16 = 64;
const LED: u16 = 65;
const STATUS_RETURN_LEVEL: u16 = 68;
const REGISTERED_INSTRUCTION: u16 = 69;
const VELOCITY_I_GAIN: u16 = 76;
const POSITION_P_GAIN: u16 = 84;
const FEEDFORWARD_1ST_GAIN: u16 = 90;
const BUS_WATCHDOG: u16 = 98;
const GOAL_PWM: u16 = 100;
const GOAL_CURRENT: u16 = 102;
const GOAL_VELOCITY: u16 = 104;
const PROFILE_ACCELERATION: u16 = 108;
const PROFILE_VELOCITY: u16 = 112;
const GOAL_POSITION: u16 = 116;
const PRESENT_CURRENT: u16 = 126;
const PRESENT_POSITION: u16 = 132;
const PRESENT_INPUT_VOLTAGE: u16 = 144;
const PRESENT_TEMPERATURE: u16 = 146;

/// The status packet of ID 1 with no error and no parameters, as the e-Manual prints it
/// (Write, Reg Write, Action, Factory Reset, Reboot and Clear examples).
const DOCUMENTED_ACK_ID1: [u8; 11] = [
    0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C,
];

/// The servos of the example robot: IDs 1–6, model 1020 (XM430-W350), 1 Mbit/s.
const IDS: [u8; 6] = [1, 2, 3, 4, 5, 6];
const BAUD: u32 = 1_000_000;

fn robot() -> Robot {
    softcbf_tests::robots::hardware_example()
}

fn model() -> &'static Model {
    softcbf_tests::robots::hardware_example_model()
}

/// The emulated bus, driven with a clock of the test's own.
struct Bench {
    device: Device<'static>,
    now: Instant,
}

impl Bench {
    fn new() -> Bench {
        Bench::with(EmulatorSettings::new(BAUD))
    }

    fn with(settings: EmulatorSettings) -> Bench {
        let map = TendonMap::new(&robot()).unwrap();
        let mut plant = Plant::new(model(), Tolerances::default()).unwrap();
        plant.advance(settings.settle).unwrap();
        let now = Instant::now();
        let device = Device::new(map, plant, &settings, now).unwrap();
        Bench { device, now }
    }

    /// Lets `span` pass; the status packets sent meanwhile, decoded.
    fn wait(&mut self, span: Duration) -> Vec<PacketBuf> {
        self.now += span;
        self.device.poll(self.now).unwrap();
        let mut decoder = Decoder::default();
        let mut replies = Vec::new();
        while let Some(out) = self.device.take_due(self.now) {
            assert_eq!(decoder.push(&out.bytes), out.bytes.len());
            while let Some(packet) = decoder.next_packet() {
                let packet = packet.expect("the emulator sends valid packets");
                assert_eq!(packet.instruction, Instruction::Status);
                replies.push(packet.to_buf());
            }
        }
        replies
    }

    /// Sends `bytes` now and waits 5 ms (the longest exchange here takes under 2 ms at
    /// 1 Mbit/s); the status packets sent.
    fn send(&mut self, bytes: &[u8]) -> Vec<PacketBuf> {
        self.device.receive(bytes, self.now).unwrap();
        self.wait(Duration::from_millis(5))
    }

    /// Sends `bytes` and returns the raw bytes of the status packets sent.
    fn send_raw(&mut self, bytes: &[u8]) -> Vec<Vec<u8>> {
        self.device.receive(bytes, self.now).unwrap();
        self.now += Duration::from_millis(5);
        self.device.poll(self.now).unwrap();
        let mut out = Vec::new();
        while let Some(o) = self.device.take_due(self.now) {
            out.push(o.bytes);
        }
        out
    }

    /// The one status packet `id` sends to `bytes`.
    fn one(&mut self, id: u8, bytes: &[u8]) -> PacketBuf {
        let replies = self.send(bytes);
        assert_eq!(replies.len(), 1, "one status packet expected: {replies:?}");
        assert_eq!(replies[0].id, id);
        replies.into_iter().next().unwrap()
    }

    /// The error number of the status packet answering a write of `data` at `addr`.
    fn write(&mut self, id: u8, addr: u16, data: &[u8]) -> u8 {
        self.one(id, &packet(|o| encode_write(id, addr, data, o)))
            .error
            .unwrap()
            .code
    }

    /// `len` bytes at `addr` of servo `id`, which must answer without error.
    fn read(&mut self, id: u8, addr: u16, len: u16) -> Vec<u8> {
        let reply = self.one(id, &packet(|o| encode_read(id, addr, len, o)));
        assert_eq!(reply.error.unwrap().code, 0, "read {len} at {addr}");
        reply.params
    }

    /// The error number answering a read.
    fn read_error(&mut self, id: u8, addr: u16, len: u16) -> u8 {
        let reply = self.one(id, &packet(|o| encode_read(id, addr, len, o)));
        reply.error.unwrap().code
    }

    fn read_i64(&mut self, id: u8, addr: u16, len: u16) -> i64 {
        let bytes = self.read(id, addr, len);
        let mut raw = [0u8; 8];
        raw[..bytes.len()].copy_from_slice(&bytes);
        let v = i64::from_le_bytes(raw);
        let bits = 8 * u32::from(len);
        (v << (64 - bits)) >> (64 - bits)
    }
}

fn packet(
    encode: impl FnOnce(&mut Vec<u8>) -> Result<(), softcbf::protocol::EncodeError>,
) -> Vec<u8> {
    let mut out = Vec::new();
    encode(&mut out).unwrap();
    out
}

/// A packet with any instruction byte (also undefined ones), length and CRC filled in.
fn raw_packet(id: u8, instruction: u8, params: &[u8]) -> Vec<u8> {
    let mut p = vec![0xFF, 0xFF, 0xFD, 0x00, id];
    p.extend_from_slice(&(params.len() as u16 + 3).to_le_bytes());
    p.push(instruction);
    p.extend_from_slice(params);
    let crc = crc16(&p);
    p.extend_from_slice(&crc.to_le_bytes());
    p
}

fn le(value: i64, size: usize) -> Vec<u8> {
    value.to_le_bytes()[..size].to_vec()
}

// ---------------------------------------------------------------------------------------
// 1. Packet timeout

#[test]
fn an_incomplete_packet_is_dropped_after_the_packet_timeout() {
    let mut bus = Bench::new();
    let ping = packet(|o| encode_ping(1, o));
    // A header announcing 1024 more bytes (the decoder's largest), then nothing.
    let stale = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x00, 0x04];
    assert!(bus.send(&stale).is_empty());
    // A ping 1 ms later is taken for part of that packet's body, as on a real bus...
    assert!(
        bus.send(&ping).is_empty(),
        "swallowed by the incomplete packet"
    );
    // ... but once the whole announced packet could have arrived (1031 bytes take 10.3 ms
    // at 1 Mbit/s) and more, the servo listens again.
    bus.wait(Duration::from_millis(500));
    let reply = bus.one(1, &ping);
    assert_eq!(reply.params[..2], [0xFC, 0x03], "model number 1020");
    assert_eq!(bus.device.log().stale_packets, 1);
}

#[test]
fn a_slow_bus_waits_for_the_wire_time_of_the_announced_packet() {
    // At 9600 bit/s the 1031 announced bytes take 1.07 s to send: a ping 0.5 s after the
    // header still belongs to that packet; 3 s after it, it is answered.
    let mut bus = Bench::with(EmulatorSettings::new(9600));
    let ping = packet(|o| encode_ping(2, o));
    bus.device
        .receive(&[0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x00, 0x04], bus.now)
        .unwrap();
    bus.wait(Duration::from_millis(500));
    assert!(bus.send(&ping).is_empty());
    bus.wait(Duration::from_millis(2500));
    bus.device.receive(&ping, bus.now).unwrap();
    // 10 + 14 bytes at 9600 bit/s: 25 ms on the wire.
    let replies = bus.wait(Duration::from_millis(50));
    assert_eq!(replies.len(), 1);
    assert_eq!(replies[0].id, 2);
}

#[test]
fn bytes_before_a_header_do_not_delay_a_complete_request() {
    let mut bus = Bench::new();
    let mut bytes = vec![0x00, 0xFF, 0x13, 0xFF, 0xFF];
    bytes.extend(packet(|o| encode_ping(3, o)));
    let replies = bus.send(&bytes);
    assert_eq!(replies.len(), 1);
    assert_eq!(replies[0].id, 3);
    assert_eq!(bus.device.log().stale_packets, 0);
}

// ---------------------------------------------------------------------------------------
// 2. Ranges of the writable items

/// One writable item: address, size, values the e-Manual allows, values it does not
/// (each refused with a Data Range Error), and the value to leave behind.
struct Case {
    addr: u16,
    size: usize,
    good: &'static [i64],
    bad: &'static [i64],
    keep: i64,
}

const fn case(
    addr: u16,
    size: usize,
    good: &'static [i64],
    bad: &'static [i64],
    keep: i64,
) -> Case {
    Case {
        addr,
        size,
        good,
        bad,
        keep,
    }
}

/// EEPROM items (written with torque off). ID and Baud Rate keep servo 1 on the bus, so
/// only their current values are written as good ones; Protocol Type likewise.
const EEPROM_CASES: &[Case] = &[
    case(ID, 1, &[1], &[253, 254, 255], 1),
    case(BAUD_RATE, 1, &[3], &[8, 9, 255], 3),
    case(RETURN_DELAY_TIME, 1, &[254, 0], &[255], 0),
    case(DRIVE_MODE, 1, &[0, 1, 4, 8, 13], &[2, 16, 0x80, 0xFF], 0),
    case(
        OPERATING_MODE,
        1,
        &[0, 1, 4, 5, 16, 3],
        &[2, 6, 7, 15, 17, 255],
        3,
    ),
    case(PROTOCOL_TYPE, 1, &[2], &[0, 3, 255], 2),
    case(
        HOMING_OFFSET,
        4,
        &[-1_044_479, 1_044_479, 0],
        &[-1_044_480, 1_044_480, i32::MIN as i64],
        0,
    ),
    case(
        MOVING_THRESHOLD,
        4,
        &[0, 1023, 10],
        &[1024, 0xFFFF_FFFF],
        10,
    ),
    case(TEMPERATURE_LIMIT, 1, &[0, 100, 80], &[101, 255], 80),
    case(MAX_VOLTAGE_LIMIT, 2, &[95, 160], &[94, 161], 160),
    case(MIN_VOLTAGE_LIMIT, 2, &[95, 160], &[94, 161], 95),
    case(PWM_LIMIT, 2, &[0, 885], &[886, 0xFFFF], 885),
    case(CURRENT_LIMIT, 2, &[0, 1193], &[1194, 0xFFFF], 1193),
    case(ACCELERATION_LIMIT, 4, &[0, 32767], &[32768], 32767),
    case(VELOCITY_LIMIT, 4, &[0, 1023, 350], &[1024], 350),
    case(
        MAX_POSITION_LIMIT,
        4,
        &[0, 4095],
        &[4096, 0xFFFF_FFFF],
        4095,
    ),
    case(MIN_POSITION_LIMIT, 4, &[4095, 0], &[4096, 0xFFFF_FFFF], 0),
    case(SHUTDOWN, 1, &[0, 0x01, 0x3D, 52], &[0x02, 0x40, 0x80], 52),
];

/// RAM items.
const RAM_CASES: &[Case] = &[
    case(TORQUE_ENABLE, 1, &[1, 0], &[2, 255], 0),
    case(LED, 1, &[1, 0], &[2, 255], 0),
    case(STATUS_RETURN_LEVEL, 1, &[2], &[3, 255], 2),
    case(
        VELOCITY_I_GAIN,
        2,
        &[0, 16383, 1920],
        &[16384, 0xFFFF],
        1920,
    ),
    case(POSITION_P_GAIN, 2, &[0, 16383, 800], &[16384], 800),
    case(FEEDFORWARD_1ST_GAIN, 2, &[16383, 0], &[16384], 0),
    case(BUS_WATCHDOG, 1, &[127, 1, 0], &[128, 0xFF], 0),
    case(PROFILE_ACCELERATION, 4, &[32767, 0], &[32768], 0),
    case(PROFILE_VELOCITY, 4, &[32767, 0], &[32768], 0),
];

fn check_cases(bus: &mut Bench, cases: &[Case]) {
    for c in cases {
        for &v in c.good {
            assert_eq!(bus.write(1, c.addr, &le(v, c.size)), 0, "{} ← {v}", c.addr);
            assert_eq!(bus.read(1, c.addr, c.size as u16), le(v, c.size));
        }
        let before = bus.read(1, c.addr, c.size as u16);
        for &v in c.bad {
            assert_eq!(
                bus.write(1, c.addr, &le(v, c.size)),
                DATA_RANGE_ERROR,
                "{} ← {v}",
                c.addr
            );
            assert_eq!(bus.read(1, c.addr, c.size as u16), before, "not applied");
        }
        assert_eq!(bus.write(1, c.addr, &le(c.keep, c.size)), 0);
    }
}

#[test]
fn eeprom_items_take_their_documented_ranges_only() {
    let mut bus = Bench::new();
    check_cases(&mut bus, EEPROM_CASES);
}

#[test]
fn ram_items_take_their_documented_ranges_only() {
    let mut bus = Bench::new();
    check_cases(&mut bus, RAM_CASES);
}

#[test]
fn goal_values_beyond_their_limits_are_data_limit_errors() {
    let mut bus = Bench::new();
    // Goal PWM within ± PWM Limit (885), Goal Current within ± Current Limit (1193), Goal
    // Velocity within ± Velocity Limit (350), in any operating mode.
    for (addr, size, limit) in [
        (GOAL_PWM, 2, 885),
        (GOAL_CURRENT, 2, 1193),
        (GOAL_VELOCITY, 4, 350),
    ] {
        for v in [limit, -limit, 0] {
            assert_eq!(bus.write(1, addr, &le(v, size)), 0, "{addr} ← {v}");
        }
        for v in [limit + 1, -limit - 1] {
            assert_eq!(
                bus.write(1, addr, &le(v, size)),
                DATA_LIMIT_ERROR,
                "{addr} ← {v}"
            );
        }
    }
    // A lower limit lowers the bound.
    assert_eq!(bus.write(1, CURRENT_LIMIT, &le(500, 2)), 0);
    assert_eq!(bus.write(1, GOAL_CURRENT, &le(501, 2)), DATA_LIMIT_ERROR);
    assert_eq!(bus.write(1, GOAL_CURRENT, &le(-500, 2)), 0);
    // Goal Position: between the position limits in Position Control Mode (3, the
    // factory mode), ±256 turns (±1 048 575) in Extended Position Control Mode (4).
    assert_eq!(bus.write(1, GOAL_POSITION, &le(4095, 4)), 0);
    assert_eq!(bus.write(1, GOAL_POSITION, &le(4096, 4)), DATA_LIMIT_ERROR);
    assert_eq!(bus.write(1, GOAL_POSITION, &le(-1, 4)), DATA_LIMIT_ERROR);
    assert_eq!(bus.write(1, MAX_POSITION_LIMIT, &le(3000, 4)), 0);
    assert_eq!(bus.write(1, GOAL_POSITION, &le(3001, 4)), DATA_LIMIT_ERROR);
    assert_eq!(bus.write(1, OPERATING_MODE, &[4]), 0);
    for v in [1_048_575, -1_048_575, 3001] {
        assert_eq!(bus.write(1, GOAL_POSITION, &le(v, 4)), 0, "{v}");
    }
    for v in [1_048_576, -1_048_576] {
        assert_eq!(
            bus.write(1, GOAL_POSITION, &le(v, 4)),
            DATA_RANGE_ERROR,
            "{v}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// 3. Lengths and access

#[test]
fn partial_empty_undefined_read_only_and_locked_writes_are_refused() {
    let mut bus = Bench::new();
    // Part of a multi-byte item: Data Length Error (e-Manual: data shorter than the item).
    assert_eq!(bus.write(1, GOAL_CURRENT, &[5]), DATA_LENGTH_ERROR);
    assert_eq!(bus.write(1, GOAL_CURRENT, &[5, 0, 0]), DATA_LENGTH_ERROR);
    assert_eq!(bus.write(1, GOAL_CURRENT + 1, &[0, 0]), DATA_LENGTH_ERROR);
    assert_eq!(bus.write(1, GOAL_POSITION, &[1, 0]), DATA_LENGTH_ERROR);
    // No data at all.
    let empty = raw_packet(1, 0x03, &GOAL_CURRENT.to_le_bytes());
    assert_eq!(bus.one(1, &empty).error.unwrap().code, DATA_LENGTH_ERROR);
    assert_eq!(bus.read(1, GOAL_CURRENT, 2), [0, 0], "nothing written");
    // Read-only and undefined addresses: Access Error.
    assert_eq!(bus.write(1, MODEL_NUMBER, &le(1, 2)), ACCESS_ERROR);
    assert_eq!(bus.write(1, PRESENT_POSITION, &[0; 4]), ACCESS_ERROR);
    assert_eq!(bus.write(1, PRESENT_CURRENT, &[0; 2]), ACCESS_ERROR);
    assert_eq!(bus.write(1, REGISTERED_INSTRUCTION, &[1]), ACCESS_ERROR);
    assert_eq!(
        bus.write(1, 99, &[0]),
        ACCESS_ERROR,
        "between Bus Watchdog and Goal PWM"
    );
    assert_eq!(bus.write(1, 14, &[0]), ACCESS_ERROR, "after Protocol Type");
    assert_eq!(
        bus.write(1, TORQUE_ENABLE, &[0, 0, 0, 0]),
        ACCESS_ERROR,
        "66 and 67 undefined"
    );
    // Two whole items at once are fine.
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[0, 1]), 0);
    assert_eq!(bus.read(1, LED, 1), [1]);
    // EEPROM while torque is on: Access Error; RAM still writable.
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[1]), 0);
    assert_eq!(bus.write(1, OPERATING_MODE, &[0]), ACCESS_ERROR);
    assert_eq!(bus.write(1, RETURN_DELAY_TIME, &[10]), ACCESS_ERROR);
    assert_eq!(bus.write(1, ID, &[9]), ACCESS_ERROR);
    assert_eq!(bus.write(1, LED, &[0]), 0);
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[0]), 0);
    assert_eq!(bus.write(1, RETURN_DELAY_TIME, &[10]), 0);
    // Reads: the whole modelled table at once; past its end an Access Error.
    let all = bus.read(1, 0, 147);
    assert_eq!(all.len(), 147);
    assert_eq!(all[..2], [0xFC, 0x03]);
    assert_eq!(all[usize::from(ID)], 1);
    assert_eq!(all[usize::from(RETURN_DELAY_TIME)], 10);
    assert_eq!(bus.read_error(1, 200, 4), ACCESS_ERROR);
    assert_eq!(bus.read_error(1, 146, 2), ACCESS_ERROR);
    assert_eq!(
        bus.read_error(1, 99, 1),
        ACCESS_ERROR,
        "an undefined address"
    );
}

// ---------------------------------------------------------------------------------------
// 4. Every instruction, Status Return Level, broadcast

#[test]
fn ping_answers_model_and_firmware_and_a_broadcast_ping_every_servo() {
    let mut bus = Bench::new();
    // The e-Manual's ping of ID 1.
    let ping1 = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];
    let reply = bus.one(1, &ping1);
    assert_eq!(reply.error.unwrap().code, 0);
    assert_eq!(reply.params.len(), 3);
    assert_eq!(reply.params[..2], [0xFC, 0x03], "model number 1020");
    assert!(
        reply.params[2] >= 42,
        "firmware with Bus Watchdog and Clear"
    );
    // The e-Manual's broadcast ping: every servo answers, one after the other.
    let all = [0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x03, 0x00, 0x01, 0x31, 0x42];
    let replies = bus.send(&all);
    let ids: Vec<u8> = replies.iter().map(|r| r.id).collect();
    assert_eq!(ids, IDS);
    // An absent ID: nothing.
    assert!(bus.send(&packet(|o| encode_ping(9, o))).is_empty());
}

#[test]
fn read_and_write_answer_as_the_documented_examples() {
    let mut bus = Bench::new();
    // Write 512 to Goal Position of ID 1.
    let write = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00, 0x00, 0xCA,
        0x89,
    ];
    assert_eq!(bus.send_raw(&write), [DOCUMENTED_ACK_ID1.to_vec()]);
    assert_eq!(bus.read_i64(1, GOAL_POSITION, 4), 512);
    // Read Present Position of ID 1: four bytes.
    let read = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15,
    ];
    let reply = bus.one(1, &read);
    assert_eq!(reply.error.unwrap().code, 0);
    assert_eq!(reply.params.len(), 4);
}

#[test]
fn reg_write_waits_for_action_and_action_alone_is_an_instruction_error() {
    let mut bus = Bench::new();
    // Reg Write 200 to Goal Velocity of ID 1.
    let reg_write = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x04, 0x68, 0x00, 0xC8, 0x00, 0x00, 0x00, 0xAE,
        0x8E,
    ];
    let action = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x05, 0x02, 0xCE];
    assert_eq!(bus.send_raw(&reg_write), [DOCUMENTED_ACK_ID1.to_vec()]);
    assert_eq!(bus.read(1, REGISTERED_INSTRUCTION, 1), [1]);
    assert_eq!(bus.read_i64(1, GOAL_VELOCITY, 4), 0, "not before Action");
    assert_eq!(bus.send_raw(&action), [DOCUMENTED_ACK_ID1.to_vec()]);
    assert_eq!(bus.read_i64(1, GOAL_VELOCITY, 4), 200);
    assert_eq!(bus.read(1, REGISTERED_INSTRUCTION, 1), [0]);
    // Action without a registered write.
    assert_eq!(bus.one(1, &action).error.unwrap().code, INSTRUCTION_ERROR);
    // A broadcast Action runs every registered write and answers nothing.
    for id in [2, 3] {
        let reg = packet(|o| softcbf::protocol::encode_reg_write(id, LED, &[1], o));
        assert_eq!(bus.one(id, &reg).error.unwrap().code, 0);
    }
    assert!(
        bus.send(&packet(|o| softcbf::protocol::encode_action(
            BROADCAST_ID,
            o
        )))
        .is_empty()
    );
    assert_eq!(bus.read(2, LED, 1), [1]);
    assert_eq!(bus.read(3, LED, 1), [1]);
    assert_eq!(bus.read(4, LED, 1), [0]);
}

#[test]
fn factory_reset_restores_the_factory_table() {
    let mut bus = Bench::new();
    // Option 0x02 keeps ID and Baud Rate: the servo stays on this bus.
    assert_eq!(bus.write(2, OPERATING_MODE, &[0]), 0);
    assert_eq!(bus.write(2, STATUS_RETURN_LEVEL, &[2]), 0);
    let reset = packet(|o| softcbf::protocol::encode_factory_reset(2, 0x02, o));
    assert_eq!(bus.one(2, &reset).error.unwrap().code, 0);
    assert_eq!(
        bus.read(2, OPERATING_MODE, 1),
        [3],
        "factory: position control"
    );
    assert_eq!(bus.read(2, RETURN_DELAY_TIME, 1), [250], "factory: 500 µs");
    assert_eq!(bus.read(2, BAUD_RATE, 1), [3], "kept");
    // The e-Manual's example: option 0x01 (all but the ID) on ID 1. The answer comes
    // first; then the Baud Rate is the factory's 57 600 bit/s (1), off this 1 Mbit/s bus.
    let example = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x06, 0x01, 0xA1, 0xE6,
    ];
    assert_eq!(bus.send_raw(&example), [DOCUMENTED_ACK_ID1.to_vec()]);
    assert!(bus.send(&packet(|o| encode_ping(1, o))).is_empty());
    // Sent to the broadcast ID with option 0xFF it does nothing (firmware 42 and later).
    assert_eq!(bus.write(3, RETURN_DELAY_TIME, &[0]), 0);
    let everything = packet(|o| softcbf::protocol::encode_factory_reset(BROADCAST_ID, 0xFF, o));
    assert!(bus.send(&everything).is_empty());
    assert_eq!(bus.read(3, RETURN_DELAY_TIME, 1), [0]);
    assert_eq!(bus.read(3, ID, 1), [3]);
}

#[test]
fn reboot_answers_then_turns_torque_off() {
    let mut bus = Bench::new();
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[1]), 0);
    assert_eq!(bus.write(1, LED, &[1]), 0);
    let reboot = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x08, 0x2F, 0x4E];
    assert_eq!(bus.send_raw(&reboot), [DOCUMENTED_ACK_ID1.to_vec()]);
    assert_eq!(bus.read(1, TORQUE_ENABLE, 1), [0]);
    assert_eq!(bus.read(1, LED, 1), [0], "RAM back to its initial values");
}

#[test]
fn clear_answers_and_brings_the_position_within_one_turn() {
    let mut bus = Bench::new();
    // Shift Present Position by two turns (Homing Offset), then Clear.
    assert_eq!(bus.write(1, HOMING_OFFSET, &le(8192, 4)), 0);
    assert!(bus.read_i64(1, PRESENT_POSITION, 4) >= 8192);
    let clear = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x10, 0x01, 0x44, 0x58, 0x4C, 0x22, 0xB1, 0xDC,
    ];
    assert_eq!(bus.send_raw(&clear), [DOCUMENTED_ACK_ID1.to_vec()]);
    let position = bus.read_i64(1, PRESENT_POSITION, 4);
    assert!((0..4096).contains(&position), "{position}");
    // Anything but option 0x01 with its fixed bytes is refused.
    let wrong = raw_packet(1, 0x10, &[0x01, 0x44, 0x58, 0x4C, 0x23]);
    assert_ne!(bus.one(1, &wrong).error.unwrap().code, 0);
}

#[test]
fn sync_read_and_sync_write_follow_the_documented_examples() {
    let mut bus = Bench::new();
    // Sync Write 150 and 170 to Goal Position of IDs 1 and 2: no status packet.
    let sync_write = [
        0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83, 0x74, 0x00, 0x04, 0x00, 0x01, 0x96, 0x00,
        0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87,
    ];
    assert!(bus.send(&sync_write).is_empty());
    assert_eq!(bus.read_i64(1, GOAL_POSITION, 4), 150);
    assert_eq!(bus.read_i64(2, GOAL_POSITION, 4), 170);
    // Sync Read Present Position of IDs 1 and 2: one status packet each, in that order.
    let sync_read = [
        0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82, 0x84, 0x00, 0x04, 0x00, 0x01, 0x02, 0xCE,
        0xFA,
    ];
    let replies = bus.send(&sync_read);
    assert_eq!(replies.iter().map(|r| r.id).collect::<Vec<_>>(), [1, 2]);
    assert!(
        replies
            .iter()
            .all(|r| r.params.len() == 4 && r.error.unwrap().code == 0)
    );
}

#[test]
fn bulk_read_and_bulk_write_follow_the_documented_examples() {
    let mut bus = Bench::new();
    assert_eq!(bus.write(1, MAX_VOLTAGE_LIMIT, &le(150, 2)), 0);
    assert_eq!(bus.write(2, TEMPERATURE_LIMIT, &[70]), 0);
    // Bulk Write: Max Voltage Limit 160 to ID 1, Temperature Limit 80 to ID 2.
    let bulk_write = [
        0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x10, 0x00, 0x93, 0x01, 0x20, 0x00, 0x02, 0x00, 0xA0, 0x00,
        0x02, 0x1F, 0x00, 0x01, 0x00, 0x50, 0xB7, 0x68,
    ];
    assert!(bus.send(&bulk_write).is_empty());
    assert_eq!(bus.read_i64(1, MAX_VOLTAGE_LIMIT, 2), 160);
    assert_eq!(bus.read(2, TEMPERATURE_LIMIT, 1), [80]);
    // Bulk Read: Present Input Voltage (2 bytes) of ID 1, Present Temperature (1 byte) of
    // ID 2.
    let bulk_read = [
        0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x0D, 0x00, 0x92, 0x01, 0x90, 0x00, 0x02, 0x00, 0x02, 0x92,
        0x00, 0x01, 0x00, 0x1A, 0x05,
    ];
    let replies = bus.send(&bulk_read);
    assert_eq!(replies.len(), 2);
    assert_eq!((replies[0].id, replies[0].params.len()), (1, 2));
    assert_eq!((replies[1].id, replies[1].params.len()), (2, 1));
    assert_eq!(bus.read(1, PRESENT_INPUT_VOLTAGE, 2), replies[0].params);
    assert_eq!(bus.read(2, PRESENT_TEMPERATURE, 1), replies[1].params);
}

#[test]
fn an_undefined_instruction_to_a_servo_is_an_instruction_error() {
    let mut bus = Bench::new();
    for code in [0x00, 0x07, 0x09, 0x11, 0x55 + 1, 0xFF] {
        let reply = bus.one(4, &raw_packet(4, code, &[]));
        assert_eq!(
            reply.error.unwrap().code,
            INSTRUCTION_ERROR,
            "code {code:#04x}"
        );
    }
    // To the broadcast ID, or to an absent servo: nothing.
    assert!(bus.send(&raw_packet(BROADCAST_ID, 0x07, &[])).is_empty());
    assert!(bus.send(&raw_packet(9, 0x07, &[])).is_empty());
}

#[test]
fn status_return_level_decides_what_is_answered() {
    let mut bus = Bench::new();
    let ping = packet(|o| encode_ping(5, o));
    let read_led = packet(|o| encode_read(5, LED, 1, o));
    let led_on = packet(|o| encode_write(5, LED, &[1], o));
    // Level 1: ping and read answered, write obeyed in silence.
    assert_eq!(bus.write(5, STATUS_RETURN_LEVEL, &[1]), 0);
    assert_eq!(bus.send(&ping).len(), 1);
    assert!(bus.send(&led_on).is_empty());
    assert_eq!(bus.one(5, &read_led).params, [1]);
    // Level 0: ping only.
    assert!(
        bus.send(&packet(|o| encode_write(5, STATUS_RETURN_LEVEL, &[0], o)))
            .is_empty()
    );
    assert_eq!(bus.send(&ping).len(), 1);
    assert!(bus.send(&read_led).is_empty());
    let sync_read = packet(|o| softcbf::protocol::encode_sync_read(LED, 1, &[4, 5, 6], o));
    assert_eq!(
        bus.send(&sync_read)
            .iter()
            .map(|r| r.id)
            .collect::<Vec<_>>(),
        [4, 6],
        "a sync read is a read"
    );
    // Errors are not answered either; back to level 2.
    assert!(
        bus.send(&packet(|o| encode_write(5, LED, &[7], o)))
            .is_empty()
    );
    assert!(
        bus.send(&packet(|o| encode_write(5, STATUS_RETURN_LEVEL, &[2], o)))
            .is_empty()
    );
    assert_eq!(bus.one(5, &read_led).params, [1]);
    // Broadcast Read and Write: no status packet at any level; the write is obeyed.
    assert!(
        bus.send(&packet(|o| encode_read(BROADCAST_ID, LED, 1, o)))
            .is_empty()
    );
    assert!(
        bus.send(&packet(|o| encode_write(BROADCAST_ID, LED, &[0], o)))
            .is_empty()
    );
    for id in IDS {
        assert_eq!(bus.read(id, LED, 1), [0]);
    }
}

// ---------------------------------------------------------------------------------------
// 5. Sync and bulk instructions need the broadcast ID

#[test]
fn sync_and_bulk_instructions_to_one_servo_are_ignored() {
    let mut bus = Bench::new();
    let mut sync_read = LED.to_le_bytes().to_vec();
    sync_read.extend_from_slice(&[1, 0, 1]);
    assert!(bus.send(&raw_packet(1, 0x82, &sync_read)).is_empty());
    let mut sync_write = LED.to_le_bytes().to_vec();
    sync_write.extend_from_slice(&[1, 0, 1, 1]);
    assert!(bus.send(&raw_packet(1, 0x83, &sync_write)).is_empty());
    let bulk_read = [1, LED as u8, 0, 1, 0];
    assert!(bus.send(&raw_packet(1, 0x92, &bulk_read)).is_empty());
    let bulk_write = [1, LED as u8, 0, 1, 0, 1];
    assert!(bus.send(&raw_packet(1, 0x93, &bulk_write)).is_empty());
    assert_eq!(bus.read(1, LED, 1), [0], "neither write applied");
    // The same packets to the broadcast ID are obeyed.
    assert_eq!(
        bus.send(&raw_packet(BROADCAST_ID, 0x82, &sync_read)).len(),
        1
    );
    assert!(
        bus.send(&raw_packet(BROADCAST_ID, 0x83, &sync_write))
            .is_empty()
    );
    assert_eq!(bus.read(1, LED, 1), [1]);
}

// ---------------------------------------------------------------------------------------
// 6. CRC errors

#[test]
fn a_bad_crc_to_a_servo_is_answered_with_a_crc_error() {
    let mut bus = Bench::new();
    let mut ping = packet(|o| encode_ping(2, o));
    *ping.last_mut().unwrap() ^= 0x01;
    let reply = bus.one(2, &ping);
    assert_eq!(reply.error.unwrap().code, CRC_ERROR);
    assert!(reply.params.is_empty());
    let mut write = packet(|o| encode_write(2, LED, &[1], o));
    write[10] ^= 0x10; // the data byte
    assert_eq!(bus.one(2, &write).error.unwrap().code, CRC_ERROR);
    assert_eq!(bus.read(2, LED, 1), [0], "not applied");
    // Broadcast or absent ID: nothing.
    let mut all = packet(|o| encode_ping(BROADCAST_ID, o));
    *all.last_mut().unwrap() ^= 0x01;
    assert!(bus.send(&all).is_empty());
    let mut absent = packet(|o| encode_ping(9, o));
    *absent.last_mut().unwrap() ^= 0x01;
    assert!(bus.send(&absent).is_empty());
}

// ---------------------------------------------------------------------------------------
// 7. Bus Watchdog

#[test]
fn the_bus_watchdog_stops_a_servo_nobody_talks_to() {
    let mut bus = Bench::new();
    assert_eq!(bus.write(1, OPERATING_MODE, &[0]), 0);
    assert_eq!(bus.write(1, GOAL_CURRENT, &le(100, 2)), 0);
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[1]), 0);
    assert!(bus.device.servos().tension(0) > 0.0, "pulling");
    // 5 × 20 ms = 100 ms without an instruction packet, and the servo stops.
    assert_eq!(bus.write(1, BUS_WATCHDOG, &[5]), 0);
    bus.wait(Duration::from_millis(85)); // 90 ms after the write
    assert!(bus.device.servos().tension(0) > 0.0, "not yet");
    assert!(bus.device.log().watchdog_stops.is_empty());
    bus.wait(Duration::from_millis(20)); // 110 ms: nothing arrived, it stopped on its own
    assert_eq!(bus.device.servos().tension(0), 0.0);
    assert_eq!(bus.device.log().watchdog_stops.len(), 1);
    assert_eq!(bus.device.log().watchdog_stops[0].1, 1);
    assert_eq!(
        bus.read(1, BUS_WATCHDOG, 1),
        [0xFF],
        "−1: Bus Watchdog Error"
    );
    assert_eq!(bus.read(1, PRESENT_CURRENT, 2), [0, 0]);
    assert_eq!(bus.read(1, TORQUE_ENABLE, 1), [1], "torque stays on");
    // The Goal values are read-only now: Data Range Error.
    assert_eq!(bus.write(1, GOAL_CURRENT, &le(50, 2)), DATA_RANGE_ERROR);
    assert_eq!(bus.write(1, GOAL_PWM, &le(50, 2)), DATA_RANGE_ERROR);
    assert_eq!(bus.write(1, GOAL_VELOCITY, &le(50, 4)), DATA_RANGE_ERROR);
    assert_eq!(bus.write(1, GOAL_POSITION, &le(50, 4)), DATA_RANGE_ERROR);
    assert_eq!(bus.write(1, LED, &[1]), 0, "other items are not");
    // Writing 0 clears the error; goals are writable again.
    assert_eq!(bus.write(1, BUS_WATCHDOG, &[0]), 0);
    assert_eq!(bus.read(1, BUS_WATCHDOG, 1), [0]);
    assert_eq!(bus.write(1, GOAL_CURRENT, &le(50, 2)), 0);
    assert!(bus.device.servos().tension(0) > 0.0);
}

#[test]
fn any_instruction_packet_feeds_the_bus_watchdog_and_torque_off_disarms_it() {
    let mut bus = Bench::new();
    assert_eq!(bus.write(1, OPERATING_MODE, &[0]), 0);
    assert_eq!(bus.write(1, GOAL_CURRENT, &le(100, 2)), 0);
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[1]), 0);
    assert_eq!(bus.write(1, BUS_WATCHDOG, &[5]), 0);
    // Pings to another servo every 60 ms: every instruction packet counts.
    for _ in 0..10 {
        bus.wait(Duration::from_millis(55));
        assert_eq!(bus.send(&packet(|o| encode_ping(6, o))).len(), 1);
    }
    assert!(bus.device.log().watchdog_stops.is_empty());
    assert!(bus.device.servos().tension(0) > 0.0);
    // A packet with a bad CRC is not an instruction packet.
    let mut bad = packet(|o| encode_ping(6, o));
    *bad.last_mut().unwrap() ^= 0x01;
    bus.send(&bad);
    bus.wait(Duration::from_millis(100));
    assert_eq!(bus.device.log().watchdog_stops.len(), 1);
    // With torque off the watchdog does not watch.
    assert_eq!(bus.write(1, BUS_WATCHDOG, &[0]), 0);
    assert_eq!(bus.write(1, TORQUE_ENABLE, &[0]), 0);
    assert_eq!(bus.write(1, BUS_WATCHDOG, &[1]), 0);
    bus.wait(Duration::from_secs(1));
    assert_eq!(bus.device.log().watchdog_stops.len(), 1);
    assert_eq!(bus.read(1, BUS_WATCHDOG, 1), [1]);
}

// ---------------------------------------------------------------------------------------
// 8. Ctrl-C while a reply waits

#[test]
fn serve_returns_soon_after_stop_while_a_reply_is_pending() {
    let (mut master, slave) = TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(20)).unwrap();
    let name = slave.name().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let shared = Arc::new(Mutex::new(EmulatorLog::default()));
    let (ready_tx, ready_rx) = mpsc::channel();
    let (done_tx, done_rx) = mpsc::channel();
    {
        let (stop, shared) = (stop.clone(), shared.clone());
        thread::spawn(move || {
            let mut settings = EmulatorSettings::new(BAUD);
            settings.faults.delay = Duration::from_secs(3600);
            let mut ready = || ready_tx.send(()).unwrap();
            let result = emulator::serve(
                &robot(),
                &settings,
                &mut master,
                &stop,
                &mut ready,
                Some(&*shared),
            );
            let _ = done_tx.send(result.map_err(|e| e.to_string()));
        });
    }
    ready_rx.recv().unwrap();
    let mut port = serialport::new(&name, BAUD)
        .timeout(Duration::from_millis(1))
        .open_native()
        .unwrap();
    std::io::Write::write_all(&mut port, &packet(|o| encode_ping(1, o))).unwrap();
    // Once the ping's reply is scheduled an hour from now, stop. The bounds only keep a
    // failure from hanging.
    let give_up = Instant::now() + Duration::from_secs(30);
    while shared.lock().unwrap().fates[ReplyFate::Delayed as usize] == 0 && Instant::now() < give_up
    {
        thread::sleep(Duration::from_millis(5));
    }
    stop.store(true, Ordering::Relaxed);
    let log = done_rx
        .recv_timeout(Duration::from_secs(30))
        .expect("serve returns once stop is set")
        .unwrap();
    assert_eq!(log.requests, 1);
    assert_eq!(
        log.fates,
        [0, 1, 0, 0, 0],
        "the ping's reply was delayed, never sent"
    );
    drop(slave);
}

// ---------------------------------------------------------------------------------------
// 9. Settings

fn refused(settings: &EmulatorSettings) -> String {
    let mut port = std::io::Cursor::new(Vec::new());
    let stop = AtomicBool::new(false);
    let mut ready = || panic!("a refused setting must not start serving");
    match emulator::serve(&robot(), settings, &mut port, &stop, &mut ready, None) {
        Err(e @ EmulatorError::Setting(_)) => e.to_string(),
        other => panic!("expected a setting error, got {other:?}"),
    }
}

#[test]
fn settings_the_emulator_cannot_use_are_refused_by_name() {
    let base = EmulatorSettings::new(BAUD);
    let with = |f: &dyn Fn(&mut EmulatorSettings)| {
        let mut s = base.clone();
        f(&mut s);
        refused(&s)
    };
    assert!(with(&|s| s.baud = 0).contains("baud rate 0 bit/s"));
    assert!(with(&|s| s.faults.drop = 1.5).contains("drop 1.5"));
    assert!(with(&|s| s.faults.corrupt = f64::NAN).contains("corrupt"));
    assert!(with(&|s| s.faults.delay_fraction = -0.1).contains("delay fraction"));
    let delay = with(&|s| s.return_delay = Duration::from_micros(510));
    assert!(delay.contains("return delay 510 µs"), "{delay}");
    let silent = with(&|s| s.faults.silent_servo = Some(9));
    assert!(silent.contains("silent servo 9"), "{silent}");
    assert!(with(&|s| s.settle = f64::INFINITY).contains("settling time"));
    assert!(
        !with(&|s| s.baud = 0).contains("settle"),
        "only what a user can set"
    );
}

#[test]
fn huge_delays_and_times_do_not_overflow() {
    let mut settings = EmulatorSettings::new(BAUD);
    settings.return_delay = Duration::from_micros(508);
    settings.faults = Faults {
        delay: Duration::MAX,
        delay_fraction: 1.0,
        silent_servo: Some(2),
        silent_after: Duration::MAX,
        ..Faults::default()
    };
    let mut bus = Bench::with(settings);
    assert!(
        bus.send(&packet(|o| encode_ping(1, o))).is_empty(),
        "delayed, for ever"
    );
    assert!(bus.device.next_due().is_some());
    // The bus stays busy with the first reply: the second ping waits behind it.
    assert!(bus.send(&packet(|o| encode_ping(2, o))).is_empty());
    assert!(bus.wait(Duration::from_secs(3600 * 24 * 365)).is_empty());
    assert_eq!(bus.device.log().fates[ReplyFate::Delayed as usize], 1);
    assert_eq!(bus.device.log().requests, 1);
}

// ---------------------------------------------------------------------------------------
// 10. Injected faults

/// The fate of each of `pings` status packets (pings to servo 1, one every 5 ms) under
/// `faults`.
fn fates(faults: Faults, pings: usize) -> Vec<ReplyFate> {
    let mut settings = EmulatorSettings::new(BAUD);
    settings.faults = faults;
    let mut bus = Bench::with(settings);
    let all = [
        ReplyFate::Sent,
        ReplyFate::Delayed,
        ReplyFate::Dropped,
        ReplyFate::Corrupted,
        ReplyFate::Silent,
    ];
    (0..pings)
        .map(|_| {
            let before = bus.device.log().fates;
            bus.send_raw(&packet(|o| encode_ping(1, o)));
            let after = bus.device.log().fates;
            let changed: Vec<_> = all
                .into_iter()
                .filter(|&f| after[f as usize] != before[f as usize])
                .collect();
            assert_eq!(
                changed.len(),
                1,
                "one reply per ping: {before:?} → {after:?}"
            );
            assert_eq!(after[changed[0] as usize], before[changed[0] as usize] + 1);
            changed[0]
        })
        .collect()
}

#[test]
fn injected_faults_follow_their_seed_and_their_probabilities() {
    // A reply is dropped with probability p_d; else corrupted with p_c; else delayed with
    // p_l; else sent. The delay (1 ms) ends within the 5 ms between pings.
    let (p_d, p_c, p_l) = (0.2, 0.1, 0.1);
    let faults = |seed| Faults {
        drop: p_d,
        corrupt: p_c,
        delay: Duration::from_millis(1),
        delay_fraction: p_l,
        seed,
        ..Faults::default()
    };
    const N: usize = 2000;
    let first = fates(faults(5), N);
    assert_eq!(first, fates(faults(5), N), "the same seed, the same faults");
    let other = fates(faults(6), N);
    let differ = first.iter().zip(&other).filter(|(a, b)| a != b).count();
    // Two independent runs agree on a reply with probability Σ pᵢ² ≈ 0.48.
    assert!(
        differ > N / 3,
        "another seed, other faults: {differ} of {N} differ"
    );
    for run in [&first, &other] {
        let expected = [
            (ReplyFate::Dropped, p_d),
            (ReplyFate::Corrupted, (1.0 - p_d) * p_c),
            (ReplyFate::Delayed, (1.0 - p_d) * (1.0 - p_c) * p_l),
            (ReplyFate::Sent, (1.0 - p_d) * (1.0 - p_c) * (1.0 - p_l)),
            (ReplyFate::Silent, 0.0),
        ];
        for (fate, p) in expected {
            let count = run.iter().filter(|&&f| f == fate).count() as f64;
            let (mean, sd) = (N as f64 * p, (N as f64 * p * (1.0 - p)).sqrt());
            // Five standard deviations of the binomial count: a false alarm about once in
            // 10⁶ runs, while a draw that is wrong (a stuck generator, a fault decided
            // from the wrong draw) is off by far more.
            assert!(
                (count - mean).abs() <= 5.0 * sd,
                "{fate:?}: {count} of {N}, expected {mean:.0} ± {sd:.0}"
            );
        }
    }
}

#[test]
fn a_silent_servo_counts_from_the_first_packet_received() {
    // `--silent-after 1`: one second after the first packet, not after the emulator's start,
    // so a `run` started later than the emulator still gets its safe start.
    let mut settings = EmulatorSettings::new(BAUD);
    settings.faults = Faults {
        silent_servo: Some(2),
        silent_after: Duration::from_secs(1),
        ..Faults::default()
    };
    let mut bus = Bench::with(settings);
    let ping = |id| packet(|o| encode_ping(id, o));
    assert!(bus.wait(Duration::from_secs(10)).is_empty());
    assert_eq!(bus.send(&ping(2)).len(), 1, "10 s after the start: answers");
    // `send` waits 5 ms after each packet: the next ping goes 905 ms after the first.
    bus.wait(Duration::from_millis(900));
    assert_eq!(bus.send(&ping(2)).len(), 1, "0.9 s after the first packet");
    bus.wait(Duration::from_millis(100));
    assert!(bus.send(&ping(2)).is_empty(), "1.01 s after: silent");
    assert_eq!(bus.send(&ping(1)).len(), 1, "the other servos answer");
    assert_eq!(bus.device.log().fates[ReplyFate::Silent as usize], 1);
}
