//! The Dynamixel X-series control table (Protocol 2.0, e.g. XM430-W350): the addresses the
//! hardware path uses, the block read every tick, and [`X_SERIES`], the table as data.
//!
//! [`X_SERIES`] lists every item of the XM430-W350's table up to Present Temperature (146)
//! with its size, access, area, accepted values and factory value, as the ROBOTIS e-Manual
//! gives them (XM430-W350 page and the item descriptions it includes). The indirect
//! addresses and data (168 and above) are not in it.

/// Model Number (2 bytes, read-only).
pub const MODEL_NUMBER: u16 = 0;
/// Firmware Version (1 byte, read-only).
pub const FIRMWARE_VERSION: u16 = 6;
/// ID (1 byte, EEPROM).
pub const ID: u16 = 7;
/// Baud Rate (1 byte, EEPROM): 0..=7 for 9600 … 4.5 M bit/s.
pub const BAUD_RATE: u16 = 8;
/// Return Delay Time (1 byte, EEPROM), units of 2 µs.
pub const RETURN_DELAY_TIME: u16 = 9;
/// Operating Mode (1 byte, EEPROM: writable with torque off only).
pub const OPERATING_MODE: u16 = 11;
/// Current Limit (2 bytes, EEPROM).
pub const CURRENT_LIMIT: u16 = 38;
/// Torque Enable (1 byte).
pub const TORQUE_ENABLE: u16 = 64;
/// Status Return Level (1 byte): 2 = reply to every instruction.
pub const STATUS_RETURN_LEVEL: u16 = 68;
/// Hardware Error Status (1 byte, read-only).
pub const HARDWARE_ERROR_STATUS: u16 = 70;
/// Bus Watchdog (1 byte, signed): 0 off (and clears a watchdog error), 1..=127 the longest
/// gap between instruction packets in units of 20 ms while torque is on, −1 after it
/// expired (the servo stopped; goal values are then read-only). Firmware v38 and later.
pub const BUS_WATCHDOG: u16 = 98;
/// Goal Current (2 bytes, signed, current units).
pub const GOAL_CURRENT: u16 = 102;
/// Present Current (2 bytes, signed).
pub const PRESENT_CURRENT: u16 = 126;
/// Present Velocity (4 bytes, signed, velocity units).
pub const PRESENT_VELOCITY: u16 = 128;
/// Present Position (4 bytes, signed, position units).
pub const PRESENT_POSITION: u16 = 132;
/// Drive Mode (1 byte, EEPROM): direction and profile bits.
pub const DRIVE_MODE: u16 = 10;
/// Protocol Type (1 byte, EEPROM): 2 for Protocol 2.0, 1 for Protocol 1.0.
pub const PROTOCOL_TYPE: u16 = 13;
/// Homing Offset (4 bytes, signed, EEPROM), added to Present Position.
pub const HOMING_OFFSET: u16 = 20;
/// Moving Threshold (4 bytes, EEPROM): the speed above which the servo counts as moving.
pub const MOVING_THRESHOLD: u16 = 24;
/// PWM Limit (2 bytes, EEPROM): bound of Goal PWM.
pub const PWM_LIMIT: u16 = 36;
/// Velocity Limit (4 bytes, EEPROM): bound of Goal Velocity.
pub const VELOCITY_LIMIT: u16 = 44;
/// Max Position Limit (4 bytes, EEPROM).
pub const MAX_POSITION_LIMIT: u16 = 48;
/// Min Position Limit (4 bytes, EEPROM).
pub const MIN_POSITION_LIMIT: u16 = 52;
/// LED (1 byte).
pub const LED: u16 = 65;
/// Registered Instruction (1 byte, read-only): 1 while a Reg Write awaits its Action.
pub const REGISTERED_INSTRUCTION: u16 = 69;
/// Goal PWM (2 bytes, signed).
pub const GOAL_PWM: u16 = 100;
/// Goal Velocity (4 bytes, signed).
pub const GOAL_VELOCITY: u16 = 104;
/// Profile Acceleration (4 bytes).
pub const PROFILE_ACCELERATION: u16 = 108;
/// Profile Velocity (4 bytes).
pub const PROFILE_VELOCITY: u16 = 112;
/// Goal Position (4 bytes, signed).
pub const GOAL_POSITION: u16 = 116;
/// Realtime Tick (2 bytes, read-only): milliseconds, wrapping at 32768.
pub const REALTIME_TICK: u16 = 120;
/// Moving (1 byte, read-only): 1 while the speed exceeds the Moving Threshold.
pub const MOVING: u16 = 122;
/// Present Input Voltage (2 bytes, read-only), units of 0.1 V.
pub const PRESENT_INPUT_VOLTAGE: u16 = 144;
/// Present Temperature (1 byte, read-only), °C.
pub const PRESENT_TEMPERATURE: u16 = 146;
/// Size of the table the emulator models: up to and including Present Temperature (146).
pub const TABLE_SIZE: usize = 147;

/// Operating Mode value of current control.
pub const CURRENT_CONTROL_MODE: u8 = 0;
/// Current Limit of an XM430-W350 (units of 2.69 mA).
pub const XM430_CURRENT_LIMIT: i16 = 1193;

/// The block sync-read every tick: Present Current, Velocity and Position.
pub const STATE_ADDRESS: u16 = PRESENT_CURRENT;
/// Its length in bytes.
pub const STATE_LENGTH: u16 = 10;

/// One servo's state block, decoded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServoState {
    /// Present Current (current units).
    pub current: i16,
    /// Present Velocity (velocity units).
    pub velocity: i32,
    /// Present Position (position units).
    pub position: i32,
}

impl ServoState {
    /// Decodes the [`STATE_LENGTH`] bytes read at [`STATE_ADDRESS`].
    pub fn from_bytes(b: &[u8]) -> ServoState {
        ServoState {
            current: i16::from_le_bytes([b[0], b[1]]),
            velocity: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
            position: i32::from_le_bytes([b[6], b[7], b[8], b[9]]),
        }
    }

    /// Encodes into the [`STATE_LENGTH`] bytes of the control table at [`STATE_ADDRESS`].
    pub fn to_bytes(self, b: &mut [u8]) {
        b[0..2].copy_from_slice(&self.current.to_le_bytes());
        b[2..6].copy_from_slice(&self.velocity.to_le_bytes());
        b[6..10].copy_from_slice(&self.position.to_le_bytes());
    }
}

/// Who may write an item over the bus (every item can be read).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Read-only: a write is refused with an Access Error.
    Read,
    /// Readable and writable.
    ReadWrite,
}

/// Where an item is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Area {
    /// Non-volatile; locked (Access Error on write) while Torque Enable is 1.
    Eeprom,
    /// Volatile; back to its initial value on a reboot.
    Ram,
}

/// The values a write may put into an item.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Values {
    /// Nothing to check (read-only items).
    Any,
    /// `min..=max`; outside it a Data Range Error.
    Range(i64, i64),
    /// One of these; otherwise a Data Range Error.
    OneOf(&'static [i64]),
    /// Only these bits may be set; otherwise a Data Range Error.
    Bits(u8),
    /// Within ± the value of the item at this address (a limit in the EEPROM area);
    /// outside it a Data Limit Error.
    WithinLimit(u16),
    /// Goal Position: `-1_048_575..=1_048_575` (the ±256 turns of the multi-turn modes;
    /// outside it a Data Range Error), and in Position Control Mode also between the Min
    /// and Max Position Limits (outside them a Data Limit Error).
    GoalPosition,
}

/// One item of the control table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Item {
    /// The e-Manual's name.
    pub name: &'static str,
    /// First byte.
    pub address: u16,
    /// Bytes (1, 2 or 4), little-endian.
    pub size: u16,
    /// Whether the value is two's complement.
    pub signed: bool,
    /// Read-only or read-write.
    pub access: Access,
    /// EEPROM or RAM.
    pub area: Area,
    /// What a write may put there.
    pub values: Values,
    /// Value from the factory (EEPROM) or after a reboot (RAM). For the Goal values, which
    /// the e-Manual leaves open, the emulator's choice: Goal PWM at the PWM Limit (full
    /// output allowed), the others 0.
    pub initial: i64,
}

impl Item {
    /// One past the last byte.
    pub const fn end(&self) -> u16 {
        self.address + self.size
    }

    /// Decodes this item's value from its `size` bytes.
    pub fn value(&self, bytes: &[u8]) -> i64 {
        let mut raw = [0u8; 8];
        let n = bytes.len().min(8);
        raw[..n].copy_from_slice(&bytes[..n]);
        let unsigned = u64::from_le_bytes(raw);
        let bits = 8 * u32::from(self.size).min(8);
        if self.signed && bits < 64 && (unsigned >> (bits - 1)) & 1 == 1 {
            (unsigned | (u64::MAX << bits)) as i64
        } else {
            unsigned as i64
        }
    }

    /// Encodes `value` into this item's `size` bytes (truncating to them).
    pub fn encode(&self, value: i64, bytes: &mut [u8]) {
        let raw = value.to_le_bytes();
        let n = usize::from(self.size).min(bytes.len()).min(8);
        bytes[..n].copy_from_slice(&raw[..n]);
    }
}

#[allow(clippy::too_many_arguments)] // one argument per column of the e-Manual's table
const fn item(
    name: &'static str,
    address: u16,
    size: u16,
    signed: bool,
    access: Access,
    area: Area,
    values: Values,
    initial: i64,
) -> Item {
    Item {
        name,
        address,
        size,
        signed,
        access,
        area,
        values,
        initial,
    }
}

use Access::{Read as R, ReadWrite as RW};
use Area::{Eeprom, Ram};
use Values::{Any, Bits, GoalPosition, OneOf, Range, WithinLimit};

/// The X-series control table (XM430-W350, model number 1020) up to Present Temperature,
/// in address order. Addresses between items (e.g. 14–19, 99) are undefined.
///
/// Ranges from the e-Manual: ID 0–252, Baud Rate 0–7 (9600 bit/s … 4.5 Mbit/s), Return
/// Delay Time 0–254 (2 µs units), Drive Mode bits 0, 2, 3, Operating Mode 0, 1, 3, 4, 5,
/// 16, Protocol Type 1 or 2, Homing Offset ±1 044 479, Moving Threshold 0–1023,
/// Temperature Limit 0–100, Voltage Limits 95–160, PWM Limit 0–885, Current Limit 0–1193,
/// Acceleration Limit 0–32767, Velocity Limit 0–1023, Position Limits 0–4095, Shutdown
/// bits 0, 2–5, Torque Enable and LED 0–1, Status Return Level 0–2, gains 0–16383, Bus
/// Watchdog 0–127 (−1 is its error state, set by the servo), Goal PWM/Current/Velocity
/// within ± their limits, Profile Acceleration/Velocity 0–32767.
#[rustfmt::skip]
pub const X_SERIES: &[Item] = &[
    //    name                     addr size signed access area    values                        initial
    item("Model Number",           0,   2,   false, R,     Eeprom, Any,                          1020),
    item("Model Information",      2,   4,   false, R,     Eeprom, Any,                          0),
    item("Firmware Version",       6,   1,   false, R,     Eeprom, Any,                          46),
    item("ID",                     7,   1,   false, RW,    Eeprom, Range(0, 252),                1),
    item("Baud Rate",              8,   1,   false, RW,    Eeprom, Range(0, 7),                  1),
    item("Return Delay Time",      9,   1,   false, RW,    Eeprom, Range(0, 254),                250),
    item("Drive Mode",             10,  1,   false, RW,    Eeprom, Bits(0x0D),                   0),
    item("Operating Mode",         11,  1,   false, RW,    Eeprom, OneOf(&[0, 1, 3, 4, 5, 16]),  3),
    item("Secondary ID",           12,  1,   false, RW,    Eeprom, Range(0, 255),                255),
    item("Protocol Type",          13,  1,   false, RW,    Eeprom, OneOf(&[1, 2]),               2),
    item("Homing Offset",          20,  4,   true,  RW,    Eeprom, Range(-1_044_479, 1_044_479), 0),
    item("Moving Threshold",       24,  4,   false, RW,    Eeprom, Range(0, 1023),               10),
    item("Temperature Limit",      31,  1,   false, RW,    Eeprom, Range(0, 100),                80),
    item("Max Voltage Limit",      32,  2,   false, RW,    Eeprom, Range(95, 160),               160),
    item("Min Voltage Limit",      34,  2,   false, RW,    Eeprom, Range(95, 160),               95),
    item("PWM Limit",              36,  2,   false, RW,    Eeprom, Range(0, 885),                885),
    item("Current Limit",          38,  2,   false, RW,    Eeprom, Range(0, 1193),               1193),
    item("Acceleration Limit",     40,  4,   false, RW,    Eeprom, Range(0, 32767),              32767),
    item("Velocity Limit",         44,  4,   false, RW,    Eeprom, Range(0, 1023),               350),
    item("Max Position Limit",     48,  4,   false, RW,    Eeprom, Range(0, 4095),               4095),
    item("Min Position Limit",     52,  4,   false, RW,    Eeprom, Range(0, 4095),               0),
    item("Shutdown",               63,  1,   false, RW,    Eeprom, Bits(0x3D),                   52),
    item("Torque Enable",          64,  1,   false, RW,    Ram,    Range(0, 1),                  0),
    item("LED",                    65,  1,   false, RW,    Ram,    Range(0, 1),                  0),
    item("Status Return Level",    68,  1,   false, RW,    Ram,    Range(0, 2),                  2),
    item("Registered Instruction", 69,  1,   false, R,     Ram,    Any,                          0),
    item("Hardware Error Status",  70,  1,   false, R,     Ram,    Any,                          0),
    item("Velocity I Gain",        76,  2,   false, RW,    Ram,    Range(0, 16383),              1920),
    item("Velocity P Gain",        78,  2,   false, RW,    Ram,    Range(0, 16383),              100),
    item("Position D Gain",        80,  2,   false, RW,    Ram,    Range(0, 16383),              0),
    item("Position I Gain",        82,  2,   false, RW,    Ram,    Range(0, 16383),              0),
    item("Position P Gain",        84,  2,   false, RW,    Ram,    Range(0, 16383),              800),
    item("Feedforward 2nd Gain",   88,  2,   false, RW,    Ram,    Range(0, 16383),              0),
    item("Feedforward 1st Gain",   90,  2,   false, RW,    Ram,    Range(0, 16383),              0),
    item("Bus Watchdog",           98,  1,   true,  RW,    Ram,    Range(0, 127),                0),
    item("Goal PWM",               100, 2,   true,  RW,    Ram,    WithinLimit(PWM_LIMIT),       885),
    item("Goal Current",           102, 2,   true,  RW,    Ram,    WithinLimit(CURRENT_LIMIT),   0),
    item("Goal Velocity",          104, 4,   true,  RW,    Ram,    WithinLimit(VELOCITY_LIMIT),  0),
    item("Profile Acceleration",   108, 4,   false, RW,    Ram,    Range(0, 32767),              0),
    item("Profile Velocity",       112, 4,   false, RW,    Ram,    Range(0, 32767),              0),
    item("Goal Position",          116, 4,   true,  RW,    Ram,    GoalPosition,                 0),
    item("Realtime Tick",          120, 2,   false, R,     Ram,    Any,                          0),
    item("Moving",                 122, 1,   false, R,     Ram,    Any,                          0),
    item("Moving Status",          123, 1,   false, R,     Ram,    Any,                          0),
    item("Present PWM",            124, 2,   true,  R,     Ram,    Any,                          0),
    item("Present Current",        126, 2,   true,  R,     Ram,    Any,                          0),
    item("Present Velocity",       128, 4,   true,  R,     Ram,    Any,                          0),
    item("Present Position",       132, 4,   true,  R,     Ram,    Any,                          0),
    item("Velocity Trajectory",    136, 4,   true,  R,     Ram,    Any,                          0),
    item("Position Trajectory",    140, 4,   true,  R,     Ram,    Any,                          0),
    item("Present Input Voltage",  144, 2,   false, R,     Ram,    Any,                          0),
    item("Present Temperature",    146, 1,   false, R,     Ram,    Any,                          0),
];

/// The item of [`X_SERIES`] that holds byte `address`, if one does.
pub fn item_at(address: usize) -> Option<&'static Item> {
    X_SERIES
        .iter()
        .find(|i| usize::from(i.address) <= address && address < usize::from(i.end()))
}

/// The item of [`X_SERIES`] that starts at `address`.
pub fn item_starting_at(address: u16) -> Option<&'static Item> {
    X_SERIES.iter().find(|i| i.address == address)
}
