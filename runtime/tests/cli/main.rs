//! End-to-end tests of the `softcbf` binary (only the package that builds a binary can run
//! it in its tests), in one test binary that links the crate once; each file is a module of
//! its own, named as the test binary it once was, and `common` is what they share.

mod bus_check_cli;
mod common;
mod emulator_realism;
mod experiment_cli;
mod figures_cli;
mod hardware_cli;
mod identify_cli;
mod plot_cli;
mod search_cli;
mod simulate_settings;
mod verify_cli;
mod view_cli;
