//! The hardware path: the robot's Dynamixel servos over Protocol 2.0, driven by the same
//! controller as the simulation, and an emulator of those servos for work without a robot.
//!
//! - The robot file's `[hardware]` table, read and checked, and the range of every servo
//!   and bus setting, are a description, below this path: [`crate::hardware_description`].
//! - [`control_table`]: the X-series registers used.
//! - [`mapping`]: servo angles → `q`, `q̇`; `τ` → tensions → currents, and back.
//! - [`emulator`]: `softcbf emulate`, the servos on a pseudo-terminal, moved by the plant.
//! - [`servo_io`]: safe start, the per-tick sync read/write with retries, safe stop.
//! - [`bus_check`]: the round trip measured at the start, the rate it allows, the USB
//!   adapter's latency timer.
//! - [`run_loop`]: `softcbf run`, the fixed-rate control loop; [`run_settings`] what it
//!   does, [`run_outcome`] how it ended and its verdict; [`log`] its rows, CSV and figures;
//!   [`log_description`] the hardware description a log was taken with (`hardware.json`);
//!   [`status_line`] the live line on the terminal; [`summary_file`] its `summary.json`.
//! - [`experiment`]: the identification experiments of `softcbf run --experiment` (static
//!   tension sets held to rest, multisines), whose tensions pass through the filter;
//!   [`next_step`]: what to run after one (both logs named for `softcbf identify`).
//! - [`signal`]: terminating signals as flags the loops poll (from `softcbf-outputs`, which
//!   verification shares); `cli`: the two subcommands' options.
//!
//! Cargo feature `serial` (on by default): the real serial ports (`serialport`) and the
//! subcommands that open them (`cli`). Without it the log formats, mapping, emulator and
//! run loop remain, for identification and Python.

// The lower crates' modules at the root, so that the paths the files had in `softcbf`
// (`crate::control`, `crate::output`, …) keep resolving.
use softcbf_core::{
    control, hardware_description, integrator, model, noise, plant, record, settings, sim, verdict,
};
#[cfg(test)]
use softcbf_core::{robot_file, scenario};
use softcbf_figures::plot;
use softcbf_outputs::output;
use softcbf_protocol as protocol;
// Only the subcommands (`cli`) use these.
#[cfg(feature = "serial")]
use {softcbf_core::exit, softcbf_outputs::mcap_log};

pub use softcbf_outputs::signal;

pub mod bus_check;
#[cfg(feature = "serial")]
pub mod cli;
pub mod control_table;
pub mod emulator;
pub mod experiment;
pub mod log;
pub mod log_description;
pub mod mapping;
pub mod next_step;
pub mod run_loop;
pub mod run_outcome;
pub mod run_settings;
pub mod servo_io;
pub mod status_line;
pub mod summary_file;
