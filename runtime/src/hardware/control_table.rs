//! The subset of the Dynamixel X-series control table (Protocol 2.0, e.g. XM430-W350) the
//! hardware path uses: addresses, sizes and the block read every tick.

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
/// Size of the table the emulator models (everything above ends before 136).
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
