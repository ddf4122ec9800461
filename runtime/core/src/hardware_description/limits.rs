//! The valid range of every servo and bus setting of the hardware path (the robot file's
//! `[hardware]` table, `softcbf run` and `softcbf emulate`), by the rule of the description.
//!
//! Each is a [`Limit`] of `softcbf_description::limits`, so that the file checker and the
//! command line name the same range; the X-series facts behind them (baud rates, register
//! units) are the servos', kept here apart from the robot's description.

use softcbf_description::limits::Limit;

/// Time constant of the velocity filter \[ms\]: longer than a second filters out the motion.
pub const VELOCITY_FILTER_MS: Limit = Limit::above(0.0, 1000.0, "ms");
/// Model number a servo answers to a ping (a 16-bit register).
pub const MODEL_NUMBER: Limit = Limit::integer(0, 65_535);
/// Current unit of the Goal/Present Current registers \[mA\] (X-series: 1 or 2.69).
pub const CURRENT_UNIT_MA: Limit = Limit::closed(1e-3, 100.0, "mA");
/// Position unit of Present Position \[deg\] (X-series: 360°/4096).
pub const POSITION_UNIT_DEG: Limit = Limit::closed(1e-4, 360.0, "°");
/// Velocity unit of Present Velocity \[rev/min\] (X-series: 0.229).
pub const VELOCITY_UNIT_RPM: Limit = Limit::closed(1e-4, 100.0, "rev/min");
/// Servo angle in the calibration pose \[deg\]: a hundred turns either way.
pub const ZERO_ANGLE_DEG: Limit = Limit::closed(-36_000.0, 36_000.0, "°");
/// Radius of the pulley a tendon winds on \[m\]: 0.1 mm to 1 m.
pub const PULLEY_RADIUS_M: Limit = Limit::closed(1e-4, 1.0, "m");
/// Tension per unit of motor current \[N/mA\] (XM430 on a 45 mm pulley: 0.04).
pub const ACTUATOR_GAIN_N_PER_MA: Limit = Limit::closed(1e-6, 100.0, "N/mA");
/// A tendon tension limit \[N\]: up to 100 kN, ten tonnes on one cable.
pub const TENSION_N: Limit = Limit::closed(0.0, 1e5, "N");

/// Ticks in a row without a good reading before the safe stop.
pub const MAX_CONSECUTIVE_ERRORS: Limit = Limit::integer(1, 1000);
/// Sync-read retries within one tick.
pub const RETRIES: Limit = Limit::integer(0, 1000);
/// Wait for one status packet \[ms\]: a reply that takes longer than a second is lost.
pub const REPLY_TIMEOUT_MS: Limit = Limit::above(0.0, 1000.0, "ms");
/// Servo ID on the bus (252 is the largest a single servo may have).
pub const SERVO_ID: Limit = Limit::integer(0, 252);
/// Baud rates the X-series servos support (Baud Rate register values 0..=7).
pub const SUPPORTED_BAUDS: [u32; 8] = [
    9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000,
];

/// Checks a baud rate against [`SUPPORTED_BAUDS`].
pub fn check_baud(baud: i64) -> Result<u32, String> {
    u32::try_from(baud)
        .ok()
        .filter(|b| SUPPORTED_BAUDS.contains(b))
        .ok_or_else(|| {
            format!("{baud} bit/s is not an X-series baud rate; use one of {SUPPORTED_BAUDS:?}")
        })
}

/// Bus Watchdog time \[ms\]: `0` (off) or 20 to 2540 ms, the register's 1..=127 units of
/// 20 ms.
pub const BUS_WATCHDOG_MS: Limit = Limit::closed(0.0, 2540.0, "ms");
/// Unit of the Bus Watchdog register \[ms\].
pub const BUS_WATCHDOG_UNIT_MS: f64 = 20.0;

// ---------------------------------------------------------------------------------------
// The emulator (`softcbf emulate`).

/// Injected extra delay of a status packet \[ms\] (up to ten minutes).
pub const DELAY_MS: Limit = Limit::closed(0.0, 600_000.0, "ms");
/// A probability.
pub const FRACTION: Limit = Limit::closed(0.0, 1.0, "");
/// Return Delay Time \[µs\]: the register holds 0..=254 units of 2 µs.
pub const RETURN_DELAY_US: Limit = Limit::closed(0.0, 508.0, "µs");
/// Seconds after the start when a servo falls silent (up to about 11 days).
pub const SILENT_AFTER_S: Limit = Limit::closed(0.0, 1e6, "s");
/// Latency timer of the emulated USB adapter \[ms\]: FTDI chips take 1 to 255 in steps of
/// 1 ms (16 from the factory); 0 models no adapter (bytes reach the host as they cross).
pub const LATENCY_TIMER_MS: Limit = Limit::integer(0, 255);
/// Standard deviation of the emulated sensor noise, in register units (Present Position or
/// Present Velocity units): up to a thousand, a quarter turn of position.
pub const NOISE_UNITS: Limit = Limit::closed(0.0, 1000.0, "units");

/// The X-series Baud Rate register value of `baud`, if it is a supported rate.
pub fn baud_register(baud: u32) -> Option<u8> {
    SUPPORTED_BAUDS
        .iter()
        .position(|&b| b == baud)
        .map(|k| k as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_accept_their_range_and_name_it_otherwise() {
        assert_eq!(REPLY_TIMEOUT_MS.check(10.0), Ok(10.0));
        assert_eq!(REPLY_TIMEOUT_MS.check(1000.0), Ok(1000.0));
        let message = REPLY_TIMEOUT_MS.check(1e300).unwrap_err();
        assert_eq!(message, "must be > 0 and ≤ 1000 ms, got 1e300");
        assert!(REPLY_TIMEOUT_MS.check(0.0).unwrap_err().contains("> 0"));
        assert!(
            REPLY_TIMEOUT_MS
                .check(f64::NAN)
                .unwrap_err()
                .contains("finite")
        );
        assert!(
            DELAY_MS
                .check(f64::INFINITY)
                .unwrap_err()
                .contains("finite")
        );
        assert_eq!(MAX_CONSECUTIVE_ERRORS.check_integer(1000), Ok(1000));
        assert_eq!(
            MAX_CONSECUTIVE_ERRORS.check_integer(100_000).unwrap_err(),
            "must be an integer in 1..=1000, got 100000"
        );
        assert!(MAX_CONSECUTIVE_ERRORS.check(2.5).is_err());
        assert_eq!(check_baud(1_000_000), Ok(1_000_000));
        for bad in [0, 12345, -1, i64::MAX] {
            assert!(
                check_baud(bad)
                    .unwrap_err()
                    .contains("not an X-series baud rate")
            );
        }
        assert_eq!(baud_register(1_000_000), Some(3));
        assert_eq!(baud_register(4_500_000), Some(7));
        assert_eq!(baud_register(1234), None);
    }

    /// Every range is a proper interval with finite ends (integer ranges with whole ends).
    #[test]
    fn every_range_is_a_proper_interval() {
        for limit in [
            MAX_CONSECUTIVE_ERRORS,
            RETRIES,
            REPLY_TIMEOUT_MS,
            SERVO_ID,
            BUS_WATCHDOG_MS,
            DELAY_MS,
            FRACTION,
            RETURN_DELAY_US,
            SILENT_AFTER_S,
            LATENCY_TIMER_MS,
            NOISE_UNITS,
            VELOCITY_FILTER_MS,
            MODEL_NUMBER,
            CURRENT_UNIT_MA,
            POSITION_UNIT_DEG,
            VELOCITY_UNIT_RPM,
            ZERO_ANGLE_DEG,
            PULLEY_RADIUS_M,
            ACTUATOR_GAIN_N_PER_MA,
            TENSION_N,
        ] {
            assert!(limit.min.is_finite() && limit.max.is_finite() && limit.min < limit.max);
            assert!(limit.contains(limit.max), "{limit:?}");
            assert_eq!(limit.contains(limit.min), limit.min_inclusive, "{limit:?}");
            if limit.integer {
                assert_eq!((limit.min.fract(), limit.max.fract()), (0.0, 0.0));
            }
        }
    }
}
