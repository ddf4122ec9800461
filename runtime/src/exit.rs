//! The exit statuses of the `softcbf` command: one meaning each, so a script (or a person)
//! can tell a safe run from an unsafe one, a fault, and a run that never started.

/// Done, and safe: every barrier stayed above the threshold and every tick was valid.
pub const OK: u8 = 0;
/// Not done, or not all of it: a bad file, setting or port, a loop rate the bus cannot hold
/// (measured before torque on), a safe start that refused, an output (log, figure, standard
/// output) that could not be written.
pub const ERROR: u8 = 1;
/// The command line could not be read (unknown option, missing value).
pub const USAGE: u8 = 2;
/// Done, but not safe: a barrier fell below the threshold, or ticks had an invalid state or
/// no verified command (the zero command was applied), or a model value was not finite.
pub const UNSAFE: u8 = 3;
/// A hardware run stopped on a fault: communication lost, a servo's hardware error, the
/// loop too slow or paused past the servos' watchdog, a torque-off not confirmed.
pub const FAULT: u8 = 4;

/// The more serious of two statuses (`FAULT > UNSAFE > ERROR > OK`; `USAGE` is only ever
/// returned alone).
pub fn worst(a: u8, b: u8) -> u8 {
    let rank = |code: u8| match code {
        FAULT => 4,
        UNSAFE => 3,
        ERROR | USAGE => 2,
        _ => 0,
    };
    if rank(b) > rank(a) { b } else { a }
}
