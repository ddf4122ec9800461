//! CRC-16 of Protocol 2.0: polynomial 0x8005, initial value 0, no reflection, no final xor.
//! Table driven (256-entry table built at compile time), over the packet as sent.

/// Generator polynomial x^16 + x^15 + x^2 + 1.
const POLY: u16 = 0x8005;

const fn build_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ POLY
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

static TABLE: [u16; 256] = build_table();

/// Continues a CRC over more bytes: `crc16_update(crc16(a), b) == crc16(a ++ b)`.
pub fn crc16_update(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        let index = ((crc >> 8) as u8 ^ b) as usize;
        crc = (crc << 8) ^ TABLE[index];
    }
    crc
}

/// CRC-16 of `bytes`; for a packet, pass everything from the header to the last parameter
/// (stuffed), and send the result low byte first.
pub fn crc16(bytes: &[u8]) -> u16 {
    crc16_update(0, bytes)
}
