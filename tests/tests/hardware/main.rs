//! The hardware path and identification: Protocol 2.0, the servo mapping, the emulator, the
//! run loop, identification from run logs.
//!
//! Each file is a module named as the test binary it once was; one binary links the
//! runtime once for all of them.

mod emulator_device;
mod hardware_emulator;
mod hardware_loop;
mod hardware_mapping;
mod identify;
mod protocol;
mod protocol_fuzz;
